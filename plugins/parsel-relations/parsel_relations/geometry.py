"""Vectorised geometry on the parts' hexahedra: oriented boxes, corner matching, box clipping.

Detection works on each part's *box*: the hexahedron's nearest orthonormal frame and the
tight extents of its corners in that frame. For the oriented bounding boxes that loaders
produce the box is the hexahedron itself; for a tapered hexahedron it is the box that
encloses it, which keeps contact tests conservative.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsel_core.hexahedron import CORNER_BITS
from parsel_relations.assignment import linear_sum_assignment

#: The 12 edges of a box as corner-index pairs (corners in the canonical bit order).
BOX_EDGES = np.array([(a, b) for a in range(8) for b in range(8)
                      if a < b and bin(a ^ b).count("1") == 1])


@dataclass(frozen=True)
class Boxes:
    """Oriented boxes of ``n`` parts as arrays, so pair tests run as one numpy call.

    ``axes[i]`` holds the unit axes of box ``i`` as rows (orthonormal); ``halves[i]`` its
    half extents along them; ``lo`` / ``hi`` its world axis-aligned bounds.
    """

    centers: np.ndarray
    axes: np.ndarray
    halves: np.ndarray

    @property
    def corners(self) -> np.ndarray:
        """(n, 8, 3) box corners in the canonical order."""
        offsets = (2.0 * CORNER_BITS - 1.0)[None] * self.halves[:, None, :]
        return self.centers[:, None, :] + np.einsum("nkj,nji->nki", offsets, self.axes)

    @property
    def volumes(self) -> np.ndarray:
        return 8.0 * np.prod(self.halves, axis=1)

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounds (n, 3) of each box."""
        reach = np.einsum("nj,nji->ni", self.halves, np.abs(self.axes))
        return self.centers - reach, self.centers + reach


def axis_vectors(corners: np.ndarray) -> np.ndarray:
    """Mean edge vectors along u, v, w (rows) of hexahedra (n, 8, 3) -> (n, 3, 3)."""
    c = corners
    return np.stack([
        (c[:, 4:8] - c[:, 0:4]).mean(axis=1),
        (c[:, [2, 3, 6, 7]] - c[:, [0, 1, 4, 5]]).mean(axis=1),
        (c[:, 1::2] - c[:, 0::2]).mean(axis=1),
    ], axis=1)


def nearest_frames(vectors: np.ndarray) -> np.ndarray:
    """The orthogonal matrix nearest to each (3, 3) matrix (polar decomposition).

    Mirrored parts have left-handed corner frames; their nearest orthogonal frame keeps
    the reflection (det -1) so it stays aligned with the box's edges.
    """
    u, _, vt = np.linalg.svd(vectors)
    return u @ vt


def boxes_of(corners: np.ndarray) -> Boxes:
    """The oriented box of each hexahedron (n, 8, 3): its nearest frame, tight extents."""
    corners = np.asarray(corners, dtype=float).reshape(-1, 8, 3)
    axes = nearest_frames(axis_vectors(corners))
    local = np.einsum("nkj,nij->nki", corners, axes)
    lo, hi = local.min(axis=1), local.max(axis=1)
    centers = np.einsum("nj,nji->ni", (lo + hi) / 2.0, axes)
    return Boxes(centers, axes, (hi - lo) / 2.0)


def match_corners(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each pair of corner sets (P, 8, 3): the target corner matching each source corner.

    Returns ``perm`` (P, 8) with ``target[p, perm[p, k]]`` the match of ``source[p, k]``,
    and the largest matched distance (P,). Nearest corners are used when they form a
    permutation (always, for true copies); otherwise an optimal assignment.
    """
    source = np.asarray(source, dtype=float).reshape(-1, 8, 3)
    target = np.asarray(target, dtype=float).reshape(-1, 8, 3)
    distances = np.linalg.norm(source[:, :, None, :] - target[:, None, :, :], axis=3)
    perm = distances.argmin(axis=2)
    sorted_perm = np.sort(perm, axis=1)
    bad = np.flatnonzero(np.any(sorted_perm != np.arange(8), axis=1))
    for p in bad:
        rows, cols = linear_sum_assignment(distances[p])
        perm[p, rows] = cols
    error = np.take_along_axis(distances, perm[:, :, None], axis=2)[:, :, 0].max(axis=1)
    return perm, error


def clip_edges(boxes: Boxes, src: np.ndarray, dst: np.ndarray, grow: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip the 12 edges of boxes ``src`` (P,) against boxes ``dst`` (P,), both grown by ``grow``.

    Returns the clipped segments' end points (P, 24, 3) and which are valid (P, 24).
    Liang-Barsky clipping against the three slabs of the destination box.
    """
    grown = Boxes(boxes.centers, boxes.axes, boxes.halves + grow)
    corners = grown.corners[src]  # (P, 8, 3)
    p0 = corners[:, BOX_EDGES[:, 0]]
    p1 = corners[:, BOX_EDGES[:, 1]]
    axes = grown.axes[dst]
    centre = grown.centers[dst][:, None, :]
    l0 = np.einsum("pej,pij->pei", p0 - centre, axes)
    l1 = np.einsum("pej,pij->pei", p1 - centre, axes)
    dl = l1 - l0
    half = grown.halves[dst][:, None, :]
    flat = np.abs(dl) < 1e-15
    safe = np.where(flat, 1.0, dl)
    t1 = (-half - l0) / safe
    t2 = (half - l0) / safe
    inside_flat = np.abs(l0) <= half
    t_lo = np.where(flat, np.where(inside_flat, -np.inf, np.inf), np.minimum(t1, t2))
    t_hi = np.where(flat, np.where(inside_flat, np.inf, -np.inf), np.maximum(t1, t2))
    t_min = np.maximum(t_lo.max(axis=2), 0.0)
    t_max = np.minimum(t_hi.min(axis=2), 1.0)
    valid = t_min <= t_max
    t_min, t_max = np.where(valid, t_min, 0.0), np.where(valid, t_max, 0.0)
    d = p1 - p0
    points = np.concatenate([p0 + t_min[..., None] * d, p0 + t_max[..., None] * d], axis=1)
    return points, np.concatenate([valid, valid], axis=1)


def intersection_vertices(boxes: Boxes, a: np.ndarray, b: np.ndarray, grow: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices of the intersection polytope of boxes ``a`` and ``b`` (P pairs), each grown.

    Every vertex of the intersection of two convex polytopes lies on an edge of one of
    them, so clipping both boxes' edges against the other gives all of them (with
    repeats). Returns points (P, 48, 3) and a validity mask (P, 48); a pair whose mask
    is all false does not intersect.
    """
    pa, va = clip_edges(boxes, a, b, grow)
    pb, vb = clip_edges(boxes, b, a, grow)
    return np.concatenate([pa, pb], axis=1), np.concatenate([va, vb], axis=1)


def separations(boxes: Boxes, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The largest gap between boxes ``a`` and ``b`` (P pairs) along a separating axis.

    Separating-axis theorem for two oriented boxes: they are disjoint iff their
    projections are disjoint on one of 15 axes (the 3 + 3 face normals and the 9 cross
    products of edge directions). The result is positive iff the boxes are disjoint (a
    lower bound on their distance, exact when a face normal separates them) and <= 0
    when they touch or overlap (minus the depth along the shallowest of the 15 axes).
    """
    a, b = np.atleast_1d(a), np.atleast_1d(b)
    axes_a, axes_b = boxes.axes[a], boxes.axes[b]  # (P, 3, 3), rows = unit axes
    crosses = np.cross(axes_a[:, :, None, :], axes_b[:, None, :, :]).reshape(-1, 9, 3)
    normals = np.concatenate([axes_a, axes_b, crosses], axis=1)  # (P, 15, 3)
    lengths = np.linalg.norm(normals, axis=2)
    usable = lengths > 1e-9  # parallel edges give no cross-product axis
    normals = normals / np.where(usable, lengths, 1.0)[..., None]
    reach_a = np.einsum("pk,pnk->pn", boxes.halves[a], np.abs(np.einsum("pnj,pkj->pnk", normals, axes_a)))
    reach_b = np.einsum("pk,pnk->pn", boxes.halves[b], np.abs(np.einsum("pnj,pkj->pnk", normals, axes_b)))
    offset = np.abs(np.einsum("pnj,pj->pn", normals, boxes.centers[b] - boxes.centers[a]))
    return np.where(usable, offset - reach_a - reach_b, -np.inf).max(axis=1)


def contains(boxes: Boxes, inner: int, outer: int, tol: float) -> bool:
    """Whether box ``inner`` lies inside box ``outer`` grown by ``tol``."""
    corners = boxes.corners[inner]
    local = (corners - boxes.centers[outer]) @ boxes.axes[outer].T
    return bool(np.all(np.abs(local) <= boxes.halves[outer] + tol))


def contains_point(boxes: Boxes, box: int, point: np.ndarray) -> bool:
    """Whether a point lies inside a box (not grown)."""
    local = boxes.axes[box] @ (point - boxes.centers[box])
    return bool(np.all(np.abs(local) <= boxes.halves[box] * (1.0 + 1e-9)))


def reflect_points(points: np.ndarray, origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Mirror points (..., 3) about the plane (origin, unit normal)."""
    d = (points - origin) @ normal
    return points - 2.0 * d[..., None] * normal


def symmetric_about(points: np.ndarray, origin: np.ndarray, normal: np.ndarray, tol: float) -> bool:
    """Whether a point set maps onto itself (each mirrored point near one of the set)."""
    mirrored = reflect_points(points, origin, normal)
    distances = np.linalg.norm(mirrored[:, None, :] - points[None, :, :], axis=2)
    return bool(distances.min(axis=1).max() <= tol)


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    n = np.asarray(axis, dtype=float)
    k = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * np.outer(n, n)


def clusters_1d(values: np.ndarray, tol: float) -> list[np.ndarray]:
    """Indices of ``values`` grouped so that sorted neighbours closer than ``tol`` share a group."""
    if len(values) == 0:
        return []
    order = np.argsort(values, kind="stable")
    breaks = np.flatnonzero(np.diff(values[order]) > tol) + 1
    return [np.sort(group) for group in np.split(order, breaks)]
