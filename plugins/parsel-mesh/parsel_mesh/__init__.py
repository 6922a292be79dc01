"""parsel-mesh: part-segmented mesh assets for parsel (docs/meshes.md).

Loaders for GLB/GLTF, OBJ, PLY, OFF, STL and PartNet directories (each named node,
object or leaf is a part, its hexahedron a fitted box), the ``cage`` deformer that moves
part meshes with their edited hexahedra, GLB/OBJ/PLY exporters of the edited meshes and
the bundled example assets (``chair``, ``table``, ``cabinet``, ``shelf``).

This module only holds the hook implementations. Every ``parsel`` command imports it,
so the work (and trimesh, which takes about a second to import) lives in submodules
that the hooks import when they are called.
"""

from __future__ import annotations

from parsel_core import hookimpl

__version__ = "0.1.0"


@hookimpl
def parsel_shape_loaders():
    from parsel_mesh.loaders import shape_loaders

    return shape_loaders()


@hookimpl
def parsel_deformers():
    from parsel_mesh.deform import CageDeformer

    return [CageDeformer()]


@hookimpl
def parsel_exporters():
    from parsel_mesh.exporters import mesh_exporters

    return mesh_exporters()


@hookimpl
def parsel_example_shapes():
    from parsel_mesh.examples import NAMES, example_path

    return {name: example_path(name) for name in NAMES}
