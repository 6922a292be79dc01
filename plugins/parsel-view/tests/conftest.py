"""Shapes and programs for the slider page tests: the bundled chair and small groups of boxes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parsel_core.examples import WIDEN_TINY_TABLE
from parsel_core.graph import ShapeGraph
from parsel_core.relations import RotationSymmetry, TranslationSymmetry
from parsel_mesh.examples import CHAIR_ALL_PART_OPS, example_path
from parsel_mesh.loaders import load_mesh_shape, shape_from_meshes
from parsel_mesh.testing import box_mesh

#: Every part op the page implements, features and two parameters included.
CHAIR_PROGRAM = CHAIR_ALL_PART_OPS
#: Widen the tiny table (the core demo's program): parts of hexahedra only, no meshes.
TABLE_PROGRAM = WIDEN_TINY_TABLE


@pytest.fixture(scope="session")
def chair() -> ShapeGraph:
    """The bundled chair without detected relations (the programs here name parts only)."""
    return load_mesh_shape(example_path("chair"))


@pytest.fixture(scope="session")
def row_shape() -> ShapeGraph:
    """Four box slats 0.2 apart in the translation group ``row``."""
    meshes = {f"slat_{i}": box_mesh((0.2 * i, 0, 0), (0.2 * i + 0.05, 0.4, 0.02)) for i in range(4)}
    identity = tuple(range(8))
    row = TranslationSymmetry("row", tuple(meshes), step=(0.2, 0.0, 0.0), correspondence=(identity,) * 4)
    return shape_from_meshes(meshes, name="row").with_relations([row])


@pytest.fixture(scope="session")
def wheel_shape() -> ShapeGraph:
    """Six spokes round the y axis (a closed rotation group ``spokes``) on a hub."""
    meshes = {"hub": box_mesh((-0.1, 0, -0.1), (0.1, 0.1, 0.1))}
    base = box_mesh((0.1, 0.02, -0.02), (0.6, 0.08, 0.02))
    for i in range(6):
        angle = i * math.pi / 3
        rotation = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0], [-math.sin(angle), 0, math.cos(angle)]])
        spoke = base.copy()
        spoke.vertices = base.vertices @ rotation.T
        meshes[f"spoke_{i}"] = spoke
    shape = shape_from_meshes(meshes, name="wheel")
    spokes = RotationSymmetry("spokes", tuple(f"spoke_{i}" for i in range(6)), center=(0, 0, 0), axis=(0, 1, 0),
                              angle=math.pi / 3, correspondence=(tuple(range(8)),) * 6)
    return shape.with_relations([spokes])
