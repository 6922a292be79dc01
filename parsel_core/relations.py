"""Inter-part relations and the constraints they impose (reference section 2).

Each relation turns the parts' corners into a residual array that is zero exactly when
the relation holds. Residuals are written once for three kinds of corner values: rest
corners (floats), corners sampled at many parameter values (float arrays with leading
sample axes) and symbolic corners (numpy object arrays of CAS expressions), so the same
code checks a program numerically over [0, tau] and gives edit propagation the
equations it solves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

Corners = Mapping[str, np.ndarray]


def _vec(v) -> np.ndarray:
    return np.asarray(v, dtype=float)


def rotation_matrix(axis, angle: float) -> np.ndarray:
    n = _vec(axis) / np.linalg.norm(axis)
    k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * np.outer(n, n)


def _concatenate(parts: list[np.ndarray]) -> np.ndarray:
    """Residual blocks joined along the last axis, their sample axes broadcast together
    (members moved by a batch of candidates next to members that stay)."""
    batch = np.broadcast_shapes(*(p.shape[:-1] for p in parts))
    return np.concatenate([np.broadcast_to(p, batch + p.shape[-1:]) for p in parts], axis=-1)


def _constant(values, dtype=float) -> np.ndarray:
    """``values`` as a read-only array: a relation's fixed vectors and index maps, made once
    (constraints are evaluated many thousand times while edits are searched)."""
    out = np.array(values, dtype=dtype)
    out.flags.writeable = False
    return out


def _member_permutations(correspondence: tuple[tuple[int, ...], ...], members: int) -> tuple[np.ndarray, ...]:
    """Each member's corner permutation of a group relation as an index array (the
    identity when the relation records none)."""
    return tuple(_constant(correspondence[j] if correspondence else range(8), np.intp) for j in range(members))


def _flat(residual: np.ndarray) -> np.ndarray:
    """Residual components along the last axis, sample axes (if any) kept in front."""
    return residual.reshape(residual.shape[:-2] + (-1,))


@dataclass(frozen=True)
class Relation:
    """A relation between parts; ``members`` are part ids."""

    kind: ClassVar[str] = ""
    #: ``symmetry`` relations are restored first and may be declared breakable.
    family: ClassVar[str] = ""

    id: str
    members: tuple[str, ...]
    #: The constraint's value on the rest shape (flattened), subtracted by :meth:`residual`
    #: so every relation holds exactly at rest; set by :meth:`anchored`.
    rest_offset: tuple[float, ...] = field(default=(), kw_only=True, repr=False, compare=False)

    def constraint(self, corners: Corners) -> np.ndarray:
        """The relation's raw constraint values (..., k), zero for an exact relation."""
        raise NotImplementedError

    def residual(self, corners: Corners) -> np.ndarray:
        """Drift of the constraint from its rest value (..., k): all zero when the relation holds.

        Detection accepts relations within a tolerance of the shape's size, so a detected
        mirror pair may be a little asymmetric at rest; measuring drift from the rest value
        makes the identity program keep every relation exactly (docs/relations.md).
        """
        raw = self.constraint(corners)
        if not self.rest_offset:
            return raw
        return raw - self._rest_offset

    @cached_property
    def _rest_offset(self) -> np.ndarray:
        return _constant(self.rest_offset)

    def anchored(self, rest: Corners) -> Relation:
        """This relation with its rest offset measured on the rest corners ``rest``."""
        offset = np.asarray(self.constraint(rest), dtype=float).reshape(-1)
        offset = np.where(np.abs(offset) < 1e-12, 0.0, offset) + 0.0
        if not np.any(offset):
            return dataclasses.replace(self, rest_offset=())
        return dataclasses.replace(self, rest_offset=tuple(float(v) for v in offset))

    @cached_property
    def rest_error(self) -> float:
        """``||C||_inf`` on the rest shape: how far from exact the relation was detected."""
        return float(np.abs(np.asarray(self.rest_offset)).max()) if self.rest_offset else 0.0

    def allowance(self, tolerance: float) -> float:
        """The drift this relation may take and still hold: the check's ``tolerance``, or its
        own rest error when detection accepted it less exact than that (a mirror pair that
        was 0.3% asymmetric may not become more than 0.3% more so)."""
        return max(tolerance, self.rest_error)

    def error(self, corners: Corners) -> np.ndarray:
        """``||C||_inf`` per sample (a float for unbatched corners)."""
        return np.abs(self.residual(corners)).max(axis=-1)

    def holds(self, corners: Corners, tol: float) -> bool:
        """Whether ``||C||_inf < tol`` at every sample given."""
        return bool(np.all(self.error(corners) < tol))

    def params(self) -> dict[str, Any]:
        return {}

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {"id": self.id, "kind": self.kind, "members": list(self.members)}
        for key, value in self.params().items():
            data[key] = np.asarray(value).tolist() if isinstance(value, (tuple, np.ndarray)) else value
        return data


@dataclass(frozen=True)
class ReflectionSymmetry(Relation):
    """``H_b[perm] = H_a - 2((H_a - o).n) n``: b is a's mirror image about a plane of normal n.

    The plane's offset is free (it passes through ``origin`` at rest and may move along
    ``n`` with the pair): mirrored parts stay mirrored when the shape around them moves.

    ``correspondence[k]`` is the corner of b that mirrors corner k of a (reflection
    reverses handedness, so it is a permutation, found once at rest).
    """

    kind: ClassVar[str] = "reflection"
    family: ClassVar[str] = "symmetry"
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (1.0, 0.0, 0.0)
    correspondence: tuple[int, ...] = tuple(range(8))

    @cached_property
    def _plane(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Normal, origin and corner permutation as arrays."""
        return _constant(self.normal), _constant(self.origin), _constant(self.correspondence, np.intp)

    def reflect(self, points: np.ndarray) -> np.ndarray:
        n, o, _ = self._plane
        d = (points - o) @ n if points.dtype != object else np.dot(points - o, n)
        return points - d[..., None] * (2 * n)

    def constraint(self, corners):
        # The plane keeps its normal but may move along it: the pair stays mirrored when the
        # whole shape moves, or when a seat widened about an off-centre point carries both
        # legs outwards by different amounts. The offset is the mean of the mirrored corners'
        # gaps along n, so the constraint stays linear in the corners.
        a, b = (corners[m] for m in self.members)
        n, _, perm = self._plane
        gap = b[..., perm, :] - self.reflect(a)
        along = gap @ n if gap.dtype != object else np.dot(gap, n)
        shift = along.sum(axis=-1, keepdims=True) / 8.0
        return _flat(gap - shift[..., None] * n)

    def params(self):
        return {"origin": self.origin, "normal": self.normal, "correspondence": self.correspondence}


@dataclass(frozen=True)
class TranslationSymmetry(Relation):
    """``H_j = H_0 + j d`` for members in order, with d the common step.

    The step is read from the first two members, so evenly re-spacing the group keeps
    the relation; ``step`` records its rest value. ``correspondence[j]`` maps the corners
    of member 0 to member j.
    """

    kind: ClassVar[str] = "translation"
    family: ClassVar[str] = "symmetry"
    step: tuple[float, float, float] = (0.0, 0.0, 0.0)
    correspondence: tuple[tuple[int, ...], ...] = ()

    @cached_property
    def _perms(self) -> tuple[np.ndarray, ...]:
        return _member_permutations(self.correspondence, len(self.members))

    def _member(self, corners, j):
        return corners[self.members[j]][..., self._perms[j], :]

    def constraint(self, corners):
        h0 = self._member(corners, 0)
        step = (self._member(corners, 1) - h0).mean(axis=-2, keepdims=True) if len(self.members) > 1 else 0
        parts = [_flat(self._member(corners, j) - h0 - step * j) for j in range(1, len(self.members))]
        return _concatenate(parts) if parts else _flat(h0 - h0)

    def params(self):
        return {"step": self.step, "correspondence": self.correspondence}


@dataclass(frozen=True)
class RotationSymmetry(Relation):
    """``H_j = o + R^j (H_0 - o)``, R the rotation by ``angle`` about ``axis`` through ``center``."""

    kind: ClassVar[str] = "rotation"
    family: ClassVar[str] = "symmetry"
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    angle: float = 0.0
    correspondence: tuple[tuple[int, ...], ...] = ()

    @property
    def closed(self) -> bool:
        """Whether the instances go all the way round (count x angle = 2 pi)."""
        return abs(len(self.members) * abs(self.angle) - 2 * np.pi) < 1e-3

    @cached_property
    def _perms(self) -> tuple[np.ndarray, ...]:
        return _member_permutations(self.correspondence, len(self.members))

    @cached_property
    def _turns(self) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """The centre and each instance's rotation ``R^j`` (j >= 1), made once."""
        return _constant(self.center), tuple(_constant(rotation_matrix(self.axis, j * self.angle))
                                            for j in range(1, len(self.members)))

    def constraint(self, corners):
        o, turns = self._turns
        h0 = corners[self.members[0]]
        parts = []
        for j, r in enumerate(turns, start=1):
            hj = corners[self.members[j]][..., self._perms[j], :]
            expected = o + (h0 - o) @ r.T if h0.dtype != object else o + np.dot(h0 - o, r.T)
            parts.append(_flat(hj - expected))
        return _concatenate(parts)

    def params(self):
        return {"center": self.center, "axis": self.axis, "angle": self.angle,
                "correspondence": self.correspondence}


@dataclass(frozen=True)
class Attachment(Relation):
    """``M_a H_a = M_b H_b`` for 1 (point), 2 (line), 4 (face) or 8 (volume) point pairs.

    ``weights_a`` (k, 8) are the cage coordinates of the contact points in part a,
    ``weights_b`` the same points' cage coordinates in part b.
    """

    kind: ClassVar[str] = "attachment"
    family: ClassVar[str] = "attachment"
    KINDS: ClassVar[dict[int, str]] = {1: "point", 2: "line", 4: "face", 8: "volume"}
    weights_a: tuple[tuple[float, ...], ...] = field(default=())
    weights_b: tuple[tuple[float, ...], ...] = field(default=())

    @property
    def contact(self) -> str:
        """``point``, ``line``, ``face`` or ``volume``, by the number of point pairs."""
        return self.KINDS.get(len(self.weights_a), f"{len(self.weights_a)}-point")

    @cached_property
    def _weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``weights_a`` and ``weights_b`` as arrays (read-only), made once."""
        return _constant(self.weights_a), _constant(self.weights_b)

    def constraint(self, corners):
        a, b = (corners[m] for m in self.members)
        wa, wb = self._weights
        pa = wa @ a if a.dtype != object else np.dot(wa, a)
        pb = wb @ b if b.dtype != object else np.dot(wb, b)
        return _flat(pa - pb)

    def points(self, corners: Corners) -> np.ndarray:
        """The contact points on part a."""
        return np.asarray(self.weights_a) @ corners[self.members[0]]

    def params(self):
        return {"contact": self.contact, "weights_a": self.weights_a, "weights_b": self.weights_b}


@dataclass(frozen=True)
class GroundContact(Relation):
    """``(M H) . up = height``: the part's contact points stay on the floor plane."""

    kind: ClassVar[str] = "ground"
    family: ClassVar[str] = "attachment"
    weights: tuple[tuple[float, ...], ...] = field(default=())
    height: float = 0.0
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def constraint(self, corners):
        h = corners[self.members[0]]
        w, up = self._arrays
        points = w @ h if h.dtype != object else np.dot(w, h)
        return (points @ up if points.dtype != object else np.dot(points, up)) - self.height

    @cached_property
    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The contact weights and the up direction as arrays."""
        return _constant(self.weights), _constant(self.up)

    def params(self):
        return {"weights": self.weights, "height": self.height, "up": self.up}


RELATION_TYPES: dict[str, type[Relation]] = {
    cls.kind: cls for cls in (ReflectionSymmetry, TranslationSymmetry, RotationSymmetry, Attachment, GroundContact)
}

_TUPLE_FIELDS = {"origin", "normal", "step", "center", "axis", "up"}


def relation_from_dict(data: Mapping[str, Any], where: str = "") -> Relation:
    """A relation from its JSON form (the inverse of ``Relation.to_dict``)."""
    prefix = f"{where}: " if where else ""
    kind = data.get("kind")
    if kind not in RELATION_TYPES:
        raise ValueError(f"{prefix}unknown relation kind {kind!r} (known: {', '.join(RELATION_TYPES)})")
    kwargs: dict[str, Any] = {"id": str(data["id"]), "members": tuple(str(m) for m in data["members"])}
    for key, value in data.items():
        if key in ("id", "kind", "members", "contact"):
            continue
        if key in _TUPLE_FIELDS:
            kwargs[key] = tuple(float(v) for v in value)
        elif key == "correspondence":
            kwargs[key] = tuple(int(v) for v in value) if kind == "reflection" else tuple(
                tuple(int(v) for v in row) for row in value)
        elif key in ("weights_a", "weights_b", "weights"):
            kwargs[key] = tuple(tuple(float(v) for v in row) for row in value)
        elif key in ("angle", "height"):
            kwargs[key] = float(value)
        else:
            raise ValueError(f"{prefix}relation {kwargs['id']!r} has unknown field {key!r}")
    return RELATION_TYPES[kind](**kwargs)
