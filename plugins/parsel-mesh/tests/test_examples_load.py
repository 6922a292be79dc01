"""The bundled examples load by name through the core, with the parts and labels they were built with."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from parsel_core.cage import inverse_trilinear
from parsel_core.hexahedron import MIRROR_PERMUTATION
from parsel_core.loading import load_shape
from parsel_core.plugins import example_shapes
from parsel_mesh.examples import NAMES, example_path
from parsel_mesh.loaders import load_mesh_shape

LABEL_COUNTS = {
    "chair": {"seat": 1, "leg": 4, "back_upright": 2, "back_rail": 1, "back_slat": 5},
    "table": {"top": 1, "leg": 4, "apron": 4},
    "cabinet": {"body": 1, "door": 2, "handle": 2, "plinth": 1},
    "shelf": {"side_panel": 2, "board": 5, "back_panel": 1},
}


@pytest.fixture(scope="module")
def shapes():
    return {name: load_mesh_shape(example_path(name)) for name in NAMES}


def test_examples_are_registered():
    examples = example_shapes()
    for name in NAMES:
        assert examples[name] == example_path(name)


def test_chair_loads_by_name_through_the_core():
    shape = load_shape("chair")
    assert shape.name == "chair"
    assert sorted(shape.parts) == sorted(["seat", "back_rail", *(f"leg.{i:03d}" for i in range(4)),
                                          *(f"back_upright.{i:03d}" for i in range(2)),
                                          *(f"back_slat.{i:03d}" for i in range(5))])


@pytest.mark.parametrize("name", NAMES)
def test_part_names_and_labels(shapes, name):
    shape = shapes[name]
    assert Counter(p.label for p in shape.parts.values()) == LABEL_COUNTS[name]
    for pid, part in shape.parts.items():
        assert part.name == pid
        assert pid.split(".")[0] == part.label


@pytest.mark.parametrize("name", NAMES)
def test_meshes_lie_inside_their_boxes(shapes, name):
    for pid, part in shapes[name].parts.items():
        uvw = inverse_trilinear(part.hexahedron.corners, np.asarray(part.mesh.vertices))
        assert uvw.min() > -1e-9 and uvw.max() < 1 + 1e-9, pid
        assert part.hexahedron.volume > 0, pid


def test_chair_legs_mirror_with_corresponding_corners(shapes):
    parts = shapes["chair"].parts

    def corners(pid):
        return parts[pid].hexahedron.corners

    flip_x, flip_z = np.array([-1.0, 1, 1]), np.array([1.0, 1, -1])
    np.testing.assert_allclose(corners("leg.001")[list(MIRROR_PERMUTATION[0])], corners("leg.000") * flip_x, atol=1e-9)
    np.testing.assert_allclose(corners("leg.002")[list(MIRROR_PERMUTATION[2])], corners("leg.000") * flip_z, atol=1e-9)


def test_chair_slats_are_translated_copies(shapes):
    parts = shapes["chair"].parts
    first = parts["back_slat.000"].hexahedron.corners
    for i in range(1, 5):
        np.testing.assert_allclose(parts[f"back_slat.{i:03d}"].hexahedron.corners, first + [0.06 * i, 0, 0], atol=1e-6)


def test_legs_stand_on_the_floor(shapes):
    for pid, part in shapes["chair"].parts.items():
        if part.label == "leg":
            assert part.hexahedron.corners[:, 1].min() == 0.0, pid
