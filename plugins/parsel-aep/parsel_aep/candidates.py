"""Candidate edits for a part, drawn from its own features (paper 5.3, supplement alg. 2).

Parameters come from the hexahedron's 27 feature points and from the global and local
axes. Equivalent candidates are merged as they are generated, by the quantities each
op actually depends on:

* a translation depends on its direction up to sign (the amount absorbs the sign);
* ``scale_1d`` about ``o`` along ``n`` only on ``o . n``; ``shear`` likewise on the
  normal's coordinate of ``o``;
* ``scale_2d`` with normal ``n`` and a rotation about axis ``n`` only on the
  projection of ``o`` onto the plane normal to ``n``;

so for a box ~200 candidates remain instead of thousands.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence

import numpy as np

from parsel_core.hexahedron import EDGE_NAMES, FACE_NAMES, Hexahedron, feature_corners
from parsel_core.ops import EditOp, Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate

#: Which op families a type hint allows (reference section 4, step 8).
HINT_TYPES = {
    "translate": ("translate",),
    "rotate": ("rotate",),
    "scale": ("scale_1d", "scale_2d", "scale_3d", "face_translate", "face_scale", "edge_translate", "shear"),
}
#: Ops in order of simplicity: the last tie-break between equally good edits.
SIMPLICITY = ("translate", "rotate", "scale_1d", "scale_3d", "scale_2d", "face_translate", "shear",
              "face_scale", "edge_translate")


def _key(values: Iterable[float]) -> tuple:
    return tuple(np.round(np.asarray(list(values), dtype=float), 7) + 0.0)


def directions(hexahedron: Hexahedron) -> list[np.ndarray]:
    """Global axes and the part's local axes, merged up to sign."""
    out: dict[tuple, np.ndarray] = {}
    for d in itertools.chain(np.eye(3), hexahedron.local_axes):
        d = d / np.linalg.norm(d)
        d = -d if d[np.argmax(np.abs(d))] < 0 else d
        out.setdefault(_key(d), d)
    return list(out.values())


def _vec(v: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(c) + 0.0 for c in np.round(v, 12))


def candidate_family(op: EditOp) -> str:
    """The hint family of a candidate (``translate``, ``face_scale``, ``free_scale_1d`` ...)."""
    family = getattr(op, "family", None)
    if family is not None:
        return family
    if op.feature is None:
        return op.name
    kind = {2: "face", 4: "edge", 6: "corner"}[len(op.feature)]
    return f"{kind}_{'translate' if op.name == 'translate' else 'scale'}"


def own_candidates(part: str, hexahedron: Hexahedron, hint: str | None = None) -> list[EditOp]:
    """Every merged candidate for ``part`` from its own features, filtered by a type hint."""
    points = hexahedron.feature_points
    dirs = directions(hexahedron)
    out: dict[tuple, EditOp] = {}

    def add(key: tuple, op: EditOp) -> None:
        out.setdefault(key, op)

    for d in dirs:
        add(("translate", _key(d)), Translate(part, "f", dir=_vec(d)))
    for n in dirs:
        for p in points:
            add(("scale_1d", _key(n), round(float(p @ n), 7)), Scale1D(part, "f", origin=_vec(p), dir=_vec(n)))
            in_plane = p - (p @ n) * n
            add(("scale_2d", _key(n), _key(in_plane)), Scale2D(part, "f", origin=_vec(p), normal=_vec(n)))
            add(("rotate", _key(n), _key(in_plane)), Rotate(part, "f", origin=_vec(p), axis=_vec(n)))
        for d in dirs:
            if abs(float(n @ d)) > 1e-6:
                continue
            for p in points:
                add(("shear", _key(n), _key(d), round(float(p @ n), 7)),
                    Shear(part, "f", origin=_vec(p), normal=_vec(n), dir=_vec(d)))
    for p in points:
        add(("scale_3d", _key(p)), Scale3D(part, "f", origin=_vec(p)))
    corners = hexahedron.corners
    for face in FACE_NAMES:
        face_points = corners[list(feature_corners(face))]
        normal = hexahedron.face_normal(face)
        for d in dirs:
            add(("face_translate", face, _key(d)), Translate(part, "f", feature=face, dir=_vec(d)))
            if abs(float(d @ normal)) > 0.9:
                continue  # scaling a face along its normal only moves it: a face translation
            for p in np.concatenate([face_points, face_points.mean(axis=0, keepdims=True)]):
                add(("face_scale", face, _key(d), round(float(p @ d), 7)),
                    Scale1D(part, "f", feature=face, origin=_vec(p), dir=_vec(d)))
    for edge in EDGE_NAMES:
        for d in dirs:
            add(("edge_translate", edge, _key(d)), Translate(part, "f", feature=edge, dir=_vec(d)))
    ops = list(out.values())
    if hint in HINT_TYPES:
        ops = [op for op in ops if candidate_family(op) in HINT_TYPES[hint]]
    return ops


def neighbour_candidates(part: str, hexahedron: Hexahedron, neighbour_ops: Sequence[EditOp],
                         neighbour_hexahedra: Sequence[Hexahedron], hint: str | None = None) -> list[EditOp]:
    """nhbd-edits (paper 5.3.1): parameters borrowed from edited neighbours.

    The neighbours' own edit parameters (a handle rotates about its door's hinge), ops
    about the neighbours' feature points, and translations along the line from this
    part to the origin of a neighbour's scaling.
    """
    out: dict[tuple, EditOp] = {}
    centre = hexahedron.center

    def add(op: EditOp) -> None:
        out.setdefault((op.name, tuple(sorted(op.params().items()))), op)

    for op in neighbour_ops:
        if op.acts_on != "part" or op.name == "keep_fixed":
            continue
        params = {k: v for k, v in op.params().items()}
        try:
            add(type(op)(part, "f", **params))
        except Exception:  # an op type that takes other parameters for a new operand
            continue
        origin = params.get("origin")
        if origin is not None and op.name.startswith("scale"):
            line = centre - np.asarray(origin)
            if np.linalg.norm(line) > 1e-9:
                add(Translate(part, "f", dir=_vec(line / np.linalg.norm(line))))
    for neighbour in neighbour_hexahedra:
        for n in directions(neighbour):
            for p in neighbour.feature_points:
                add(Rotate(part, "f", origin=_vec(p), axis=_vec(n)))
                add(Scale1D(part, "f", origin=_vec(p), dir=_vec(n)))
            add(Translate(part, "f", dir=_vec(n)))
        for p in neighbour.feature_points:
            add(Scale3D(part, "f", origin=_vec(p)))
    ops = list(out.values())
    if hint in HINT_TYPES:
        ops = [op for op in ops if candidate_family(op) in HINT_TYPES[hint]]
    return ops
