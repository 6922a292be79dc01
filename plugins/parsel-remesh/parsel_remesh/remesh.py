"""Watertight remeshing of an edited shape (after PartSDF): union of posed part SDFs, marching cubes.

Each part's signed distance field is sampled once in its rest cage (:mod:`parsel_remesh.sdf`).
For an edit, a world grid covers the edited shape; every grid point near a part is
mapped back to the part's rest cube coordinates by the inverse cage map of the part's
*edited* hexahedron (:func:`parsel_core.cage.inverse_trilinear`: exact for affine edits,
Newton iterations for the trilinear cages of feature edits) and the part's field is
read there. The union is the minimum over parts; marching cubes (scikit-image) turns
its zero level into one closed mesh, and each face takes the label of the part whose
field is lowest at its centre (the nearest part).

Edits can pull attached parts apart (a seat raised while the legs stay). With
``bridge=True`` every attachment of the shape that the edit opened is closed before
the union: the smaller of the two parts has the face of its cage that carries the
contact moved across the gap (plus a little overlap), so it stretches or leans to meet
its partner, exactly as a face translation in the program would have done.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.cage import cage_weights, inverse_trilinear
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import CORNER_BITS
from parsel_core.program import Evaluation
from parsel_core.relations import Attachment
from parsel_remesh.sdf import PartField, part_field

DEFAULT_RESOLUTION = 160
#: A hexahedron's faces as quads in canonical corner order: the mesh of a part that has none.
#: Band of exact distances around each surface, in grid cells.
BAND_CELLS = 3.0

# shape -> (part id, spacing) -> field; weak so that dropping a shape frees its fields.
_FIELDS: weakref.WeakKeyDictionary[ShapeGraph, dict[tuple[str, float], PartField]] = weakref.WeakKeyDictionary()


@dataclass
class RemeshResult:
    """The watertight mesh, the label and source part of each face, and how it was made."""

    mesh: Any
    face_labels: np.ndarray
    face_parts: np.ndarray
    spacing: float
    bridges: list[dict[str, Any]] = field(default_factory=list)

    @property
    def labels(self) -> list[str]:
        """The labels present, sorted (their index is the ``part`` property of PLY output)."""
        return sorted(set(self.face_labels.tolist()))


def _mesh_of(shape: ShapeGraph, pid: str) -> tuple[np.ndarray, np.ndarray]:
    mesh = shape.parts[pid].mesh
    if mesh is None or getattr(mesh, "vertices", None) is None or getattr(mesh, "faces", None) is None:
        hexahedron = shape.parts[pid].hexahedron
        return np.asarray(hexahedron.corners, dtype=float), hexahedron.triangles()
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


def field_of(shape: ShapeGraph, pid: str, spacing: float) -> PartField:
    """The part's rest-cage SDF at ``spacing``, computed once per shape, part and spacing."""
    per_shape = _FIELDS.setdefault(shape, {})
    key = (pid, round(float(spacing), 12))
    if key not in per_shape:
        vertices, faces = _mesh_of(shape, pid)
        if len(faces) == 0:
            raise ParselError(f"shape {shape.name!r}: part {pid!r} has no faces to remesh")
        per_shape[key] = part_field(shape.parts[pid].hexahedron.corners, vertices, faces, spacing, BAND_CELLS)
    return per_shape[key]


def posed_items(shape: ShapeGraph, evaluation: Evaluation) -> list[tuple[str, str, np.ndarray]]:
    """(name, source part, edited corners) of everything drawn, groups replaced by their instances."""
    replaced = {m for g in evaluation.instances for m in shape.relation(g).members}
    items = []
    for pid in shape.parts:
        if pid in replaced:
            continue
        corners = np.asarray(evaluation.parts[pid], dtype=float)
        if corners.shape != (8, 3):
            raise ParselError(f"cannot remesh part {pid!r} at a batch of parameter values; evaluate one at a time")
        items.append((pid, pid, corners))
    for group, instances in evaluation.instances.items():
        first = shape.relation(group).members[0]
        items += [(f"{first}#{i}", first, np.asarray(c, dtype=float)) for i, c in enumerate(instances)]
    return items


def _contact_face(weights: np.ndarray) -> tuple[int, int]:
    """The cage face a contact lies on: (axis, side) whose cube coordinate is nearest 0 or 1."""
    uvw = np.asarray(weights, dtype=float) @ CORNER_BITS  # cube coordinates of the contact points
    mean = uvw.mean(axis=0)
    distance = np.minimum(mean, 1 - mean)
    axis = int(np.argmin(distance))
    return axis, int(mean[axis] > 0.5)


def bridged_corners(shape: ShapeGraph, corners: Mapping[str, np.ndarray], spacing: float,
                    ) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
    """Corners with every opened attachment closed by moving a contact face of the smaller part."""
    out = {pid: np.array(c, dtype=float) for pid, c in corners.items()}
    bridges = []
    volume = {pid: abs(float(np.linalg.det(np.stack([c[4] - c[0], c[2] - c[0], c[1] - c[0]]))))
              for pid, c in shape.rest_corners().items()}
    for relation in shape.relations.values():
        if not isinstance(relation, Attachment):
            continue
        a, b = relation.members
        if a not in out or b not in out or not (np.all(np.isfinite(out[a])) and np.all(np.isfinite(out[b]))):
            continue
        wa, wb = np.asarray(relation.weights_a, dtype=float), np.asarray(relation.weights_b, dtype=float)
        gap = (wb @ out[b] - wa @ out[a]).mean(axis=0)  # from a's contact to b's
        length = float(np.linalg.norm(gap))
        if length < spacing:
            continue
        mover, weights, move = (a, wa, gap) if volume[a] <= volume[b] else (b, wb, -gap)
        axis, side = _contact_face(weights)
        face = [k for k in range(8) if int(CORNER_BITS[k, axis]) == side]
        out[mover][face] += move * (1 + 1.5 * spacing / length)
        bridges.append({"relation": relation.id, "moved": mover, "gap": length})
    return out, bridges


def remesh(shape: ShapeGraph, evaluation: Evaluation | None = None, resolution: int = DEFAULT_RESOLUTION,
           bridge: bool = True) -> RemeshResult:
    """One watertight mesh of ``shape`` as edited by ``evaluation`` (``None``: at rest).

    ``resolution`` is the number of grid cells along the longest side of the rest
    shape's bounding box; parts thinner than about two cells may break up.
    """
    import trimesh
    from skimage.measure import marching_cubes

    if not isinstance(resolution, int) or resolution < 8 or resolution > 1024:
        raise ParselError(f"remesh resolution must be an integer in [8, 1024], got {resolution!r}")
    evaluation = evaluation if evaluation is not None else Evaluation(shape.rest_corners())
    items = posed_items(shape, evaluation)
    rest = np.concatenate([p.hexahedron.corners for p in shape.parts.values()])
    # The spacing follows the rest shape, so the parts' fields are sampled once for every edit.
    spacing = float((rest.max(axis=0) - rest.min(axis=0)).max()) / resolution
    points = np.concatenate([c for _, _, c in items])
    lo, hi = points.min(axis=0), points.max(axis=0)
    if not spacing > 0:
        raise ParselError(f"shape {shape.name!r} has no extent to remesh")
    bridges: list[dict[str, Any]] = []
    if bridge:
        moved, bridges = bridged_corners(shape, {name: c for name, _, c in items}, spacing)
        items = [(name, source, moved[name]) for name, source, _ in items]
        points = np.concatenate([c for _, _, c in items])
        lo, hi = points.min(axis=0), points.max(axis=0)
    band = BAND_CELLS * spacing
    origin = lo - band - 2 * spacing
    dims = np.ceil((hi + band + 2 * spacing - origin) / spacing).astype(int) + 1
    if int(np.prod(dims)) > 160_000_000:
        raise ParselError(f"remesh grid of {dims.tolist()} cells is too large; lower the resolution")
    union = np.full(tuple(dims), band)
    for _name, source, corners in items:
        part = field_of(shape, source, spacing)
        box_lo = np.floor((corners.min(axis=0) - band - origin) / spacing).astype(int).clip(0, dims - 1)
        box_hi = np.ceil((corners.max(axis=0) + band - origin) / spacing).astype(int).clip(0, dims - 1)
        axes = [np.arange(box_lo[i], box_hi[i] + 1) for i in range(3)]
        index = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        world = origin + index * spacing
        values = _posed_values(part, corners, world)
        block = union[box_lo[0]:box_hi[0] + 1, box_lo[1]:box_hi[1] + 1, box_lo[2]:box_hi[2] + 1]
        np.minimum(block, values.reshape(block.shape), out=block)
    union[[0, -1], :, :] = band
    union[:, [0, -1], :] = band
    union[:, :, [0, -1]] = band
    if union.min() >= 0:
        raise ParselError(f"shape {shape.name!r}: the remesh grid found no inside (resolution too low?)")
    vertices, faces, _normals, _values = marching_cubes(union, level=0.0, spacing=(spacing,) * 3)
    # Marching cubes shares every edge vertex between the faces around it, so its output is
    # already closed; merging vertices by position (trimesh's processing) would pinch it where
    # two sheets pass within float precision of each other, so the mesh is kept as it comes.
    mesh = trimesh.Trimesh(vertices=vertices + origin, faces=faces, process=False)
    if mesh.volume < 0:
        mesh.invert()
    face_parts = _nearest_parts(shape, items, mesh.triangles_center, spacing)
    labels = np.array([shape.parts[items[i][1]].label for i in face_parts], dtype=object)
    names = np.array([items[i][0] for i in face_parts], dtype=object)
    return RemeshResult(mesh, labels, names, spacing, bridges)


def _posed_values(part: PartField, corners: np.ndarray, world: np.ndarray) -> np.ndarray:
    """The part's field at world points, through the inverse cage map of its edited corners."""
    uvw = inverse_trilinear(corners, world)
    ok = np.all(np.isfinite(uvw), axis=1)
    ok[ok] = np.abs(cage_weights(uvw[ok]) @ corners - world[ok]).max(axis=1) < 1e-6 * max(1.0, part.band)
    values = np.full(len(world), part.band)
    values[ok] = part.sample(uvw[ok])
    return values


def _nearest_parts(shape: ShapeGraph, items: list[tuple[str, str, np.ndarray]], centres: np.ndarray,
                   spacing: float) -> np.ndarray:
    """Index into ``items`` of the part whose field is lowest at each face centre."""
    best = np.full(len(centres), np.inf)
    owner = np.zeros(len(centres), dtype=int)
    for i, (_name, source, corners) in enumerate(items):
        part = field_of(shape, source, spacing)
        near = np.all((centres >= corners.min(axis=0) - part.band) & (centres <= corners.max(axis=0) + part.band),
                      axis=1)
        if not near.any():
            continue
        values = _posed_values(part, corners, centres[near])
        better = values < best[near]
        where = np.flatnonzero(near)[better]
        best[where] = values[better]
        owner[where] = i
    return owner
