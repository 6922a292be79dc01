"""Box geometry the detectors rely on, against hand-computed values and a second method."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from parsel_relations.geometry import Boxes, intersection_vertices, rotation_matrix, separations

EYE = np.eye(3)
QUARTER_TURN_Z = rotation_matrix(np.array([0.0, 0.0, 1.0]), np.pi / 4)


def unit_boxes(centers, frames) -> Boxes:
    return Boxes(np.asarray(centers, dtype=float), np.stack(frames), np.full((len(centers), 3), 0.5))


def test_separation_of_axis_aligned_boxes():
    boxes = unit_boxes([(0, 0, 0), (1.5, 0, 0), (0.25, 0.25, 0), (1.0, 1.0, 0), (3, 4, 0)], [EYE] * 5)
    got = separations(boxes, np.zeros(4, int), np.array([1, 2, 3, 4]))
    # 0.5 apart along x; overlapping 0.75 deep; touching along an edge; 3 apart along y (2 along x)
    np.testing.assert_allclose(got, [0.5, -0.75, 0.0, 3.0])


def test_separation_of_a_box_turned_about_z():
    # its edge points at the unit cube: the half diagonal sqrt(2)/2 reaches towards it
    boxes = unit_boxes([(0, 0, 0), (1 + np.sqrt(0.5) + 0.1, 0, 0), (0.5 + np.sqrt(0.5) - 0.05, 0, 0)],
                       [EYE, QUARTER_TURN_Z, QUARTER_TURN_Z])
    np.testing.assert_allclose(separations(boxes, np.array([0, 0]), np.array([1, 2])), [0.6, -0.05], atol=1e-12)


def test_separation_is_symmetric_in_its_arguments():
    boxes = unit_boxes([(0, 0, 0), (1.2, 0.3, -0.4)], [EYE, rotation_matrix(np.array([0.6, 0.8, 0.0]), 0.7)])
    assert separations(boxes, np.array([0]), np.array([1]))[0] == separations(boxes, np.array([1]), np.array([0]))[0]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3), st.lists(st.floats(-1, 1), min_size=3, max_size=3),
       st.floats(0, np.pi), st.lists(st.floats(0.05, 1.0), min_size=6, max_size=6))
def test_separation_agrees_with_clipping_and_bounds_the_distance(offset, axis, angle, halves):
    axis = np.asarray(axis) if np.linalg.norm(axis) > 1e-3 else np.array([0.0, 0.0, 1.0])
    frame = rotation_matrix(axis / np.linalg.norm(axis), angle)
    boxes = Boxes(np.array([[0.0, 0.0, 0.0], offset]), np.stack([EYE, frame]), np.reshape(halves, (2, 3)))
    gap = separations(boxes, np.array([0]), np.array([1]))[0]
    _, valid = intersection_vertices(boxes, np.array([0]), np.array([1]), 0.0)
    if abs(gap) > 1e-9:  # away from touching, the two methods must agree on intersecting
        assert (gap < 0) == bool(valid.any())
    if gap > 0:  # a lower bound on the distance between the boxes' points
        rng = np.random.default_rng(0)
        local = rng.uniform(-1, 1, size=(2, 1500, 3)) * boxes.halves[:, None, :]
        points = boxes.centers[:, None, :] + np.einsum("bnj,bji->bni", local, boxes.axes)
        nearest = np.linalg.norm(points[0][:, None, :] - points[1][None, :, :], axis=2).min()
        assert gap <= nearest + 1e-9
