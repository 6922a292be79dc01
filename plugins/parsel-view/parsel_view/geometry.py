"""Small geometry shared by the page, the pictures and the tests: hexahedra as triangles."""

from __future__ import annotations

import numpy as np

#: The 6 faces of a hexahedron in canonical corner order (corner k at the bits of k), as quads.
HEX_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))


def hexahedron_triangles() -> np.ndarray:
    """(12, 3) corner indices: each quad of :data:`HEX_QUADS` split in two."""
    return np.array([(a, b, c) for a, b, c, _ in HEX_QUADS] + [(a, c, d) for a, _, c, d in HEX_QUADS],
                    dtype=np.int64)


def hexahedron_quads(corners: np.ndarray) -> np.ndarray:
    """(6, 4, 3) face polygons of a hexahedron's corners, for drawing filled boxes."""
    corners = np.asarray(corners, dtype=float)
    return corners[np.array(HEX_QUADS)]
