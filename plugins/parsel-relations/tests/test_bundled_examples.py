"""Detected relations on the bundled assets: what a person sees in them is what is found."""

import pytest

from parsel_core.cli import main
from parsel_core.loading import load_shape


def members(shape, kind):
    return {frozenset(r.members) for r in shape.relations.values() if r.kind == kind}


def attached(shape, a, b):
    return frozenset({a, b}) in members(shape, "attachment")


def test_chair_legs_two_reflection_pairs_each_on_seat_and_ground():
    chair = load_shape("chair")
    legs = [f"leg.{i:03d}" for i in range(4)]
    reflections = members(chair, "reflection")
    assert frozenset({"leg.000", "leg.001"}) in reflections and frozenset({"leg.002", "leg.003"}) in reflections
    grounded = {next(iter(m)) for m in members(chair, "ground")}
    assert grounded == set(legs)
    assert all(attached(chair, leg, "seat") for leg in legs)
    (row,) = [r for r in chair.relations.values() if r.kind == "translation"]
    assert row.members == tuple(f"back_slat.{i:03d}" for i in range(5))
    assert all(attached(chair, f"back_slat.{i:03d}", "back_rail") for i in range(5))
    assert frozenset({"back_upright.000", "back_upright.001"}) in reflections


def test_table_aprons_between_legs_and_under_the_top():
    table = load_shape("table")
    assert all(attached(table, f"leg.{i:03d}", "top") for i in range(4))
    assert all(attached(table, f"apron.{i:03d}", "top") for i in range(4))
    assert attached(table, "apron.000", "leg.000") and attached(table, "apron.000", "leg.001")
    assert {next(iter(m)) for m in members(table, "ground")} == {f"leg.{i:03d}" for i in range(4)}


def test_cabinet_doors_and_handles_mirror_and_attach():
    cabinet = load_shape("cabinet")
    reflections = members(cabinet, "reflection")
    assert frozenset({"door.000", "door.001"}) in reflections and frozenset({"handle.000", "handle.001"}) in reflections
    assert attached(cabinet, "handle.000", "door.000") and attached(cabinet, "door.000", "body")
    assert {next(iter(m)) for m in members(cabinet, "ground")} == {"plinth"}


def test_shelf_boards_form_a_translation_group_held_by_both_sides():
    shelf = load_shape("shelf")
    (row,) = [r for r in shelf.relations.values() if r.kind == "translation"]
    assert row.members == tuple(f"board.{i:03d}" for i in range(5))
    assert row.step[1] == pytest.approx(0.383, abs=1e-6)
    assert all(attached(shelf, f"board.{i:03d}", f"side_panel.{s:03d}") for i in range(5) for s in range(2))


@pytest.mark.parametrize("name", ["chair", "table", "cabinet", "shelf"])
def test_every_detected_relation_holds_at_rest_and_inspect_lists_it(name, capsys):
    shape = load_shape(name)
    corners = shape.rest_corners()
    assert all(float(r.error(corners)) < 1e-6 * shape.size for r in shape.relations.values())
    assert main(["inspect", name]) == 0
    out = capsys.readouterr().out
    assert all(rid in out for rid in shape.relations)
