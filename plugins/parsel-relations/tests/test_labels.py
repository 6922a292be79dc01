"""Directional labels and shape descriptions of shapes with detected relations."""

from __future__ import annotations

from parsel_core import ShapeGraph
from parsel_core.examples import tiny_table
from parsel_core.labels import directional_labels
from parsel_core.language import describe_shape
from parsel_relations import detect_relations


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
    assert "+x is right, +y is up, +z is front" in text
    assert "- leg_fl: leg, front-left; size 0.050 x 0.700 x 0.050; centre (-0.450, 0.350, 0.250)" in text
    assert "leg_bl and leg_br mirror each other across the plane x = 0.000" in text
    assert "slat_0, slat_1, slat_2, slat_3 repeat in a row, 4 copies 0.200 apart along +x" in text
    assert "(point contact): leg_fl is attached to top" in text or "(point contact): top is attached to leg_fl" in text
    assert "ground contact: leg_fr stands on the ground" in text


def test_describe_rotation_and_bare_shapes(shapes):
    text = describe_shape(detect_relations(shapes.spokes(6)))
    assert "repeat around the axis +y" in text and "6 copies 60.0 degrees apart" in text
    assert "- spoke_0: spoke, 1 of 6;" in text  # more than five: numbered around the ring
    bare = describe_shape(shapes.spokes(3))
    assert "- (none)" in bare and "spoke_2" in bare
