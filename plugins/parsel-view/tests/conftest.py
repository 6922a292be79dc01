"""Shapes and programs for the slider page tests: the bundled chair and small groups of boxes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from parsel_core.graph import ShapeGraph
from parsel_core.relations import RotationSymmetry, TranslationSymmetry
from parsel_mesh.examples import example_path
from parsel_mesh.loaders import load_mesh_shape, shape_from_meshes
from parsel_mesh.testing import box_mesh

#: Every part op the page implements, features and two parameters included.
CHAIR_PROGRAM = """\
param x in [0, 1] default 0.5
param y in [-0.5, 0.5] default 0
scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)
translate('leg.000', dir=(-1, 0, 0), amount=0.19 * x)
translate(face('leg.001', 'v-'), dir=(1, 0, 0), amount=0.1 * x ** 2)
rotate('back_upright.000', origin=(-0.19, 0.45, -0.19), axis=(0, 0, 1), amount=0.3 * sin(x))
shear('leg.002', origin=(0, 0, 0), normal=(0, 1, 0), dir=(1, 0, 0), amount=-0.2 * y)
scale_2d(back_rail, origin=(0, 0.83, -0.19), normal=(0, 1, 0), amount=max(x, y) / 2)
scale_3d('leg.003', origin=(0.19, 0, -0.18), amount=abs(y))
translate(corner(seat, 'u+v+w+'), dir=(0, 1, 0), amount=0.05 * y - -x / e)
keep_fixed('back_slat.002')
"""

#: Widen the tiny table (the core demo's program): parts of hexahedra only, no meshes.
TABLE_PROGRAM = """\
param x in [0, 0.5] default 0.25
scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)
translate(leg_br, dir=(1, 0, 0), amount=0.45 * x)
translate(leg_fr, dir=(1, 0, 0), amount=0.45 * x)
translate(leg_bl, dir=(-1, 0, 0), amount=0.45 * x)
translate(leg_fl, dir=(-1, 0, 0), amount=0.45 * x)
scale_1d(rail_back, origin=(0, 0.22, -0.25), dir=(1, 0, 0), amount=18 * x / 17)
scale_1d(rail_front, origin=(0, 0.22, 0.25), dir=(1, 0, 0), amount=18 * x / 17)
"""


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
