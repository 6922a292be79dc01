"""Best-fitting cuboids of hexahedra, in the frames a ShapeAssembly program can state.

An edit keeps most parts boxes, but tapers and shears turn some into general
hexahedra; a ShapeAssembly program can only hold cuboids, so each part is written as
the cuboid whose corners are closest to its corners (least squares over the 8 corners,
started from the polar decomposition of the mean edge vectors) and its deviation is
reported. The cuboid's frame is a right-handed signed permutation of the fitted axes,
chosen closest to a reference frame, so that boxes aligned with the program's block come
out exactly aligned and rotations stay as small as possible.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from parsel_core.hexahedron import CORNER_BITS

#: Rows that differ from a frame's rows by less than this are snapped to them (exact alignment).
SNAP = 1e-12

_SIGNED_PERMUTATIONS = tuple(
    np.array([[sign[i] if j == perm[i] else 0.0 for j in range(3)] for i in range(3)])
    for perm in itertools.permutations(range(3))
    for sign in itertools.product((1.0, -1.0), repeat=3)
)
_ROTATIONS = tuple(p for p in _SIGNED_PERMUTATIONS if np.linalg.det(p) > 0)


@dataclass(frozen=True)
class Box:
    """A cuboid: centre, unit right-handed axes (rows: length, height, width) and full dims."""

    center: np.ndarray
    axes: np.ndarray
    dims: np.ndarray

    def corners(self) -> np.ndarray:
        """(8, 3) corners in the core's canonical order (bits of k = u, v, w along the rows)."""
        return self.center + ((CORNER_BITS - 0.5) * self.dims) @ self.axes


def _edge_matrix(corners: np.ndarray) -> np.ndarray:
    """Rows: the mean edge vector along u, v, w of a hexahedron (corner k = 4u + 2v + w)."""
    rows = []
    for bit in (4, 2, 1):
        low = [k for k in range(8) if not k & bit]
        rows.append(np.mean([corners[k | bit] - corners[k] for k in low], axis=0))
    return np.array(rows)


def _rotation(rotvec: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(rotvec).as_matrix()


def fit_box(corners: np.ndarray) -> tuple[Box, float]:
    """The cuboid closest to a hexahedron's corners and the largest corner distance to it."""
    corners = np.asarray(corners, dtype=float)
    edges = _edge_matrix(corners)
    u, s, vt = np.linalg.svd(edges)
    axes = u @ vt  # the orthogonal matrix closest to the edge rows
    if np.linalg.det(axes) < 0:  # a folded hexahedron: keep a right-handed frame, flip the weakest axis
        u[:, -1] *= -1
        axes = u @ vt
    dims = np.abs(np.einsum("ij,ij->i", edges, axes))
    box = Box(corners.mean(axis=0), axes, dims)
    deviation = float(np.abs(box.corners() - corners).max())
    scale = float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0))) or 1.0
    if deviation <= 1e-12 * scale:
        return box, deviation
    from scipy.optimize import least_squares

    def residual(x: np.ndarray) -> np.ndarray:
        frame = _rotation(x[3:6]).T @ axes
        return (x[:3] + ((CORNER_BITS - 0.5) * x[6:]) @ frame - corners).ravel()

    start = np.concatenate([box.center, np.zeros(3), dims])
    solution = least_squares(residual, start, x_scale=scale)
    refined = Box(solution.x[:3], _rotation(solution.x[3:6]).T @ axes, np.abs(solution.x[6:]))
    refined_deviation = float(np.abs(refined.corners() - corners).max())
    if refined_deviation < deviation:
        return refined, refined_deviation
    return box, deviation


def in_frame(box: Box, frame: np.ndarray) -> Box:
    """The same cuboid with its axes relabelled (a right-handed signed permutation) to be
    closest to ``frame`` (rows); axes within ``SNAP`` of the frame's rows become them exactly."""
    best = max(_ROTATIONS, key=lambda p: float(np.trace((p @ box.axes) @ frame.T)))
    axes = best @ box.axes
    dims = np.abs(best) @ box.dims
    if np.abs(axes - frame).max() < SNAP:
        axes = frame.copy()
    return Box(box.center, axes, dims)


def same_frame(a: np.ndarray, b: np.ndarray, tol: float = SNAP) -> bool:
    """Whether two frames (rows) are the same up to relabelling the axes."""
    return any(np.abs(p @ a - b).max() < tol for p in _SIGNED_PERMUTATIONS)
