"""Directional labels and shape descriptions."""

from __future__ import annotations

from parsel_core import ShapeGraph
from parsel_core.examples import tiny_table
from parsel_relations import describe_shape, detect_relations, directional_labels


def test_tiny_table_labels():
    labels = directional_labels(tiny_table())
    assert labels["top"] == "top"
    assert labels["leg_bl"] == "leg (back-left)"
    assert labels["leg_fr"] == "leg (front-right)"
    assert labels["rail_back"] == "rail (back)" and labels["rail_front"] == "rail (front)"
    assert [labels[f"slat_{k}"] for k in range(4)] == [
        "slat (left)", "slat (left-center)", "slat (right-center)", "slat (right)"]
    assert list(labels) == list(tiny_table().parts)


def test_rows_of_three_and_five(shapes):
    three = [shapes.bounds(f"s{k}", "shelf", (0, y, 0), (1, y + 0.05, 1)) for k, y in enumerate((0.9, 0.1, 0.5))]
    assert directional_labels(ShapeGraph(three)) == {
        "s0": "shelf (top)", "s1": "shelf (bottom)", "s2": "shelf (center)"}
    five = [shapes.bounds(f"d{k}", "drawer", (0, 0, z), (1, 0.2, z + 0.1)) for k, z in enumerate(range(5))]
    assert [directional_labels(ShapeGraph(five))[f"d{k}"] for k in range(5)] == [
        "drawer (back)", "drawer (back-center)", "drawer (center)", "drawer (front-center)", "drawer (front)"]


def test_more_than_five_get_numbers(shapes):
    parts = [shapes.bounds(f"slat_{k}", "slat", (x, 0, 0), (x + 0.1, 0.1, 1)) for k, x in enumerate((5, 0, 3, 1, 4, 2))]
    labels = directional_labels(ShapeGraph(parts))
    assert labels["slat_1"] == "slat (1 of 6)" and labels["slat_0"] == "slat (6 of 6)"
    assert len(set(labels.values())) == 6


def test_rotational_arrangement_uses_compass_words(shapes):
    labels = directional_labels(detect_relations(shapes.spokes(4)))
    assert labels["spoke_0"] == "spoke (front)"
    assert labels["spoke_1"] == "spoke (right)"
    assert labels["spoke_2"] == "spoke (back)"
    assert labels["spoke_3"] == "spoke (left)"
    five = directional_labels(detect_relations(shapes.spokes(5)))
    assert len({five[f"spoke_{k}"] for k in range(5)}) == 5
    assert five["spoke_2"] == "spoke (right-back)"


def test_centre_of_a_grid_and_collisions(shapes):
    corners = {"a": (-1, -1), "b": (1, -1), "c": (-1, 1), "d": (1, 1), "e": (0, 0)}
    parts = [shapes.bounds(k, "leg", (x - 0.1, 0, z - 0.1), (x + 0.1, 1, z + 0.1)) for k, (x, z) in corners.items()]
    labels = directional_labels(ShapeGraph(parts))
    assert labels["e"] == "leg (center)" and labels["c"] == "leg (front-left)"
    same = [shapes.bounds(k, "knob", (0, 0, 0), (0.1, 0.1, 0.1)) for k in "xy"]
    assert directional_labels(ShapeGraph(same)) == {"x": "knob (1)", "y": "knob (2)"}


def test_describe_shape_names_parts_and_relations():
    text = describe_shape(detect_relations(tiny_table()))
    assert "+x right, +y up, +z front" in text
    assert "- leg_fl: leg (front-left), size 0.05 x 0.70 x 0.05, centre (-0.45, 0.35, 0.25)" in text
    assert "leg (back-left) and leg (back-right) mirror each other about the plane x = 0.00" in text
    assert "form a row of 4 evenly spaced copies, step (0.20, 0.00, 0.00)" in text
    assert "top and leg (front-left) are attached (point contact)" in text or \
        "leg (front-left) and top are attached (point contact)" in text
    assert "leg (front-right) stands on the ground" in text


def test_describe_rotation_and_bare_shapes(shapes):
    text = describe_shape(detect_relations(shapes.spokes(6)))
    assert "form a full ring of 6 copies around the y axis" in text and "60 degrees apart" in text
    bare = describe_shape(shapes.spokes(3))
    assert "Relations:" not in bare and "spoke_2" in bare
