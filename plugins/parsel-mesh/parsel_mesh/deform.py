"""The cage deformer: part meshes follow their edited hexahedra through cage coordinates.

Each vertex is held by its 8 trilinear weights in the part's rest hexahedron
(``parsel_core.cage.point_weights``), computed once per shape and part, so deforming is
one ``(m, 8) @ (8, 3)`` product per part. Vertices outside the box (there are none for
fitted boxes, but meshes may be edited) extrapolate the same map. The products run on one
BLAS thread (:func:`parsel_core.blas.one_blas_thread`): three columns wide, they gain little from OpenBLAS's
threads on an idle machine, and those threads slow them down many times over as soon as
other work shares the cores.

:func:`deformed_vertices` returns fresh float64 arrays (exports, pictures, tests);
:class:`LiveDeformation` is the slider's form: float32 operands and vertex buffers reused
from step to step, only the parts whose corners moved since the last step recomputed, and
affinely edited parts moved by a 4-column product of their rest vertices.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import DTypeLike

from parsel_core.blas import one_blas_thread
from parsel_core.cage import point_weights
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import Deformer
from parsel_core.program import Evaluation

# shape -> part id -> (part, weights); weak so that dropping a shape frees its weights.
_WEIGHTS: weakref.WeakKeyDictionary[ShapeGraph, dict[str, tuple[Any, np.ndarray]]] = weakref.WeakKeyDictionary()


def instance_name(member: str, index: int) -> str:
    """Name of the ``index``-th instance of a group laid out from ``member``."""
    return f"{member}#{index}"


def part_mesh(shape: ShapeGraph, part_id: str) -> Any:
    """A part's mesh, or an error naming the part when it has none (a shape read from corners)."""
    mesh = shape.part(part_id).mesh
    if mesh is None or not hasattr(mesh, "vertices"):
        raise ParselError(f"shape {shape.name!r}: part {part_id!r} has no mesh to deform "
                          f"(shapes read from hexahedra export with .hex.json)")
    return mesh


def cage_weights_of(shape: ShapeGraph, part_id: str) -> np.ndarray:
    """Cage coordinates (m, 8) of the part's mesh vertices in its rest hexahedron, cached."""
    per_shape = _WEIGHTS.setdefault(shape, {})
    part = shape.part(part_id)
    cached = per_shape.get(part_id)
    if cached is not None and cached[0] is part:  # parts are frozen: same part, same mesh and box
        return cached[1]
    mesh = part_mesh(shape, part_id)
    weights = point_weights(part.hexahedron.corners, np.asarray(mesh.vertices, dtype=float))
    weights.flags.writeable = False
    per_shape[part_id] = (part, weights)
    return weights


def _corners(evaluation: Evaluation, part_id: str) -> np.ndarray:
    corners = np.asarray(evaluation.parts[part_id], dtype=float)
    if corners.shape != (8, 3):
        raise ParselError(f"cannot deform part {part_id!r} at a batch of parameter values "
                          f"(corners of shape {corners.shape}); evaluate one value at a time")
    return corners


def deformed_vertices(shape: ShapeGraph, evaluation: Evaluation) -> dict[str, np.ndarray]:
    """Deformed vertex arrays per part id, and per ``<member>#<i>`` instance of re-laid-out groups.

    Members of a group whose layout a group op changed are replaced by the group's
    instances, each a copy of the first member's mesh in that instance's corners.
    """
    replaced = {m for group in evaluation.instances for m in shape.relation(group).members}
    weights = {pid: cage_weights_of(shape, pid) for pid in shape.parts if pid not in replaced}
    firsts = {group: shape.relation(group).members[0] for group in evaluation.instances}
    weights.update({first: cage_weights_of(shape, first) for first in firsts.values()})
    with one_blas_thread():
        out = {pid: weights[pid] @ _corners(evaluation, pid) for pid in shape.parts if pid not in replaced}
        for group, instances in evaluation.instances.items():
            first = firsts[group]
            stacked = weights[first] @ np.asarray(instances, dtype=float)  # (n, m, 3)
            out.update({instance_name(first, i): vertices for i, vertices in enumerate(stacked)})
    return out


#: An edit is treated as affine when its corners fit an affine map of the rest corners to
#: this fraction of their magnitude; vertices inside the box then move by at most that much
#: more than under the trilinear map (their weights are non-negative and sum to 1).
AFFINE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class _Cage:
    """What a live deformation keeps per part, built once."""

    rest: np.ndarray     # (m, 4) rest vertices with a 1 appended, for affine edits
    weights: np.ndarray  # (m, 8) cage coordinates, for the others
    fit: np.ndarray      # (4, 8) least-squares affine map from the 8 corners (pseudo-inverse)
    corners: np.ndarray  # (8, 4) rest corners with a 1 appended


class LiveDeformation:
    """Deformed vertices for an interactive slider: call it once per slider step.

    Built once per shape: every part's rest vertices and cage coordinates, in ``dtype``
    (float32 by default: half the time and memory of float64 for a relative error near
    1e-7, far below a pixel), and a vertex buffer per part and group instance that every
    step writes into, so that a step allocates nothing per vertex. A step recomputes only
    the parts and instances whose corners differ from the previous step's. Most edits
    (translate, rotate, scale, shear, a face moved along an axis, group copies) map the
    rest box affinely; those parts are one ``(m, 4) @ (4, 3)`` product of the rest
    vertices, the others ``(m, 8) @ (8, 3)`` of the cage coordinates. A step returns
    read-only views of the buffers: they change with the next step, so copy what must
    outlive it. ``dtype=np.float64`` gives the values of :func:`deformed_vertices` to
    rounding.

    ``order`` is the buffers' memory layout, numpy's: ``"F"`` (the default) stores each
    coordinate contiguously (``view.T`` is a C-contiguous ``(3, m)`` array), which makes
    the products ``(3, k) @ (k, m)``: a step of the 437k-vertex chair deformed 1.4-1.6
    times faster on one core than into ``"C"`` buffers of interleaved ``x, y, z``
    (docs/meshes.md). Ask for ``"C"`` when the vertices go to something that needs them
    interleaved (a GPU vertex buffer): that costs less than a transposing copy.
    """

    def __init__(self, shape: ShapeGraph, dtype: DTypeLike = np.float32, order: str = "F") -> None:
        if order not in ("C", "F"):
            raise ValueError(f"order must be 'C' or 'F', got {order!r}")
        self.shape = shape
        self.dtype = np.dtype(dtype)
        self.order = order
        self._cages = {pid: self._cage(pid) for pid in shape.parts}
        # name -> (buffer, read-only view of it, corners it was last computed for)
        self._vertices: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray | None]] = {}

    def _cage(self, part_id: str) -> _Cage:
        weights = cage_weights_of(self.shape, part_id)
        vertices = np.asarray(part_mesh(self.shape, part_id).vertices, dtype=float)
        corners = np.hstack([self.shape.part(part_id).hexahedron.corners, np.ones((8, 1))])
        # Column-major operands: their transposes are the row-major (k, m) factors of an
        # "F" step, and a "C" step's tall, thin products ran 10-30% faster from them than
        # from row-major ones (OpenBLAS, one core, 20k-80k-vertex parts)
        rest = np.asfortranarray(np.hstack([vertices, np.ones((len(vertices), 1))]), dtype=self.dtype)
        cage = _Cage(rest, np.asfortranarray(weights, dtype=self.dtype), np.linalg.pinv(corners), corners)
        for array in (cage.rest, cage.weights):
            array.flags.writeable = False
        return cage

    def __call__(self, evaluation: Evaluation) -> dict[str, np.ndarray]:
        """Deformed vertices per part id and ``<member>#<i>`` instance, as :func:`deformed_vertices` names them."""
        shape = self.shape
        replaced = {m for group in evaluation.instances for m in shape.relation(group).members}
        moved: list[tuple[str, _Cage, np.ndarray]] = []  # (name, cage, corners) to recompute
        out: dict[str, np.ndarray] = {}
        for pid in shape.parts:
            if pid not in replaced:
                out[pid] = self._view(pid, self._cages[pid], _corners(evaluation, pid), moved)
        for group, instances in evaluation.instances.items():
            first = shape.relation(group).members[0]
            for i, corners in enumerate(np.asarray(instances, dtype=float)):
                name = instance_name(first, i)
                out[name] = self._view(name, self._cages[first], corners, moved)
        if moved:
            with one_blas_thread():
                for name, cage, corners in moved:
                    buffer, view, _ = self._vertices[name]
                    self._deform(cage, corners, buffer)
                    self._vertices[name] = (buffer, view, corners.copy())
        return out

    def _deform(self, cage: _Cage, corners: np.ndarray, out: np.ndarray) -> None:
        affine = cage.fit @ corners  # (4, 3): rows x, y, z and the translation
        scale = 1.0 + float(np.abs(corners).max())
        if float(np.abs(cage.corners @ affine - corners).max()) <= AFFINE_TOLERANCE * scale:
            operand, factor = cage.rest, affine
        else:
            operand, factor = cage.weights, corners
        factor = factor.astype(self.dtype)
        if self.order == "F":  # out^T = factor^T operand^T: every operand row-major, out^T too
            np.matmul(factor.T, operand.T, out=out.T)
        else:
            np.matmul(operand, factor, out=out)

    def _view(self, name: str, cage: _Cage, corners: np.ndarray,
              moved: list[tuple[str, _Cage, np.ndarray]]) -> np.ndarray:
        """The read-only view of ``name``'s buffer; queues the product when its corners moved."""
        entry = self._vertices.get(name)
        if entry is None:
            buffer = np.empty((len(cage.rest), 3), dtype=self.dtype, order=self.order)
            view = buffer.view()
            view.flags.writeable = False
            entry = self._vertices[name] = (buffer, view, None)
        last = entry[2]
        if last is None or not np.array_equal(last, corners):
            moved.append((name, cage, corners))
        return entry[1]


def source_part(shape: ShapeGraph, name: str) -> str:
    """The part whose mesh a deformed name comes from (``leg#2`` -> ``leg``)."""
    return name if name in shape.parts else name.rpartition("#")[0]


def deformed_meshes(shape: ShapeGraph, evaluation: Evaluation | None = None) -> dict[str, Any]:
    """Deformed trimesh per part (and instance), faces and materials of the source mesh kept.

    ``evaluation=None`` means the rest shape (every part at its own corners).
    """
    import trimesh

    evaluation = evaluation if evaluation is not None else Evaluation(shape.rest_corners())
    meshes = {}
    for name, vertices in deformed_vertices(shape, evaluation).items():
        source = part_mesh(shape, source_part(shape, name))
        visual = source.visual.copy() if getattr(source, "visual", None) is not None else None
        meshes[name] = trimesh.Trimesh(vertices=vertices, faces=source.faces, visual=visual,
                                       metadata={"name": name}, process=False, validate=False)
    return meshes


class CageDeformer(Deformer):
    """Moves part meshes with their hexahedra by cached cage coordinates (``cage``)."""

    name = "cage"

    def deform(self, shape: ShapeGraph, evaluation: Evaluation) -> Mapping[str, Any]:
        """``{part id or '<member>#<i>': trimesh.Trimesh}`` in the evaluated corners."""
        return deformed_meshes(shape, evaluation)

    def vertices(self, shape: ShapeGraph, evaluation: Evaluation) -> dict[str, np.ndarray]:
        """Only the vertex arrays: the cheapest form for an interactive slider."""
        return deformed_vertices(shape, evaluation)

    def live(self, shape: ShapeGraph, dtype: DTypeLike = np.float32, order: str = "F") -> LiveDeformation:
        """A :class:`LiveDeformation` of ``shape``: the fastest form for a slider, one call per step."""
        return LiveDeformation(shape, dtype, order)
