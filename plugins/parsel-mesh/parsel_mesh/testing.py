"""Tiny meshes and scenes for tests of parsel-mesh and of plugins that consume mesh shapes.

A box mesh whose 8 vertices are its corners in the core's canonical order is its own
cage, which makes deformation and export results exact and easy to state.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from parsel_core.hexahedron import CORNER_BITS

#: The 6 faces of a canonical box as quads, counter-clockwise seen from outside.
BOX_QUADS = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))


def box_mesh(lo, hi) -> Any:
    """A closed triangle mesh of the box [lo, hi]; vertex k is corner k (cube point = bits of k)."""
    import trimesh

    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    faces = [(a, b, c) for a, b, c, _ in BOX_QUADS] + [(a, c, d) for a, _, c, d in BOX_QUADS]
    return trimesh.Trimesh(vertices=np.where(CORNER_BITS == 1, hi, lo), faces=faces, process=False)


def named_scene(meshes: Mapping[str, Any]) -> Any:
    """A trimesh scene with one node per mesh, node and geometry named by the key."""
    import trimesh

    scene = trimesh.Scene()
    for name, mesh in meshes.items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return scene
