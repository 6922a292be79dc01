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

import dataclasses
import itertools
import math
from collections.abc import Iterable, Sequence

import numpy as np

from parsel_core.hexahedron import EDGE_NAMES, FACE_NAMES, Hexahedron, canonical_feature_name, feature_corners
from parsel_core.ops import EditOp, Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate, as_vector

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


def _vecs(rows) -> list[tuple[float, float, float]]:
    """:func:`_vec` of every row (rounded together: the same values)."""
    return [tuple(row) for row in (np.round(np.asarray(rows, dtype=float), 12) + 0.0).tolist()]


def _points(rows) -> list[tuple[float, float, float]]:
    """:func:`_vec` of every row as an op stores it in a point field: the same floats, when
    finite (``as_vector`` only checks a point), else through :func:`_vector` (which raises)."""
    vecs = _vecs(rows)
    if all(math.isfinite(c) for v in vecs for c in v):
        return vecs
    return [_vector(Scale1D, "origin", v) for v in vecs]


def candidate_family(op: EditOp) -> str:
    """The hint family of a candidate (``translate``, ``face_scale``, ``free_scale_1d`` ...)."""
    family = getattr(op, "family", None)
    if family is not None:
        return family
    if op.feature is None:
        return op.name
    kind = {2: "face", 4: "edge", 6: "corner"}[len(op.feature)]
    return f"{kind}_{'translate' if op.name == 'translate' else 'scale'}"


#: own_candidates' merged lists by (part, rest corners, hint): the loop, the repair passes
#: and the joint pass search the same parts again (bounded; cleared when full).
_OWN: dict[tuple, tuple[EditOp, ...]] = {}
_OWN_SIZE = 256


def own_candidates(part: str, hexahedron: Hexahedron, hint: str | None = None) -> list[EditOp]:
    """Every merged candidate for ``part`` from its own features, filtered by a type hint.

    The ops are frozen and shared between calls on the same box (a new list each time).
    """
    key = (part, np.asarray(hexahedron.corners, dtype=float).tobytes(), hint)
    ops = _OWN.get(key)
    if ops is None:
        if len(_OWN) >= _OWN_SIZE:
            _OWN.clear()
        ops = _OWN[key] = tuple(_own_candidates(part, hexahedron, hint))
    return list(ops)


def _own_candidates(part: str, hexahedron: Hexahedron, hint: str | None) -> list[EditOp]:
    points = hexahedron.feature_points
    dirs = directions(hexahedron)
    # Each family's merge key depends on one quantity per point (a height along a direction,
    # a point's projection on a plane, the point itself), so an op is new exactly where that
    # quantity first appears: the first of each key is kept, in generation order. Points and
    # directions are normalised once, as the ops' constructors store them.
    point_vecs = _points(points)
    dir_vecs = [_vector(Scale1D, "dir", d) for d in _vecs(dirs)]
    make = _Maker(part)
    ops = [make(Translate, None, dir=dv) for dv in dir_vecs]
    for n, nv in zip(dirs, dir_vecs):
        along = [p @ n for p in points]
        new_height = _first_seen([round(float(a), 7) for a in along])
        # (each point's projection on the plane normal to n, rounded as _key rounds it)
        new_plane = _first_seen(map(tuple, np.round(points - np.array(along)[:, None] * n, 7) + 0.0))
        for pv, height, plane in zip(point_vecs, new_height, new_plane):
            if height:
                ops.append(make(Scale1D, None, origin=pv, dir=nv))
            if plane:  # (a scale_2d and a rotation about n merge by the same projection)
                ops.append(make(Scale2D, None, origin=pv, normal=nv))
                ops.append(make(Rotate, None, origin=pv, axis=nv))
        for d, dv in zip(dirs, dir_vecs):
            if abs(float(n @ d)) <= 1e-6:  # a shear merges by the height along its normal
                ops += [make(Shear, None, origin=pv, normal=nv, dir=dv)
                        for pv, height in zip(point_vecs, new_height) if height]
    ops += [make(Scale3D, None, origin=pv)
            for pv, new in zip(point_vecs, _first_seen(map(tuple, np.round(points, 7) + 0.0))) if new]
    corners = hexahedron.corners
    for face in FACE_NAMES:
        feature = _canonical(face)
        face_points = corners[list(feature_corners(face))]
        normal = hexahedron.face_normal(face)
        face_points = np.concatenate([face_points, face_points.mean(axis=0, keepdims=True)])
        face_vecs = None
        for d, dv in zip(dirs, dir_vecs):
            ops.append(make(Translate, feature, dir=dv))
            if abs(float(d @ normal)) > 0.9:
                continue  # scaling a face along its normal only moves it: a face translation
            if face_vecs is None:
                face_vecs = _points(face_points)
            ops += [make(Scale1D, feature, origin=pv, dir=dv)
                    for pv, new in zip(face_vecs, _first_seen([round(float(p @ d), 7) for p in face_points])) if new]
    for edge in EDGE_NAMES:
        feature = _canonical(edge)
        ops += [make(Translate, feature, dir=dv) for dv in dir_vecs]
    if hint in HINT_TYPES:
        ops = [op for op in ops if candidate_family(op) in HINT_TYPES[hint]]
    return ops


def _first_seen(keys: Iterable) -> list[bool]:
    """Whether each key is the first of its value."""
    seen: set = set()
    out = []
    for key in keys:
        out.append(key not in seen)
        seen.add(key)
    return out


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
    for key, op in _about_neighbours(part, neighbour_hexahedra).items():
        out.setdefault(key, op)
    ops = list(out.values())
    if hint in HINT_TYPES:
        ops = [op for op in ops if candidate_family(op) in HINT_TYPES[hint]]
    return ops


#: _about_neighbour's specs by a neighbour's corners; bounded.
_ABOUT: dict[bytes, tuple[tuple[tuple, type, dict, list | None], ...]] = {}
_ABOUT_SIZE = 1024


def _about_neighbours(part: str, neighbour_hexahedra: Sequence[Hexahedron]) -> dict[tuple, EditOp]:
    """Ops of ``part`` about the neighbours' feature points and along their axes, merged
    (first of each key kept, in order). What a neighbour offers does not depend on the
    part, so each neighbour's keys and normalised fields are worked out once
    (:func:`_about_neighbour`) and only the ops are built for each part."""
    out: dict[tuple, EditOp] = {}
    new = object.__new__
    for neighbour in neighbour_hexahedra:
        for key, cls, params, fields in _about_neighbour(neighbour):
            if key not in out:
                if fields is None:
                    out[key] = cls(part, "f", **params)
                else:  # (_build, with the fields in one dictionary)
                    op = out[key] = new(cls)
                    op.__dict__.update(fields)
                    op.__dict__["operand"] = part
    return out


def _about_neighbour(neighbour: Hexahedron) -> tuple[tuple[tuple, type, dict, dict | None], ...]:
    """``(merge key, class, parameters, the op's fields with a placeholder operand, or
    None)`` of every op about one neighbour's feature points and along its axes, in order,
    each key once."""
    cached = _ABOUT.get(corners := np.asarray(neighbour.corners, dtype=float).tobytes())
    if cached is not None:
        return cached
    specs: dict[tuple, tuple[tuple, type, dict, dict | None]] = {}
    own = {cls: _own_fields(cls) for cls in (Rotate, Scale1D, Translate, Scale3D)}

    def add(cls: type, params: dict, normalised: dict) -> None:
        names = own[cls]
        if names is None:  # a class _make leaves to its constructor
            op = cls("p", "f", **params)
            key = (op.name, tuple(sorted(op.params().items())))
            fields = None
        else:
            fields = [(name, normalised[name]) for name in names]
            key = (cls.name, tuple(sorted(fields)))
            fields = {"operand": "p", "amount": "f", "feature": None, **dict(fields)}
        if key not in specs:
            specs[key] = (key, cls, params, fields)

    points = _vecs(neighbour.feature_points)
    origins = _points(neighbour.feature_points)  # (every class stores a point alike)
    for n in _vecs(directions(neighbour)):
        unit = _vector(Scale1D, "dir", n)
        for p, origin in zip(points, origins):
            add(Rotate, {"origin": p, "axis": n}, {"origin": origin, "axis": unit})
            add(Scale1D, {"origin": p, "dir": n}, {"origin": origin, "dir": unit})
        add(Translate, {"dir": n}, {"dir": unit})
    for p, origin in zip(points, origins):
        add(Scale3D, {"origin": p}, {"origin": origin})
    if len(_ABOUT) >= _ABOUT_SIZE:
        _ABOUT.clear()
    out = _ABOUT[corners] = tuple(specs.values())
    return out


def _own_fields(cls: type) -> tuple[str, ...] | None:
    """The names of ``cls``'s own fields when :func:`_build` makes its ops as its
    constructor does, else ``None``."""
    if cls not in _LAYOUT:
        _make(cls, "p")  # (checks the class)
    own, exact = _LAYOUT[cls]
    return tuple(name for name, _ in own) if exact else None


def _build(cls: type, part: str, fields, feature: str | None = None) -> EditOp:
    """The op :func:`_make` builds, from fields already normalised (:func:`_vector`) and
    a canonical feature name: a frozen dataclass, its fields set as the constructor sets them."""
    op = object.__new__(cls)
    op.__dict__.update(operand=part, amount="f", feature=feature)
    op.__dict__.update(fields)
    return op


#: Normalised vector fields by (unit, value): what ``EditOp.__post_init__`` makes of them.
_VECTORS: dict[tuple, tuple[float, float, float]] = {}
#: Per op class: its own fields (name, default), and whether :func:`_make` builds it
#: exactly as the constructor does (checked on the first op of each class).
_LAYOUT: dict[type, tuple[tuple[tuple[str, object], ...], bool]] = {}


def _make(cls: type, part: str, feature: str | None = None, normalised: bool = False, **params) -> EditOp:
    """``cls(part, "f", feature=feature, **params)`` for the valid parameters candidates use,
    without validating them again (a few hundred ops per part, every one a dataclass whose
    ``__post_init__`` parses the amount and normalises each vector). The fields hold the
    values the constructor would store: vectors normalised as ``as_vector`` does (cached;
    ``normalised``: the vectors given already are, each normalised once for many ops),
    the feature name made canonical. The first op of each class is also built by its
    constructor and compared; a class where the two differ is always built by it."""
    layout = _LAYOUT.get(cls)
    if layout is None:
        own = tuple((f.name, f.default) for f in dataclasses.fields(cls)
                    if f.name not in ("operand", "amount", "feature"))
        _LAYOUT[cls] = (own, True)
        try:
            built = cls(part, "f", feature=feature, **params)
            same = _fast_make(cls, own, part, feature, params)
            exact = type(same) is cls and same == built and vars(same) == vars(built)
        except Exception:  # anything unusual: the constructor decides
            exact = False
        layout = _LAYOUT[cls] = (own, exact)
    if not layout[1]:
        return cls(part, "f", feature=feature, **params)
    return _fast_make(cls, layout[0], part, feature, params, normalised)


def _vector(cls: type, name: str, value):
    """The value ``EditOp.__post_init__`` stores for field ``name`` (vectors normalised)."""
    unit = name in cls.unit_fields
    if not (unit or name in cls.point_fields):
        return value
    # (-0.0 == 0.0, but as_vector keeps the sign)
    key = (unit, value, tuple(math.copysign(1.0, v) for v in value) if 0.0 in value else None)
    vector = _VECTORS.get(key)
    if vector is None:
        if len(_VECTORS) >= 100_000:
            _VECTORS.clear()
        vector = _VECTORS[key] = as_vector(value, f"{cls.name}.{name}", unit=unit)
    return vector


def _fast_make(cls: type, own, part: str, feature: str | None, params: dict, normalised: bool = False) -> EditOp:
    fields = {}
    for name, default in own:
        if normalised and name in params:
            fields[name] = params[name]
            continue
        value = params.get(name, default)
        if value is dataclasses.MISSING:
            return cls(part, "f", feature=feature, **params)
        fields[name] = _vector(cls, name, value)
    return _build(cls, part, fields, None if feature is None else _canonical(feature))


class _Maker:
    """Builds ``part``'s candidate ops from normalised fields (in the class's field order)
    and a canonical feature name: by :func:`_build` for a class it builds exactly as the
    constructor does, given every field; by :func:`_make` otherwise."""

    def __init__(self, part: str) -> None:
        self.part = part
        self.direct: dict[type, frozenset[str]] = {}

    def __call__(self, cls: type, feature: str | None, **fields) -> EditOp:
        names = self.direct.get(cls)
        if names is None:
            names = self.direct[cls] = frozenset(_own_fields(cls) or ())
        if names and fields.keys() == names:
            return _build(cls, self.part, fields, feature)
        return _make(cls, self.part, feature, normalised=True, **fields)


_CANONICAL: dict[str, str] = {}


def _canonical(feature: str) -> str:
    name = _CANONICAL.get(feature)
    if name is None:
        feature_corners(feature)  # (raises for a name that is not a feature)
        name = _CANONICAL[feature] = canonical_feature_name(feature)
    return name
