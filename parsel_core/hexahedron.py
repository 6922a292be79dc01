"""Hexahedra: the 8-corner proxies that parts are edited through (reference section 1).

Canonical corner order
----------------------
A hexahedron is the trilinear image of the unit cube. Corner ``k`` sits at the cube
point ``(u, v, w)`` given by the bits of ``k``::

    k = 4*u + 2*v + w          u, v, w in {0, 1}

    0: (0,0,0)  1: (0,0,1)  2: (0,1,0)  3: (0,1,1)
    4: (1,0,0)  5: (1,0,1)  6: (1,1,0)  7: (1,1,1)

The local axes are ``u`` (corner 0 -> 4), ``v`` (0 -> 2) and ``w`` (0 -> 1). Features are
named by the sides they lie on: face ``"u+"`` is the face ``u = 1``; edge ``"u+v-"`` is
the edge ``u = 1, v = 0``; corner ``"u+v-w+"`` is corner 5. Each of the 27 feature points
(centre, 6 face centres, 12 edge centres, 8 corners) is a cube point with coordinates in
``{0, 1/2, 1}``, so its cage coordinates (trilinear weights) are exact.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from parsel_core.cage import cage_weights

AXES = ("u", "v", "w")
CORNER_BITS = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)


def _side_name(axis: int, side: int) -> str:
    return f"{AXES[axis]}{'+' if side else '-'}"


def feature_corners(name: str) -> tuple[int, ...]:
    """Corner indices of a named feature: ``"u+"`` (face), ``"u+v-"`` (edge), ``"u+v-w+"``."""
    if len(name) % 2 or not 2 <= len(name) <= 6:
        raise ValueError(f"feature name {name!r} is not one of u±, u±v±, u±v±w± (e.g. 'u+', 'u+v-')")
    fixed: dict[int, int] = {}
    for i in range(0, len(name), 2):
        axis_char, sign = name[i], name[i + 1]
        if axis_char not in AXES or sign not in "+-":
            raise ValueError(f"feature name {name!r}: {name[i:i + 2]!r} is not an axis u/v/w with a sign")
        axis = AXES.index(axis_char)
        if axis in fixed:
            raise ValueError(f"feature name {name!r} names axis {axis_char!r} twice")
        fixed[axis] = 1 if sign == "+" else 0
    return tuple(k for k in range(8) if all(CORNER_BITS[k, a] == s for a, s in fixed.items()))


def feature_kind(name: str) -> str:
    """``"face"``, ``"edge"`` or ``"corner"`` for a feature name."""
    return {2: "face", 4: "edge", 6: "corner"}[len(name)]


def canonical_feature_name(name: str) -> str:
    """The feature name with its axes in u, v, w order (``"v-u+"`` -> ``"u+v-"``)."""
    parts = sorted((name[i:i + 2] for i in range(0, len(name), 2)), key=lambda s: AXES.index(s[0]))
    return "".join(parts)


FACE_NAMES = tuple(_side_name(a, s) for a in range(3) for s in (0, 1))
EDGE_NAMES = tuple(
    _side_name(a, sa) + _side_name(b, sb)
    for a, b in itertools.combinations(range(3), 2)
    for sa in (0, 1)
    for sb in (0, 1)
)
CORNER_NAMES = tuple(
    _side_name(0, (k >> 2) & 1) + _side_name(1, (k >> 1) & 1) + _side_name(2, k & 1) for k in range(8)
)


def _feature_point_table() -> tuple[tuple[str, ...], np.ndarray]:
    """Names and cube coordinates of the 27 feature points, centre first."""
    names = ["center"]
    coords = [(0.5, 0.5, 0.5)]
    for name in FACE_NAMES + EDGE_NAMES + CORNER_NAMES:
        point = [0.5, 0.5, 0.5]
        for i in range(0, len(name), 2):
            point[AXES.index(name[i])] = 1.0 if name[i + 1] == "+" else 0.0
        names.append(name)
        coords.append(tuple(point))
    return tuple(names), np.array(coords)


FEATURE_POINT_NAMES, FEATURE_POINT_UVW = _feature_point_table()
FEATURE_POINT_WEIGHTS = cage_weights(FEATURE_POINT_UVW)  # (27, 8), exact in {0, 1/8, 1/4, 1/2, 1}

#: The 6 faces as corner quads, counter-clockwise seen from outside when the frame
#: (u, v, w) is right-handed; each split in two triangles for meshes.
FACE_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))
FACE_TRIANGLES = np.array([(a, b, c) for a, b, c, _ in FACE_QUADS] + [(a, c, d) for a, _, c, d in FACE_QUADS])

# Corner permutation that mirrors the cube across the mid-plane of each local axis.
MIRROR_PERMUTATION = tuple(tuple(k ^ (4 >> axis) for k in range(8)) for axis in range(3))


def corner_jacobians(corners: np.ndarray) -> np.ndarray:
    """The cage map's Jacobian determinant at each corner of hexahedra (..., 8, 3) -> (..., 8).

    At corner k the derivatives along u, v, w are the three edges leaving it, each taken
    from its low to its high end. A right-handed box gives 8 positive values (its volume);
    a corner pushed past its neighbours, or a mirrored frame, turns some negative. The
    NaN corners of a removed group member give NaN, without a numpy warning.
    """
    corners = np.asarray(corners, dtype=float)
    out = []
    with np.errstate(invalid="ignore"):
        for k in range(8):
            edges = [corners[..., k | bit, :] - corners[..., k & ~bit, :] for bit in (4, 2, 1)]
            out.append(np.linalg.det(np.stack(edges, axis=-2)))
    return np.stack(out, axis=-1)


@dataclass(frozen=True)
class Hexahedron:
    """Eight corners in the canonical order; the cage every part is edited through."""

    corners: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        corners = np.asarray(self.corners, dtype=float)
        if corners.shape != (8, 3):
            raise ValueError(f"a hexahedron needs 8 x 3 corners, got shape {corners.shape}")
        if not np.all(np.isfinite(corners)):
            raise ValueError("hexahedron corners must be finite numbers")
        corners = corners.copy()
        corners.flags.writeable = False
        object.__setattr__(self, "corners", corners)

    @classmethod
    def from_box(cls, center, size, axes=None) -> Hexahedron:
        """A box with full side lengths ``size`` along the rows of ``axes`` (default: x, y, z)."""
        center = np.asarray(center, dtype=float)
        size = np.asarray(size, dtype=float)
        axes = np.eye(3) if axes is None else np.asarray(axes, dtype=float)
        offsets = (CORNER_BITS - 0.5) * size
        return cls(center + offsets @ axes)

    @classmethod
    def canonical_box(cls, center, size, axes) -> Hexahedron:
        """A box with its axes (rows) matched to world x, y, z and pointing their positive way.

        Loaders use this so that every box of a shape follows one convention: u is the
        box axis closest to world x (then v to y, w to z, chosen jointly), each flipped to
        point along its world axis. A part and its translated copy then get identical
        corner orders, and a mirror image gets the mirrored order (corner k <-> k ^ 4 for
        a mirror across x), which is what symmetry detection relies on.
        """
        axes = np.asarray(axes, dtype=float)
        size = np.asarray(size, dtype=float)
        alignment = np.abs(axes)  # alignment[i, j]: |cos| between box axis i and world axis j
        best = max(itertools.permutations(range(3)), key=lambda p: sum(alignment[p[j], j] for j in range(3)))
        ordered = np.array([axes[best[j]] * (1.0 if axes[best[j], j] >= 0 else -1.0) for j in range(3)])
        return cls.from_box(center, size[list(best)], ordered)

    @classmethod
    def from_bounds(cls, lo, hi) -> Hexahedron:
        """An axis-aligned box from its minimum and maximum points."""
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        return cls(lo + CORNER_BITS * (hi - lo))

    @property
    def center(self) -> np.ndarray:
        return self.corners.mean(axis=0)

    @cached_property
    def feature_points(self) -> np.ndarray:
        """The 27 feature points, in the order of ``FEATURE_POINT_NAMES``."""
        return FEATURE_POINT_WEIGHTS @ self.corners

    def feature_point(self, name: str) -> np.ndarray:
        return self.feature_points[FEATURE_POINT_NAMES.index(name)]

    @cached_property
    def axis_vectors(self) -> np.ndarray:
        """Mean edge vector along u, v and w (rows); for a box, its side vectors."""
        c = self.corners
        return np.array([
            (c[4:8] - c[0:4]).mean(axis=0),
            (c[[2, 3, 6, 7]] - c[[0, 1, 4, 5]]).mean(axis=0),
            (c[1::2] - c[0::2]).mean(axis=0),
        ])

    @property
    def local_axes(self) -> np.ndarray:
        """Unit local axes u, v, w (rows)."""
        vectors = self.axis_vectors
        return vectors / np.linalg.norm(vectors, axis=1, keepdims=True)

    @property
    def extents(self) -> np.ndarray:
        """Mean side lengths along u, v, w."""
        return np.linalg.norm(self.axis_vectors, axis=1)

    def face(self, name: str) -> np.ndarray:
        """The 4 corners of a face, e.g. ``face("v+")``."""
        return self.corners[list(feature_corners(name))]

    def edge(self, name: str) -> np.ndarray:
        return self.corners[list(feature_corners(name))]

    def face_normal(self, name: str) -> np.ndarray:
        """Outward unit normal of a face, from its mean axis direction."""
        axis = AXES.index(name[0])
        sign = 1.0 if name[1] == "+" else -1.0
        return sign * self.local_axes[axis]

    def point_at(self, uvw) -> np.ndarray:
        """The point at cube coordinates ``uvw`` (trilinear interpolation of the corners)."""
        return cage_weights(np.atleast_2d(uvw)) @ self.corners

    @property
    def volume(self) -> float:
        """Signed volume by the triple product of the mean axes; exact for parallelepipeds."""
        return float(np.linalg.det(self.axis_vectors))

    def triangles(self) -> np.ndarray:
        """(12, 3) corner indices of the faces, wound outward whatever the frame's handedness."""
        return FACE_TRIANGLES if self.volume >= 0 else FACE_TRIANGLES[:, ::-1].copy()

    def intrinsic_symmetry_planes(self, tol: float = 1e-6) -> list[tuple[np.ndarray, np.ndarray]]:
        """Planes (origin, unit normal) through the centre, normal to a local axis, that map
        the hexahedron onto itself. A box has 3; a taper keeps fewer (supplement 3.3)."""
        planes = []
        scale = max(float(np.ptp(self.corners, axis=0).max()), 1e-12)
        for axis in range(3):
            perm = list(MIRROR_PERMUTATION[axis])
            low = [k for k in range(8) if not CORNER_BITS[k, axis]]
            # A mirror plane is normal to the mean vector from each corner to its partner.
            direction = (self.corners[perm] - self.corners)[low].sum(axis=0)
            norm = np.linalg.norm(direction)
            if norm < 1e-12:
                continue
            n = direction / norm
            o = self.center
            reflected = self.corners - 2.0 * ((self.corners - o) @ n)[:, None] * n
            if np.abs(reflected - self.corners[perm]).max() <= tol * scale:
                planes.append((o, n))
        return planes
