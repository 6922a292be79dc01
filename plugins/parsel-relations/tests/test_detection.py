"""The detectors against shapes whose relations are known: tiny_table and synthetic ones."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from parsel_core import Hexahedron, Part, ShapeGraph
from parsel_core.examples import tiny_table
from parsel_core.interfaces import RelationDetector
from parsel_core.relations import Attachment, GroundContact, ReflectionSymmetry, RotationSymmetry, TranslationSymmetry
from parsel_relations import FAMILIES, detect_all, detect_relations, detectors

REST_TOL = 1e-9


def members(shape: ShapeGraph, cls) -> set[frozenset[str]]:
    return {frozenset(r.members) for r in shape.relations.values() if isinstance(r, cls)}


def assert_hold_at_rest(shape: ShapeGraph, tol: float = REST_TOL) -> None:
    rest = shape.rest_corners()
    for relation in shape.relations.values():
        assert float(relation.error(rest)) < tol, relation.id


def group_members(shape: ShapeGraph) -> list[str]:
    return [m for r in shape.relations.values() if r.kind in ("translation", "rotation") for m in r.members]


# -- tiny_table ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def table_pair() -> tuple[ShapeGraph, ShapeGraph]:
    hand = tiny_table()
    return hand, detect_relations(hand)


def test_tiny_table_symmetries_match_the_hand_built_ones(table_pair):
    hand, found = table_pair
    assert members(found, ReflectionSymmetry) == members(hand, ReflectionSymmetry)
    assert not members(found, RotationSymmetry)
    (row,) = [r for r in found.relations.values() if isinstance(r, TranslationSymmetry)]
    assert row.members == hand.relations["slat_row"].members
    assert np.allclose(row.step, hand.relations["slat_row"].step)


def test_tiny_table_reflection_parameters(table_pair):
    hand, found = table_pair
    by_members = {r.members: r for r in found.relations.values() if isinstance(r, ReflectionSymmetry)}
    for expected in (r for r in hand.relations.values() if isinstance(r, ReflectionSymmetry)):
        got = by_members[expected.members]
        assert np.allclose(got.normal, expected.normal)
        assert np.isclose(np.dot(got.origin, got.normal), np.dot(expected.origin, expected.normal))
        assert got.correspondence == expected.correspondence


def test_tiny_table_attachments_join_the_same_pairs(table_pair):
    hand, found = table_pair
    assert members(found, Attachment) == members(hand, Attachment)
    assert members(found, GroundContact) == members(hand, GroundContact)


def test_tiny_table_attachment_kinds(table_pair):
    """Leg under the top's corner: point. Slat across a rail: line, across the rail, on the
    slat's centre line (as built by hand). Rail end against a leg: the rail is centred on
    the leg in z, so the region shares that plane and the contact is a line (the hand-built
    table uses a point there)."""
    _, found = table_pair
    kinds = {frozenset(r.members): r.contact for r in found.relations.values() if isinstance(r, Attachment)}
    assert kinds[frozenset(("top", "leg_fl"))] == "point"
    assert kinds[frozenset(("slat_2", "rail_front"))] == "line"
    assert kinds[frozenset(("rail_back", "leg_bl"))] == "line"
    slat = next(r for r in found.relations.values() if set(r.members) == {"slat_0", "rail_back"})
    points = slat.points(found.rest_corners())
    assert np.allclose(points[:, 0], -0.3) and np.allclose(points[:, 1], 0.24)
    assert np.allclose(sorted(points[:, 2]), [-0.26, -0.24])


def test_tiny_table_ground_points_are_the_leg_bottoms(table_pair):
    _, found = table_pair
    for relation in (r for r in found.relations.values() if isinstance(r, GroundContact)):
        assert len(relation.weights) == 4
        assert relation.height == pytest.approx(0.0)


def test_every_relation_holds_at_rest(table_pair):
    assert_hold_at_rest(table_pair[1])


def test_ids_are_deterministic_and_ordered():
    first = detect_relations(tiny_table())
    second = detect_relations(tiny_table())
    assert [r.to_dict() for r in first.relations.values()] == [r.to_dict() for r in second.relations.values()]
    reflections = [r for r in first.relations.values() if r.kind == "reflection"]
    assert [r.id for r in reflections] == [f"reflection_{k}" for k in range(len(reflections))]
    assert [r.members for r in reflections] == sorted(r.members for r in reflections)


def test_families_select_without_changing_results():
    full = detect_all(tiny_table())
    only = detect_all(tiny_table(), families=["reflection", "ground"])
    assert {r.kind for r in only} == {"reflection", "ground"}
    assert [r.to_dict() for r in only] == [r.to_dict() for r in full if r.kind in ("reflection", "ground")]
    with pytest.raises(ValueError, match="unknown relation famil"):
        detect_all(tiny_table(), families=["mirror"])


def test_input_shape_is_not_changed():
    shape = tiny_table()
    before = sorted(shape.relations)
    detect_relations(shape)
    assert sorted(shape.relations) == before


# -- plugin ----------------------------------------------------------------------------


def test_detectors_are_registered():
    from parsel_core.plugins import relation_detectors

    installed = relation_detectors()
    for family in FAMILIES:
        assert isinstance(installed[family], RelationDetector)
    assert [d.name for d in detectors()] == list(FAMILIES)


def test_core_detection_finds_the_same_relations():
    from parsel_core.detection import detect_relations as core_detect

    bare = tiny_table().with_relations([])
    ours = detect_relations(bare)
    core = core_detect(bare, families=FAMILIES)
    assert [r.to_dict() for r in core.relations.values()] == [r.to_dict() for r in ours.relations.values()]


def test_relative_tolerance_is_configurable(tmp_path, monkeypatch):
    config = tmp_path / "parsel.toml"
    config.write_text("[parsel]\nrelation_tolerance = 0.2\n")
    monkeypatch.setenv("PARSEL_CONFIG", str(config))
    near = ShapeGraph([Part("a", "a", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1))),
                       Part("b", "b", Hexahedron.from_bounds((1.1, 0, 0), (2, 1, 1)))])
    assert members(detect_relations(near), Attachment) == {frozenset("ab")}
    monkeypatch.delenv("PARSEL_CONFIG")
    assert not members(detect_relations(near), Attachment)


# -- symmetries ------------------------------------------------------------------------


@pytest.mark.parametrize("count", [3, 5, 6, 8])
def test_spokes_form_a_closed_rotation_group(shapes, count):
    found = detect_relations(shapes.spokes(count))
    (ring,) = [r for r in found.relations.values() if isinstance(r, RotationSymmetry)]
    assert ring.members == tuple(f"spoke_{k}" for k in range(count))
    assert ring.closed
    assert ring.angle == pytest.approx(2 * np.pi / count)
    assert np.allclose(ring.axis, (0, 1, 0)) and np.allclose(np.asarray(ring.center)[[0, 2]], 0)
    assert not members(found, ReflectionSymmetry)  # no pairs inside the group
    assert {frozenset(("hub", f"spoke_{k}")) for k in range(count)} <= members(found, Attachment)
    assert ring.id in found.virtual_parents
    assert_hold_at_rest(found)


def test_open_arc_of_rotated_copies(shapes):
    shape = shapes.spokes(8)
    arc = ShapeGraph([p for p in shape.parts.values() if p.id in {"spoke_0", "spoke_1", "spoke_2", "spoke_3"}])
    (ring,) = [r for r in detect_relations(arc).relations.values() if isinstance(r, RotationSymmetry)]
    assert ring.members == ("spoke_0", "spoke_1", "spoke_2", "spoke_3")
    assert not ring.closed and ring.angle == pytest.approx(np.pi / 4)
    assert_hold_at_rest(detect_relations(arc))


def test_square_legs_are_mirror_pairs_not_a_ring(shapes):
    found = detect_relations(shapes.square_legs())
    assert not members(found, RotationSymmetry)
    assert members(found, ReflectionSymmetry) == {
        frozenset(p) for p in (("leg_bl", "leg_br"), ("leg_fl", "leg_fr"), ("leg_bl", "leg_fl"), ("leg_br", "leg_fr"))}


@pytest.mark.parametrize("angle", [0.0, 0.5, 1.2])
def test_mirrored_rotated_boxes(shapes, angle):
    found = detect_relations(shapes.mirrored_pair(angle))
    (mirror,) = [r for r in found.relations.values() if isinstance(r, ReflectionSymmetry)]
    assert mirror.members == ("arm_a", "arm_b")
    assert np.allclose(mirror.normal, (1, 0, 0)) and mirror.origin[0] == pytest.approx(0.2)
    assert sorted(mirror.correspondence) == list(range(8))
    assert_hold_at_rest(found)


def test_no_reflection_between_different_labels(shapes):
    found = detect_relations(shapes.mirrored_pair(0.5, label_b="handle"))
    assert not members(found, ReflectionSymmetry)


def test_no_reflection_between_different_sizes(shapes):
    parts = [shapes.bounds("a", "leg", (-1, 0, 0), (-0.8, 1, 0.2)),
             shapes.bounds("b", "leg", (0.8, 0, 0), (1, 1.2, 0.2))]
    assert not members(detect_relations(ShapeGraph(parts)), ReflectionSymmetry)


def test_mirrored_rows_pair_each_slat_with_its_mirror_image(shapes):
    found = detect_relations(shapes.two_rows(5))
    rows = [r for r in found.relations.values() if isinstance(r, TranslationSymmetry)]
    assert {r.members for r in rows} == {tuple(f"slat_{s}{k}" for k in range(5)) for s in "lr"}
    assert members(found, ReflectionSymmetry) == {frozenset((f"slat_l{k}", f"slat_r{k}")) for k in range(5)}
    assert_hold_at_rest(found)


def test_a_part_is_in_at_most_one_group(shapes):
    """A 3 x 3 grid of knobs: rows and columns are both translation groups; keep disjoint ones."""
    parts = [shapes.bounds(f"k{i}{j}", "knob", (i - 0.1, 0, j - 0.1), (i + 0.1, 0.2, j + 0.1))
             for i in range(3) for j in range(3)]
    found = detect_relations(ShapeGraph(parts))
    in_groups = group_members(found)
    assert len(in_groups) == len(set(in_groups)) == 9
    assert_hold_at_rest(found)


def test_uneven_row_is_not_a_group(shapes):
    parts = [shapes.bounds(f"s{k}", "slat", (x, 0, 0), (x + 0.1, 0.1, 1)) for k, x in enumerate((0, 0.3, 0.9))]
    assert not group_members(detect_relations(ShapeGraph(parts)))


def test_two_copies_are_a_reflection_not_a_group(shapes):
    parts = [shapes.bounds(f"s{k}", "slat", (x, 0, 0), (x + 0.1, 0.1, 1)) for k, x in enumerate((0, 0.3))]
    found = detect_relations(ShapeGraph(parts))
    assert not group_members(found)
    assert members(found, ReflectionSymmetry) == {frozenset(("s0", "s1"))}


@settings(max_examples=40, deadline=None)
@given(angles=st.tuples(*[st.floats(-np.pi, np.pi) for _ in range(3)]),
       size=st.tuples(*[st.floats(0.05, 1.0) for _ in range(3)]),
       axis=st.integers(0, 2), offset=st.floats(-1, 1), distance=st.floats(0.8, 2.0))
def test_any_mirrored_pair_is_found(angles, size, axis, offset, distance):
    rotation = np.eye(3)
    for k, angle in enumerate(angles):
        c, s = np.cos(angle), np.sin(angle)
        turn = np.eye(3)
        i, j = [a for a in range(3) if a != k]
        turn[[i, i, j, j], [i, j, i, j]] = c, -s, s, c
        rotation = rotation @ turn
    centre = np.zeros(3)
    centre[axis] = offset - distance
    a = Hexahedron.from_box(centre, size, rotation.T)
    corners = a.corners.copy()
    corners[:, axis] = 2 * offset - corners[:, axis]
    shape = ShapeGraph([Part("p", "part", a), Part("q", "part", Hexahedron(corners))])
    found = detect_relations(shape)
    (mirror,) = [r for r in found.relations.values() if isinstance(r, ReflectionSymmetry)]
    assert mirror.normal[axis] == 1.0 and mirror.origin[axis] == pytest.approx(offset)
    assert_hold_at_rest(found, 1e-6 * shape.size)  # ground: corners level within 1e-6 x size


# -- attachments -----------------------------------------------------------------------


def kind_of(parts) -> str:
    (relation,) = [r for r in detect_relations(ShapeGraph(parts)).relations.values() if isinstance(r, Attachment)]
    return relation.contact


def test_attachment_kinds_follow_the_symmetry_order(shapes):
    seat = shapes.bounds("seat", "seat", (-0.5, 0.4, -0.5), (0.5, 0.5, 0.5))
    # a leg under one corner of the seat: the region is off-centre on the seat -> point
    leg = shapes.bounds("leg", "leg", (-0.5, 0, -0.5), (-0.4, 0.4, -0.4))
    assert kind_of([seat, leg]) == "point"
    # a back across the full width at the rear: symmetric about the seat's x plane -> line
    back = shapes.bounds("back", "back", (-0.5, 0.5, -0.5), (0.5, 1.2, -0.4))
    assert kind_of([seat, back]) == "line"
    # a cushion centred on the seat: symmetric about x and z planes of both -> face
    cushion = shapes.bounds("cushion", "cushion", (-0.3, 0.5, -0.3), (0.3, 0.6, 0.3))
    assert kind_of([seat, cushion]) == "face"
    # a dowel inside the seat -> volume
    dowel = shapes.bounds("dowel", "dowel", (0.1, 0.42, 0.1), (0.2, 0.48, 0.2))
    assert kind_of([seat, dowel]) == "volume"


def test_line_attachment_spans_the_shared_width(shapes):
    seat = shapes.bounds("seat", "seat", (-0.5, 0.4, -0.5), (0.5, 0.5, 0.5))
    back = shapes.bounds("back", "back", (-0.5, 0.5, -0.5), (0.5, 1.2, -0.4))
    found = detect_relations(ShapeGraph([seat, back]))
    (relation,) = [r for r in found.relations.values() if isinstance(r, Attachment)]
    points = relation.points(found.rest_corners())
    assert np.allclose(sorted(points[:, 0]), [-0.5, 0.5])
    assert np.allclose(points[:, 1], 0.5) and np.allclose(points[:, 2], -0.45)


def test_attachment_weights_in_both_parts(shapes):
    seat = shapes.bounds("seat", "seat", (-0.5, 0.4, -0.5), (0.5, 0.5, 0.5))
    cushion = shapes.bounds("cushion", "cushion", (-0.3, 0.5, -0.3), (0.3, 0.6, 0.3))
    found = detect_relations(ShapeGraph([seat, cushion]))
    (relation,) = [r for r in found.relations.values() if isinstance(r, Attachment)]
    assert relation.members == ("cushion", "seat")
    weights_a, weights_b = np.asarray(relation.weights_a), np.asarray(relation.weights_b)
    assert weights_a.shape == weights_b.shape == (4, 8)
    assert np.allclose(weights_a.sum(axis=1), 1) and np.allclose(weights_b.sum(axis=1), 1)
    rest = found.rest_corners()
    assert np.allclose(weights_a @ rest["cushion"], weights_b @ rest["seat"])


def test_gap_within_tolerance_attaches_and_larger_does_not(shapes):
    a = shapes.bounds("a", "a", (0, 0, 0), (1, 1, 1))
    near = shapes.bounds("b", "b", (1.005, 0, 0), (2, 1, 1))
    far = shapes.bounds("b", "b", (1.1, 0, 0), (2, 1, 1))
    assert members(detect_relations(ShapeGraph([a, near])), Attachment) == {frozenset("ab")}
    assert not members(detect_relations(ShapeGraph([a, far])), Attachment)
    assert_hold_at_rest(detect_relations(ShapeGraph([a, near])))


def test_rotated_boxes_touching_at_an_angle(shapes):
    base = shapes.bounds("base", "base", (-1, 0, -1), (1, 0.2, 1))
    tilted = Part("strut", "strut", shapes.posed_box((0.3, 0.2 + 0.25, 0), (0.1, 0.6, 0.1), shapes.rot_x(0.4)))
    found = detect_relations(ShapeGraph([base, tilted]))
    assert members(found, Attachment) == {frozenset(("base", "strut"))}
    assert_hold_at_rest(found)


def test_ground_uses_the_lowest_corners(shapes):
    leg = shapes.bounds("leg", "leg", (0, 0, 0), (0.1, 1, 0.1))
    shelf = shapes.bounds("shelf", "shelf", (0, 0.5, 0.1), (1, 0.6, 1))
    tilted = Part("strut", "strut", shapes.posed_box((1.5, 0.5, 0), (0.1, 1.0, 0.1), shapes.rot_x(0.3)))
    shape = ShapeGraph([leg, shelf, tilted])
    floor = tilted.hexahedron.corners[:, 1].min()
    found = detect_relations(shape, tolerance=0.01)
    grounds = {r.members[0]: r for r in found.relations.values() if isinstance(r, GroundContact)}
    assert set(grounds) == {"strut"} if floor < -0.01 else {"leg", "strut"}
    assert len(grounds["strut"].weights) == 2  # turned about x: the lowest edge
    assert_hold_at_rest(found)


def test_empty_and_single_part_shapes(shapes):
    single = ShapeGraph([shapes.bounds("a", "a", (0, 0, 0), (1, 1, 1))])
    found = detect_relations(single)
    assert [r.kind for r in found.relations.values()] == ["ground"]


def test_nested_reflections_stay_within_a_half(shapes):
    """Planks at x = -3, -2, 2, 3: a reflected pair of mirrored pairs. Pairs straddling x = 0
    other than the mirror images (-3 with 2, -2 with 3) are not reflections of the shape."""
    parts = [shapes.bounds(f"p{k}", "plank", (x - 0.1, 0, 0), (x + 0.1, 1, 1)) for k, x in enumerate((-3, -2, 2, 3))]
    found = detect_relations(ShapeGraph(parts))
    assert members(found, ReflectionSymmetry) == {frozenset(p) for p in (("p0", "p3"), ("p1", "p2"), ("p0", "p1"),
                                                                           ("p2", "p3"))}
    assert_hold_at_rest(found)


def test_a_part_a_little_above_the_floor_may_drift_by_its_gap():
    """Ground contacts stand at the floor's height: a part detected 0.005 above it has that gap
    as its rest error and may drift by it; a part on the floor may not (docs/relations.md)."""
    from parsel_core.report import tolerance_for

    shape = detect_relations(ShapeGraph([
        Part("low", "low", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1))),
        Part("high", "high", Hexahedron.from_bounds((1.5, 0.005, 0), (2.5, 1, 1)))]), families=["ground"])
    grounds = {r.members[0]: r for r in shape.relations.values() if isinstance(r, GroundContact)}
    assert set(grounds) == {"low", "high"} and all(r.height == 0.0 for r in grounds.values())
    tol = tolerance_for(shape)
    assert grounds["low"].allowance(tol) == tol and grounds["high"].allowance(tol) == pytest.approx(0.005)
    rest = shape.rest_corners()
    assert all(float(r.error(rest)) == 0.0 for r in grounds.values())  # anchored: exact at rest
    for lift, kept in ((0.004, True), (0.006, False)):
        moved = {**rest, "high": rest["high"] + (0.0, lift, 0.0)}
        assert (float(grounds["high"].error(moved)) < grounds["high"].allowance(tol)) is kept
    moved = {**rest, "low": rest["low"] + (0.0, 10 * tol, 0.0)}
    assert not float(grounds["low"].error(moved)) < grounds["low"].allowance(tol)
