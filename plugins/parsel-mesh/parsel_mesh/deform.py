"""The cage deformer: part meshes follow their edited hexahedra through cage coordinates.

Each vertex is held by its 8 trilinear weights in the part's rest hexahedron
(``parsel_core.cage.point_weights``), computed once per shape and part, so a slider step
is one ``(m, 8) @ (8, 3)`` product per part. Vertices outside the box (there are none for
fitted boxes, but meshes may be edited) extrapolate the same map. The products run on one
BLAS thread (:func:`one_blas_thread`): they are bound by memory, and OpenBLAS's threads
slow them down many times over as soon as other work shares the cores.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np

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


@cache
def _blas_controller():
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # finds the loaded BLAS libraries once per process


def one_blas_thread():
    """A context in which BLAS (numpy's OpenBLAS) runs on one thread.

    Measured with ``benchmarks/bench_deform.py --vertices 437000`` on a shared 2-core
    machine: deforming took 37-42 ms on one thread against 600-650 ms on OpenBLAS's
    default threads next to two busy processes, 12-13 ms against 24-92 ms without them;
    entering the context costs about 10 microseconds.
    """
    return _blas_controller().limit(limits=1, user_api="blas")


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
