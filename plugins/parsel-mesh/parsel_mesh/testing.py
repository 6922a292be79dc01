"""Tiny meshes and scenes for tests of parsel-mesh and of plugins that consume mesh shapes.

A box mesh whose 8 vertices are its corners in the core's canonical order is its own
cage, which makes deformation and export results exact and easy to state.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from parsel_core.hexahedron import CORNER_BITS, FACE_TRIANGLES

#: The 6 faces of a canonical box as quads, counter-clockwise seen from outside.


def box_mesh(lo, hi) -> Any:
    """A closed triangle mesh of the box [lo, hi]; vertex k is corner k (cube point = bits of k)."""
    import trimesh

    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    return trimesh.Trimesh(vertices=np.where(CORNER_BITS == 1, hi, lo), faces=FACE_TRIANGLES, process=False)


def named_scene(meshes: Mapping[str, Any]) -> Any:
    """A trimesh scene with one node per mesh, node and geometry named by the key."""
    import trimesh

    scene = trimesh.Scene()
    for name, mesh in meshes.items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene
