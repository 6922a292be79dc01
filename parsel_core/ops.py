"""The editing DSL: parameterized edit operators (reference section 3, supplement table 2).

Every part operator is a point map ``p -> T(p; amount)`` written once and used on three
kinds of values: float arrays (the reference numeric path, batched over parameter
samples), numpy object arrays of CAS expressions (the symbolic path that edit
propagation solves on and that compiled evaluation lambdifies), and single points.
Applied to a whole part the map moves all 8 corners; applied to a feature (a face, an
edge, a corner) it moves only that feature's corners, which gives tapers and other
non-affine edits.

Amounts are expression text over named control parameters (``"x"``, ``"0.5*x"``),
parsed safely by :mod:`parsel_core.expressions`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from parsel_core.errors import ProgramFormatError
from parsel_core.expressions import parse_expression
from parsel_core.hexahedron import canonical_feature_name, feature_corners

Vector = tuple[float, float, float]


def as_vector(value: Any, field_name: str, *, unit: bool = False) -> Vector:
    """Three finite floats; unit vectors are normalised unless already of length 1."""
    if type(value) is tuple and len(value) == 3 and all(type(v) is float and math.isfinite(v) for v in value):
        # The common case (edit propagation builds tens of thousands of ops) without numpy:
        # the same tuple comes back whenever the general path would return it unchanged.
        # A direction is kept when its squared length is within 1e-14 of 1, far inside the
        # 1e-12 below, whatever the rounding of the norm; anything else takes that path.
        x, y, z = value
        if not unit or abs(x * x + y * y + z * z - 1.0) < 1e-14:
            return value
    try:
        vector = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an integer beyond any float
        raise ProgramFormatError(f"field {field_name!r} must be 3 numbers, got {value!r}") from None
    if not np.all(np.isfinite(vector)):
        raise ProgramFormatError(f"field {field_name!r} must be finite, got {value!r}")
    if unit:
        norm = float(np.linalg.norm(vector))
        if norm < 1e-12:
            raise ProgramFormatError(f"field {field_name!r} must be a non-zero direction")
        if abs(norm - 1.0) > 1e-12:
            vector = vector / norm
    return (float(vector[0]), float(vector[1]), float(vector[2]))


def _dot(points: np.ndarray, n: Vector) -> np.ndarray:
    """Row-wise dot product with a constant vector, keeping the last axis (works on objects)."""
    return (points[..., 0:1] * n[0] + points[..., 1:2] * n[1] + points[..., 2:3] * n[2])


def _cross(n: Vector, points: np.ndarray) -> np.ndarray:
    """``n x p`` for each row p (works on object arrays, unlike np.cross)."""
    x, y, z = points[..., 0:1], points[..., 1:2], points[..., 2:3]
    return np.concatenate([n[1] * z - n[2] * y, n[2] * x - n[0] * z, n[0] * y - n[1] * x], axis=-1)


def _vec(v: Vector) -> np.ndarray:
    return np.asarray(v, dtype=float)


@dataclass(frozen=True)
class EditOp:
    """One edit: an operator, its operand, its numeric parameters and its amount.

    ``operand`` is a part id (or, for group operators, a symmetry relation id);
    ``feature`` optionally restricts a part operator to a face/edge/corner of that part
    (names as in :mod:`parsel_core.hexahedron`); ``amount`` is expression text.
    """

    #: The name in the text form and in JSON (``"scale_1d"``).
    name: ClassVar[str] = ""
    #: Whether the op moves points (part ops) or re-lays out a symmetry group.
    acts_on: ClassVar[str] = "part"
    #: Fields holding unit directions; normalised on construction.
    unit_fields: ClassVar[tuple[str, ...]] = ()
    #: Fields holding points.
    point_fields: ClassVar[tuple[str, ...]] = ()

    operand: str
    amount: str = "x"
    feature: str | None = field(default=None, kw_only=True)

    def __post_init__(self) -> None:
        if not isinstance(self.operand, str) or not self.operand:
            raise ProgramFormatError(f"{self.name}: operand must be a part or relation id, got {self.operand!r}")
        parse_expression(self.amount)
        if self.feature is not None:
            if self.acts_on != "part":
                raise ProgramFormatError(f"{self.name}: acts on a symmetry group and takes no feature")
            try:
                feature_corners(self.feature)
            except ValueError as exc:
                raise ProgramFormatError(f"{self.name} on {self.operand!r}: {exc}") from None
            object.__setattr__(self, "feature", canonical_feature_name(self.feature))
        for name in self.unit_fields:
            object.__setattr__(self, name, as_vector(getattr(self, name), f"{self.name}.{name}", unit=True))
        for name in self.point_fields:
            object.__setattr__(self, name, as_vector(getattr(self, name), f"{self.name}.{name}"))

    @property
    def parameters(self) -> frozenset[str]:
        """Names of the control parameters the amount uses."""
        return parse_expression(self.amount).names

    @property
    def corner_indices(self) -> tuple[int, ...]:
        """The corners this op moves: all 8, or the feature's."""
        return tuple(range(8)) if self.feature is None else feature_corners(self.feature)

    def params(self) -> dict[str, Any]:
        """The op's own numeric parameters (not operand, feature or amount)."""
        skip = {"operand", "amount", "feature"}
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name not in skip}

    def transform(self, points: np.ndarray, amount: Any, math: Any) -> np.ndarray:
        """Map points (..., m, 3) by this op at ``amount``; ``math`` supplies sin/cos."""
        raise NotImplementedError

    def apply(self, corners: np.ndarray, amount: Any, math: Any) -> np.ndarray:
        """Corners after this op: the op's map on the moved corners, the rest unchanged."""
        if self.feature is None:
            return self.transform(corners, amount, math)
        index = list(self.corner_indices)
        moved = self.transform(corners[..., index, :], amount, math)
        dtype = object if object in (corners.dtype, moved.dtype) else np.result_type(corners, moved)
        out = np.array(np.broadcast_to(corners, moved.shape[:-2] + (8, 3)), dtype=dtype)
        out[..., index, :] = moved
        return out

    def mirrored(self, origin: Vector, normal: Vector, operand: str,
                 feature_map: Mapping[str, str] | None = None) -> EditOp:
        """This op as seen in a mirror (E* = T(E), paper 5.3): points and directions reflected.

        Used to restore a reflection symmetry when one partner was edited. Axes of
        rotation are pseudo-vectors: reflecting one also flips the sense of rotation.
        """
        o, n = _vec(origin), _vec(normal)

        def point(p):
            p = _vec(p)
            return tuple(map(float, p - 2.0 * np.dot(p - o, n) * n))

        def direction(d):
            d = _vec(d)
            return tuple(map(float, d - 2.0 * np.dot(d, n) * n))

        changes: dict[str, Any] = {"operand": operand}
        for name in self.point_fields:
            changes[name] = point(getattr(self, name))
        for name in self.unit_fields:
            changes[name] = direction(getattr(self, name))
        if self.feature is not None:
            changes["feature"] = (feature_map or {}).get(self.feature, self.feature)
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class Translate(EditOp):
    """``H(x) = H0 + x n``."""

    name: ClassVar[str] = "translate"
    unit_fields: ClassVar[tuple[str, ...]] = ("dir",)
    dir: Vector = (1.0, 0.0, 0.0)

    def transform(self, points, amount, math):
        return points + _vec(self.dir) * amount


@dataclass(frozen=True)
class Rotate(EditOp):
    """``H(x) = o + R(x) (H0 - o)``, R the rotation by angle x about unit axis n (Rodrigues)."""

    name: ClassVar[str] = "rotate"
    unit_fields: ClassVar[tuple[str, ...]] = ("axis",)
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    axis: Vector = (0.0, 1.0, 0.0)

    def transform(self, points, amount, math):
        o = _vec(self.origin)
        centred = points - o
        cos, sin = math.cos(amount), math.sin(amount)
        # R(x) p = cos x p + sin x (n x p) + (1 - cos x)(p . n) n
        rotated = centred * cos + _cross(self.axis, centred) * sin + _dot(centred, self.axis) * _vec(
            self.axis) * (1 - cos)
        return o + rotated

    def mirrored(self, origin, normal, operand, feature_map=None):
        op = super().mirrored(origin, normal, operand, feature_map)
        return dataclasses.replace(op, axis=tuple(-c for c in op.axis))


@dataclass(frozen=True)
class Scale1D(EditOp):
    """``H(x) = o + Hc + x (Hc . n) n`` with ``Hc = H0 - o``: stretch along n."""

    name: ClassVar[str] = "scale_1d"
    unit_fields: ClassVar[tuple[str, ...]] = ("dir",)
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    dir: Vector = (1.0, 0.0, 0.0)

    def transform(self, points, amount, math):
        o = _vec(self.origin)
        centred = points - o
        return o + centred + _dot(centred, self.dir) * _vec(self.dir) * amount


@dataclass(frozen=True)
class Scale2D(EditOp):
    """``H(x) = o + (1 + x)(Hc - (Hc . n) n) + (Hc . n) n``: scale in the plane normal to n."""

    name: ClassVar[str] = "scale_2d"
    unit_fields: ClassVar[tuple[str, ...]] = ("normal",)
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    normal: Vector = (0.0, 1.0, 0.0)

    def transform(self, points, amount, math):
        o = _vec(self.origin)
        centred = points - o
        along = _dot(centred, self.normal) * _vec(self.normal)
        return o + (centred - along) * (1 + amount) + along


@dataclass(frozen=True)
class Scale3D(EditOp):
    """``H(x) = o + (1 + x)(H0 - o)``: uniform scaling about o."""

    name: ClassVar[str] = "scale_3d"
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)

    def transform(self, points, amount, math):
        o = _vec(self.origin)
        return o + (points - o) * (1 + amount)


@dataclass(frozen=True)
class Shear(EditOp):
    """``H(x) = o + (I + x d n^T) Hc``: points slide along d in proportion to their height along n."""

    name: ClassVar[str] = "shear"
    unit_fields: ClassVar[tuple[str, ...]] = ("normal", "dir")
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    normal: Vector = (0.0, 1.0, 0.0)
    dir: Vector = (1.0, 0.0, 0.0)

    def transform(self, points, amount, math):
        o = _vec(self.origin)
        centred = points - o
        return o + centred + _dot(centred, self.normal) * _vec(self.dir) * amount


@dataclass(frozen=True)
class KeepFixed(EditOp):
    """``H(x) = H0``: marks a part that propagation must not move."""

    name: ClassVar[str] = "keep_fixed"
    amount: str = "0"

    def transform(self, points, amount, math):
        return points


GROUP_MODES = ("top_down", "bottom_up")


@dataclass(frozen=True)
class GroupOp(EditOp):
    """Base of operators on a translation or rotation symmetry group (its virtual parent).

    ``mode`` is ``top_down`` (the layout follows the virtual parent's box, so editing the
    parent changes spacing or count) or ``bottom_up`` (start, step and count are explicit;
    the parent's box follows the instances). See docs/dsl.md for the exact layouts.
    """

    acts_on: ClassVar[str] = "group"
    mode: str = "bottom_up"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.mode not in GROUP_MODES:
            raise ProgramFormatError(f"{self.name} on {self.operand!r}: mode must be one of {GROUP_MODES}, "
                                     f"got {self.mode!r}")

    def transform(self, points, amount, math):
        return points


@dataclass(frozen=True)
class ChangeCount(GroupOp):
    """The group's instance count becomes ``count0 + round(amount)`` (at least 1)."""

    name: ClassVar[str] = "change_count"


@dataclass(frozen=True)
class ChangeDelta(GroupOp):
    """The group's step (spacing, or angle for rotation groups) becomes ``step0 * (1 + amount)``."""

    name: ClassVar[str] = "change_delta"


BUILTIN_OPS: tuple[type[EditOp], ...] = (
    Translate, Rotate, Scale1D, Scale2D, Scale3D, Shear, KeepFixed, ChangeCount, ChangeDelta,
)


def op_from_dict(data: Mapping[str, Any], registry: Mapping[str, type[EditOp]], where: str = "") -> EditOp:
    """Build an op from its JSON form, naming the field at fault on error."""
    prefix = f"{where}: " if where else ""
    if not isinstance(data, Mapping):
        raise ProgramFormatError(f"{prefix}an op must be an object, got {type(data).__name__}")
    name = data.get("op")
    if name not in registry:
        raise ProgramFormatError(f"{prefix}unknown op {name!r} (known: {', '.join(sorted(registry))})")
    cls = registry[name]
    allowed = {f.name for f in dataclasses.fields(cls)}
    kwargs = {key: value for key, value in data.items() if key != "op"}
    unknown = sorted(set(kwargs) - allowed)
    if unknown:
        raise ProgramFormatError(f"{prefix}{name} has no field(s) {', '.join(unknown)}")
    if "operand" not in kwargs:
        raise ProgramFormatError(f"{prefix}{name} needs an 'operand'")
    for key in ("operand", "amount", "mode"):
        if key in kwargs and not isinstance(kwargs[key], str):
            raise ProgramFormatError(f"{prefix}{name}.{key} must be a string, got {kwargs[key]!r}")
    if kwargs.get("feature") is not None and not isinstance(kwargs["feature"], str):
        raise ProgramFormatError(f"{prefix}{name}.feature must be a string")
    try:
        return cls(**kwargs)
    except ProgramFormatError as exc:
        raise ProgramFormatError(f"{prefix}{exc}") from None
    except (TypeError, ValueError) as exc:
        raise ProgramFormatError(f"{prefix}{name}: {exc}") from None


def op_to_dict(op: EditOp) -> dict[str, Any]:
    """The JSON form of an op: name, operand, feature (if any), amount, then its params."""
    data: dict[str, Any] = {"op": op.name, "operand": op.operand}
    if op.feature is not None:
        data["feature"] = op.feature
    data["amount"] = op.amount
    for key, value in op.params().items():
        data[key] = list(value) if isinstance(value, tuple) else value
    return data
