"""A plain triangle mesh (vertices and faces) for meshes parsel makes itself.

Loaders of mesh files hand parts whatever their reader produced (a ``trimesh.Trimesh``);
shapes made of boxes (ShapeAssembly programs) carry their boxes as this small type, which
every consumer reads the same way (``vertices``, ``faces``), so loading them does not
import trimesh (about half a second).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.hexahedron import Hexahedron


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """Vertices (n, 3) float and triangles (m, 3) int; ``metadata`` as trimesh has it."""

    vertices: np.ndarray
    faces: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices, dtype=float)
        faces = np.array(self.faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise ValueError(f"vertices must be (n, 3), got shape {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must be (m, 3) triangles, got shape {faces.shape}")
        if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError("faces index missing vertices")
        vertices.flags.writeable = False
        faces.flags.writeable = False
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)

    def copy(self) -> TriangleMesh:
        return TriangleMesh(self.vertices, self.faces, dict(self.metadata))


def box_mesh(hexahedron: Hexahedron) -> TriangleMesh:
    """A hexahedron as a closed mesh: its 8 corners and 12 triangles wound outward."""
    return TriangleMesh(hexahedron.corners, hexahedron.triangles())
