"""Small geometry shared by the page, the pictures and the tests: hexahedra as triangles."""

from __future__ import annotations

import numpy as np

from parsel_core.hexahedron import FACE_QUADS, FACE_TRIANGLES


def hexahedron_triangles() -> np.ndarray:
    """(12, 3) corner indices: each face quad split in two."""
    return FACE_TRIANGLES.astype(np.int64)


def hexahedron_quads(corners: np.ndarray) -> np.ndarray:
    """(6, 4, 3) face polygons of a hexahedron's corners, for drawing filled boxes."""
    corners = np.asarray(corners, dtype=float)
    return corners[np.array(FACE_QUADS)]
