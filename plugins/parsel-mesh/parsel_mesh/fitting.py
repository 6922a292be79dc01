"""Fitting a part's hexahedron: an oriented bounding box in the core's canonical corner order.

The box's axes are named by the world axis each is most aligned with (u ~ x, v ~ y,
w ~ z) and point along the positive world axis. That makes the fit *equivariant*: a
translated copy of a part gets the translated box with the same corner order, and a
mirror image (about a world plane) gets the mirrored box with corners that differ only
by the flip of one local axis, which is what symmetry detection relies on.

Minimum-volume boxes are unstable for near-symmetric parts (a round leg has a family of
equally good boxes rolled about its axis), so the most aligned of several candidates
wins among those whose volume is within a tolerance of the fitted minimum: the
world-axis box, boxes that keep one fitted axis and take their roll from the world
axes, and the fitted box itself. Every candidate is tight in its own frame, so the part
always lies inside its box. The assigned frame is always right-handed (a rotation), so
hexahedra have positive volume.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from parsel_core.hexahedron import CORNER_BITS, Hexahedron

AABB_TOLERANCE = 0.01
"""A more aligned box is preferred when its volume is within this fraction of the fitted one's."""

MIN_THICKNESS = 1e-3
"""Flat parts get this fraction of their largest extent as thickness, so cages stay invertible."""

COLLINEAR_RATIO = 1e-9
"""Points whose second principal spread is below this fraction of the first are a line."""


@dataclass(frozen=True)
class BoxFrame:
    """A box as orthonormal axes (rows u, v, w) and the points' bounds along them."""

    axes: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    @property
    def extents(self) -> np.ndarray:
        return self.hi - self.lo

    @property
    def volume(self) -> float:
        return float(np.prod(self.extents))


def assign_axes(axes: np.ndarray) -> np.ndarray:
    """Reorder and flip orthonormal box axes so row j is the axis closest to world axis j, pointing along it.

    The assignment maximises the summed ``|cos|`` over the 6 permutations (ties go to
    the first in lexicographic order); since ``|cos|`` is unchanged by reflections in
    world planes, a part and its mirror image get the same assignment.
    """
    axes = np.asarray(axes, dtype=float)
    cosines = np.abs(axes)
    best = max(itertools.permutations(range(3)),
               key=lambda perm: sum(cosines[perm[j], j] for j in range(3)))
    rows = []
    for j, i in enumerate(best):
        row = axes[i]
        rows.append(-row if row[j] < 0 else row)
    return np.array(rows)


def alignment(axes: np.ndarray) -> float:
    """How well assigned axes follow the world axes: the sum of ``|cos|``, 3 for world axes.

    Unchanged by reflections in world planes, so mirror images choose alike.
    """
    return float(np.abs(np.diagonal(axes)).sum())


def _frame(points: np.ndarray, axes: np.ndarray, min_thickness: float) -> BoxFrame:
    """The tight box of ``points`` along ``axes``, thickened where it is flat."""
    local = points @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    extents = hi - lo
    floor = min_thickness * float(extents.max())
    thin = extents < floor
    if np.any(thin):
        mid = (lo + hi) / 2
        lo = np.where(thin, mid - floor / 2, lo)
        hi = np.where(thin, mid + floor / 2, hi)
    return BoxFrame(axes, lo, hi)


def _rolled(axis: np.ndarray) -> np.ndarray:
    """A frame keeping ``axis`` whose roll comes from the world: the world axis most
    perpendicular to ``axis``, projected onto the plane normal to it."""
    world = np.eye(3)[int(np.argmin(np.abs(axis)))]
    second = world - (world @ axis) * axis
    second /= np.linalg.norm(second)
    return np.array([axis, second, np.cross(axis, second)])


def _fitted_axes(points: np.ndarray, principal: np.ndarray, flat: bool) -> np.ndarray:
    """Axes (rows) of a minimum-volume box from trimesh, or the principal axes if it fails."""
    import trimesh

    centred = points - points.mean(axis=0)
    try:
        if flat:
            plane = principal[:2]
            transform, _ = trimesh.bounds.oriented_bounds_2D(centred @ plane.T)
            in_plane = transform[:2, :2] @ plane
            axes = np.array([in_plane[0], in_plane[1], principal[2]])
        else:
            transform, _ = trimesh.bounds.oriented_bounds(centred)
            axes = np.asarray(transform[:3, :3], dtype=float)
    except Exception:  # qhull refuses some inputs; the principal frame is always defined
        return principal
    u, _, vt = np.linalg.svd(axes)
    return u @ vt  # re-orthonormalise what the fitter returned


def fit_box(vertices, *, aabb_tolerance: float = AABB_TOLERANCE, min_thickness: float = MIN_THICKNESS) -> BoxFrame:
    """The box frame :func:`hexahedron_of` uses; raises ``ValueError`` on degenerate input."""
    points = np.asarray(vertices, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"expected (n, 3) vertices, got shape {points.shape}")
    if len(points) == 0:
        raise ValueError("it has no vertices")
    if not np.all(np.isfinite(points)):
        raise ValueError("it has non-finite (NaN or infinite) vertex coordinates")
    centred = np.concatenate([points - points.mean(axis=0), np.zeros((max(0, 3 - len(points)), 3))])
    _, spread, principal = np.linalg.svd(centred, full_matrices=False)  # (3,) spreads, (3, 3) axes
    if spread[0] == 0.0:
        raise ValueError("all its vertices are the same point")
    if spread[1] <= COLLINEAR_RATIO * spread[0]:
        raise ValueError("its vertices are collinear (a zero-volume box)")
    flat = spread[2] <= COLLINEAR_RATIO * spread[0]

    fitted = _frame(points, assign_axes(_fitted_axes(points, principal, flat)), min_thickness)
    candidates = [_frame(points, np.eye(3), min_thickness)]
    candidates += [_frame(points, assign_axes(_rolled(axis)), min_thickness) for axis in fitted.axes]
    candidates.append(fitted)
    limit = (1.0 + aabb_tolerance) * fitted.volume
    accepted = [frame for frame in candidates if frame.volume <= limit]
    best = max(alignment(frame.axes) for frame in accepted)
    return next(frame for frame in accepted if alignment(frame.axes) >= best - 1e-12)


def hexahedron_of(vertices, *, aabb_tolerance: float = AABB_TOLERANCE,
                  min_thickness: float = MIN_THICKNESS) -> Hexahedron:
    """The oriented bounding box of ``vertices`` (n, 3) as a canonical :class:`Hexahedron`.

    Corner ``k`` is at cube point ``(u, v, w)`` = the bits of ``k``, with u, v, w the box
    axes assigned to x, y, z and pointing along them (see the module docstring). Flat
    parts are allowed (thickened by ``min_thickness`` of their size, centred on their
    plane); collinear, empty or non-finite input raises ``ValueError`` saying why.
    """
    frame = fit_box(vertices, aabb_tolerance=aabb_tolerance, min_thickness=min_thickness)
    local = np.where(CORNER_BITS == 1, frame.hi, frame.lo)
    return Hexahedron(local @ frame.axes)
