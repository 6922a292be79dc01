"""Cage coordinates: points held as trilinear weights over a hexahedron's 8 corners.

A point ``p`` inside hexahedron ``H`` (8 x 3) is stored as weights ``M`` (8,) with
``p = M @ H`` (paper section 5.2, ``M_a H_i``). The weights of cube point ``(u, v, w)``
are the trilinear basis functions; for a box cage they coincide with the harmonic
coordinates the paper uses, since trilinear functions are harmonic and interpolate
the cage's bilinear faces. When ``H`` moves, ``M @ H(x)`` moves with it, so every
constraint becomes an expression of the corners.
"""

from __future__ import annotations

import numpy as np


def cage_weights(uvw: np.ndarray) -> np.ndarray:
    """Trilinear weights (n, 8) of cube points ``uvw`` (n, 3), in canonical corner order."""
    uvw = np.asarray(uvw, dtype=float)
    u, v, w = uvw[..., 0:1], uvw[..., 1:2], uvw[..., 2:3]
    bits = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)
    fu = np.where(bits[:, 0] == 1, u, 1.0 - u)
    fv = np.where(bits[:, 1] == 1, v, 1.0 - v)
    fw = np.where(bits[:, 2] == 1, w, 1.0 - w)
    return fu * fv * fw


def _jacobian(corners: np.ndarray, uvw: np.ndarray) -> np.ndarray:
    """d point / d (u, v, w) at cube points ``uvw`` (..., n, 3) in cages (..., 8, 3); returns
    (..., n, 3, 3)."""
    u, v, w = (uvw[..., i:i + 1] for i in range(3))
    bits = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)
    sign = 2.0 * bits - 1.0
    fu = np.where(bits[:, 0] == 1, u, 1.0 - u)
    fv = np.where(bits[:, 1] == 1, v, 1.0 - v)
    fw = np.where(bits[:, 2] == 1, w, 1.0 - w)
    du = sign[:, 0] * fv * fw
    dv = sign[:, 1] * fu * fw
    dw = sign[:, 2] * fu * fv
    # columns: derivative along u, v, w
    return np.stack([du @ corners, dv @ corners, dw @ corners], axis=-1)


def inverse_trilinear(corners: np.ndarray, points: np.ndarray, iterations: int = 30) -> np.ndarray:
    """Cube coordinates (n, 3) of world points (n, 3) in the hexahedron ``corners``.

    Exact for parallelepipeds (one Newton step from the affine start); Newton iterations
    converge quadratically for the mildly non-affine cages that tapers produce. Points
    outside the cage get coordinates outside [0, 1], which is what extrapolating a
    deformation needs.
    """
    corners = np.asarray(corners, dtype=float)
    points = np.atleast_2d(np.asarray(points, dtype=float))
    origin = corners[0]
    frame = np.stack([corners[4] - origin, corners[2] - origin, corners[1] - origin], axis=1)
    uvw = np.linalg.solve(frame, (points - origin).T).T
    for _ in range(iterations):
        residual = cage_weights(uvw) @ corners - points
        if np.abs(residual).max() < 1e-13:
            break
        step = np.linalg.solve(_jacobian(corners, uvw), residual[..., None])[..., 0]
        uvw = uvw - step
    return uvw


def batched_cube_coordinates(corners: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:func:`inverse_trilinear` over a batch: cube coordinates (..., n, 3) of points (..., n, 3)
    in hexahedra (..., 8, 3); one affine solve per hexahedron, Newton only where it is not a
    parallelepiped (:func:`_batched_newton`, the same result bit for bit)."""
    corners = np.asarray(corners, dtype=float)
    points = np.asarray(points, dtype=float)
    origin = corners[..., 0, :]
    frame = np.stack([corners[..., 4, :] - origin, corners[..., 2, :] - origin, corners[..., 1, :] - origin],
                     axis=-1)                                                   # (..., 3, 3)
    uvw = np.linalg.solve(frame[..., None, :, :], (points - origin[..., None, :])[..., None])[..., 0]
    residual = np.abs(np.einsum("...nk,...kj->...nj", cage_weights(uvw), corners) - points).max(axis=(-1, -2))
    index = np.nonzero(residual > 1e-9)
    if index[0].size:
        uvw[index] = _batched_newton(corners[index], points[index])
    return uvw


def approximate_cube_coordinates(corners: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:func:`batched_cube_coordinates` to within rounding, for cages (m, 8, 3) and points
    (m, n, 3): for callers that compare what follows with a threshold and decide near-ties
    again exactly (:func:`parsel_core.report.batch_relation_errors`).

    A cage that is a parallelepiped at its points up to 1e-10 (the non-affine terms of the
    trilinear map bounded there; :func:`batched_cube_coordinates` takes no Newton step below
    1e-9) and not flattened is solved by its frame's explicit inverse (cofactors over the
    determinant), a few array products for the whole batch instead of a LAPACK solve per
    point; the others, tapered or near-degenerate, go to :func:`batched_cube_coordinates`.
    """
    corners = np.asarray(corners, dtype=float)
    points = np.asarray(points, dtype=float)
    c = np.ascontiguousarray(np.moveaxis(corners, 0, -1))                  # (8, 3, m): one row per coordinate
    offset = np.moveaxis(points, 0, -1) - c[0]                              # (n, 3, m)
    eu, ev, ew = c[4] - c[0], c[2] - c[0], c[1] - c[0]                      # the frame's edges
    # The inverse frame's rows are the cofactors ev x ew, ew x eu, eu x ev over the determinant.
    rows = [_cross(ev, ew), _cross(ew, eu), _cross(eu, ev)]
    det = eu[0] * rows[0][0] + eu[1] * rows[0][1] + eu[2] * rows[0][2]
    volume = np.sqrt((eu * eu).sum(0) * (ev * ev).sum(0) * (ew * ew).sum(0))
    with np.errstate(divide="ignore", invalid="ignore"):
        uvw = np.stack([(offset[:, 0] * r[0] + offset[:, 1] * r[1] + offset[:, 2] * r[2]) / det for r in rows])
    # p(u, v, w) = c0 + eu u + ev v + ew w + a uv + b uw + d vw + h uvw: the affine solve is
    # off by the last four terms, bounded at the points by their coefficients.
    a = np.abs(c[6] - c[4] - c[2] + c[0]).max(axis=0)
    b = np.abs(c[5] - c[4] - c[1] + c[0]).max(axis=0)
    d = np.abs(c[3] - c[2] - c[1] + c[0]).max(axis=0)
    h = np.abs(c[7] - c[6] - c[5] - c[3] + c[4] + c[2] + c[1] - c[0]).max(axis=0)
    u, v, w = np.abs(uvw)                                                   # (n, m) each
    with np.errstate(invalid="ignore"):  # (a flat cage: NaN, sent to the exact solve)
        bound = (a * u * v + b * u * w + d * v * w + h * u * v * w).max(axis=0, initial=0.0)
        affine = (np.abs(det) >= 0.1 * volume) & (volume > 0) & (bound < 1e-10)
    uvw = np.ascontiguousarray(uvw.transpose(2, 1, 0))                      # (m, n, 3)
    rest = np.flatnonzero(~affine)
    if rest.size:
        uvw[rest] = batched_cube_coordinates(corners[rest], points[rest])
    return uvw


def _cross(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Cross products of vectors stored as coordinate rows (3, m); the same bits as
    ``np.cross(x, y, axis=0)``, which moves the axis and runs several times slower here."""
    return np.stack([x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]])


def _batched_newton(corners: np.ndarray, points: np.ndarray, iterations: int = 30) -> np.ndarray:
    """``np.stack([inverse_trilinear(c, p) for c, p in zip(corners, points)])`` for cages
    (m, 8, 3) and points (m, n, 3), every step taken for all cages at once.

    Each cage keeps its own stopping test, and every product and solve is the one
    :func:`inverse_trilinear` makes for that cage alone (a stacked ``matmul`` and
    ``solve`` work matrix by matrix), so the coordinates are the same to the last bit.
    """
    origin = corners[:, 0]
    frame = np.stack([corners[:, 4] - origin, corners[:, 2] - origin, corners[:, 1] - origin], axis=2)
    uvw = np.swapaxes(np.linalg.solve(frame, np.swapaxes(points - origin[:, None], 1, 2)), 1, 2)
    active = np.arange(len(corners))
    for _ in range(iterations):
        cages, uv = corners[active], uvw[active]
        residual = cage_weights(uv) @ cages - points[active]
        going = ~(np.abs(residual).max(axis=(1, 2)) < 1e-13)  # NaN keeps stepping, as there
        if not going.any():
            break
        active, cages, uv, residual = active[going], cages[going], uv[going], residual[going]
        step = np.linalg.solve(_jacobian(cages, uv), residual[..., None])[..., 0]
        uvw[active] = uv - step
    return uvw


def point_weights(corners: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Cage coordinates (n, 8) of world points inside a hexahedron."""
    return cage_weights(inverse_trilinear(corners, points))
