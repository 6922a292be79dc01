"""The designed cases of the AEP issue on the bundled assets (loaded, relations detected)."""

import numpy as np
import pytest

from parsel_core import Program, evaluate
from parsel_core.interfaces import SolveRequest
from parsel_core.loading import load_shape
from parsel_core.plugins import solvers
from parsel_core.report import check_program


@pytest.fixture(scope="module")
def shapes():
    return {name: load_shape(name) for name in ("chair", "table", "cabinet", "shelf")}


def relation_id(shape, kind, *members):
    (found,) = [r.id for r in shape.relations.values() if r.kind == kind and set(r.members) == set(members)]
    return found


def run(shape, seed, **kwargs):
    return solvers()["aep"].run(SolveRequest(shape, Program.from_text(seed), **kwargs))


def test_widen_chair_seat(shapes):
    chair = shapes["chair"]
    result = run(chair, "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)")
    program = result.program
    assert check_program(chair, program).counts()["broken"] == 0
    ops = {op.operand: op for op in program.ops}
    left, right = ops["leg.000"], ops["leg.001"]
    assert left.name == right.name == "translate"
    assert left.dir == (-1.0, 0.0, 0.0) and right.dir == (1.0, 0.0, 0.0) and left.amount == right.amount
    corners = evaluate(program, chair, {"x": 0.5}).parts
    assert np.allclose(corners["leg.000"].mean(axis=0)[0], -corners["leg.001"].mean(axis=0)[0])  # still mirrored
    assert ops["back_rail"].name == "scale_1d"  # the back widens
    slats = evaluate(program, chair, {"x": 1.0}).instances
    assert len(next(iter(slats.values()))) > 5  # with more slats rather than fatter ones


def test_raise_table_top_lengthens_legs(shapes):
    table = shapes["table"]
    program = run(table, "translate(top, dir=(0, 1, 0), amount=0.3 * x)").program
    assert check_program(table, program).counts()["broken"] == 0
    for leg in ("leg.000", "leg.001", "leg.002", "leg.003"):
        (op,) = [op for op in program.ops if op.operand == leg]
        assert op.name == "scale_1d" and op.dir == (0.0, 1.0, 0.0) and op.origin[1] == 0.0
    corners = evaluate(program, table, {"x": 1.0}).parts["leg.000"]
    rest_top = table.part("leg.000").hexahedron.corners[:, 1].max()
    # the foot stays on the floor; the top end follows the table top (the contact point sits
    # 2.5 mm below the leg's end, inside the top, so the end itself rises a little more)
    assert corners[:, 1].min() == pytest.approx(0.0)
    assert rest_top + 0.3 <= corners[:, 1].max() < rest_top + 0.302


DOOR = "rotate('door.000', origin=(-0.397, 0.49, 0.218), axis=(0, -1, 0), amount=x)"


def door_breaks(cabinet):
    return (relation_id(cabinet, "attachment", "body", "door.000"),
            relation_id(cabinet, "attachment", "body", "door.001"),
            relation_id(cabinet, "attachment", "door.000", "door.001"))


def test_cabinet_handle_follows_the_door_about_its_hinge(shapes):
    cabinet = shapes["cabinet"]
    result = run(cabinet, DOOR, breaks=door_breaks(cabinet))
    (handle,) = [op for op in result.program.ops if op.operand == "handle.000"]
    assert handle.name == "rotate" and handle.origin == (-0.397, 0.49, 0.218) and handle.amount == "x"
    states = check_program(cabinet, result.program, door_breaks(cabinet)).states()
    assert states[relation_id(cabinet, "attachment", "door.000", "handle.000")] == "kept"
    assert list(states.values()).count("broken") == 0


def test_cabinet_handle_comes_off_without_nhbd_edits(shapes):
    cabinet = shapes["cabinet"]
    result = run(cabinet, DOOR, breaks=door_breaks(cabinet), options={"nhbd": False})
    states = check_program(cabinet, result.program, door_breaks(cabinet)).states()
    assert states[relation_id(cabinet, "attachment", "door.000", "handle.000")] == "broken"


def test_stretch_shelf_adds_boards(shapes):
    shelf = shapes["shelf"]
    result = run(shelf, "scale_1d('side_panel.000', origin=(-0.39, 0, 0), dir=(0, 1, 0), amount=x)")
    assert check_program(shelf, result.program).counts()["broken"] == 0
    group = relation_id(shelf, "translation", *(f"board.{i:03d}" for i in range(5)))
    assert [op.name for op in result.program.ops if op.operand == group] == ["scale_1d", "change_count"]
    assert len(evaluate(result.program, shelf, {"x": 1.0}).instances[group]) == 9


def test_impossible_request_reports_what_broke(shapes):
    table = shapes["table"]
    hints = {leg: "translate" for leg in ("leg.000", "leg.001", "leg.002", "leg.003")}
    result = run(table, "translate(top, dir=(0, 1, 0), amount=0.3 * x)", hints=hints)
    assert result.stats["breaking_edits"] >= 1 and result.rejected
    states = check_program(table, result.program).states()
    assert {r for r, s in states.items() if s == "broken"} == set(result.rejected)
