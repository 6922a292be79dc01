"""Choosing among valid edits (supplement 3.5): low distortion, most symmetry, least energy."""

from __future__ import annotations

import numpy as np

from parsel_core.hexahedron import Hexahedron

# The 12 edges of a hexahedron: corners whose indices differ in one bit.
EDGES = tuple((k, k ^ bit) for k in range(8) for bit in (4, 2, 1) if k < k ^ bit)

#: Edits whose normalised ARAP energy (at tau) exceeds this are discarded as too distorting.
HIGH_DISTORTION = 1.0


def arap_energy(rest: np.ndarray, deformed: np.ndarray) -> float:
    """As-rigid-as-possible energy of a hexahedron's deformation, over its 12 edges.

    ``mean_e ||e' - R e||^2 / ||e||^2`` with R the best rotation for the whole cell
    (Sorkine and Alexa 2007, one cell): 0 for rigid motions, growing with stretch, shear
    and taper. Each edge is measured against its own length, so making a thin leg as
    wide as a table top costs far more than stretching a rail to twice its length.
    """
    e = np.array([rest[b] - rest[a] for a, b in EDGES])
    d = np.array([deformed[b] - deformed[a] for a, b in EDGES])
    u, _, vt = np.linalg.svd(d.T @ e)
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:
        rotation = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    lengths = np.maximum(np.sum(e ** 2, axis=1), 1e-300)
    return float(np.mean(np.sum((d - e @ rotation.T) ** 2, axis=1) / lengths))


def symmetry_planes(corners: np.ndarray) -> int:
    """How many intrinsic symmetry planes the edited hexahedron keeps."""
    try:
        return len(Hexahedron(corners).intrinsic_symmetry_planes(tol=1e-6))
    except ValueError:
        return 0


def arap_energies(rest: np.ndarray, deformed: np.ndarray) -> np.ndarray:
    """:func:`arap_energy` for a batch of deformations (N, 8, 3) of one rest hexahedron."""
    a, b = np.array(EDGES).T
    e = rest[b] - rest[a]                                   # (12, 3)
    d = deformed[:, b] - deformed[:, a]                     # (N, 12, 3)
    u, _, vt = np.linalg.svd(np.einsum("nei,ej->nij", d, e))
    det = np.linalg.det(u @ vt)
    fix = np.ones((len(deformed), 3))
    fix[:, 2] = np.sign(det + (det == 0))
    rotation = (u * fix[:, None, :]) @ vt                  # (N, 3, 3)
    residual = d - np.einsum("nij,ej->nei", rotation, e)
    lengths = np.maximum(np.sum(e ** 2, axis=1), 1e-300)
    return np.mean(np.sum(residual ** 2, axis=2) / lengths, axis=1)


def symmetry_plane_counts(deformed: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """:func:`symmetry_planes` for a batch of hexahedra (N, 8, 3)."""
    from parsel_core.hexahedron import CORNER_BITS, MIRROR_PERMUTATION

    counts = np.zeros(len(deformed), dtype=int)
    centre = deformed.mean(axis=1, keepdims=True)
    scale = np.maximum(np.ptp(deformed, axis=1).max(axis=1), 1e-12)
    for axis in range(3):
        perm = list(MIRROR_PERMUTATION[axis])
        low = [k for k in range(8) if not CORNER_BITS[k, axis]]
        direction = (deformed[:, perm] - deformed)[:, low].sum(axis=1)
        norm = np.linalg.norm(direction, axis=1, keepdims=True)
        n = direction / np.maximum(norm, 1e-300)
        reflected = deformed - 2.0 * np.einsum("nkj,nj->nk", deformed - centre, n)[..., None] * n[:, None, :]
        error = np.abs(reflected - deformed[:, perm]).max(axis=(1, 2))
        counts += (norm[:, 0] > 1e-12) & (error <= tol * scale)
    return counts
