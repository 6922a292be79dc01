"""Choosing among valid edits (supplement 3.5): low distortion, most symmetry, least energy."""

from __future__ import annotations

import numpy as np

from parsel_core.hexahedron import Hexahedron

# The 12 edges of a hexahedron: corners whose indices differ in one bit.
EDGES = tuple((k, k ^ bit) for k in range(8) for bit in (4, 2, 1) if k < k ^ bit)

#: Edits whose normalised ARAP energy exceeds this are discarded when others remain.
HIGH_DISTORTION = 0.5


def arap_energy(rest: np.ndarray, deformed: np.ndarray) -> float:
    """As-rigid-as-possible energy of a hexahedron's deformation, over its 12 edges.

    ``min_R sum ||e' - R e||^2 / sum ||e||^2`` (Sorkine and Alexa 2007 with one rotation
    for the whole cell): 0 for rigid motions, growing with stretch, shear and taper.
    """
    e = np.array([rest[b] - rest[a] for a, b in EDGES])
    d = np.array([deformed[b] - deformed[a] for a, b in EDGES])
    u, _, vt = np.linalg.svd(d.T @ e)
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:
        rotation = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    return float(np.sum((d - e @ rotation.T) ** 2) / max(np.sum(e ** 2), 1e-300))


def symmetry_planes(corners: np.ndarray) -> int:
    """How many intrinsic symmetry planes the edited hexahedron keeps."""
    try:
        return len(Hexahedron(corners).intrinsic_symmetry_planes(tol=1e-6))
    except ValueError:
        return 0
