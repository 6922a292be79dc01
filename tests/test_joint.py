"""Many sliders, one valid shape: layered programs keep relations at every slider combination."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from parsel_core.api import as_shape, edit, proxydural
from parsel_core.cli import main
from parsel_core.errors import ParselError, ProgramFormatError
from parsel_core.joint import (
    add_layer,
    box_corners,
    check_joint_relations,
    degenerate_parts,
    edge_skew,
    fit_joint_range,
    follows_for,
    joint_losses,
    joint_samples,
    requests_of,
    turns_parts,
)
from parsel_core.plugins import get_cas_backend
from parsel_core.program import Parameter, Program, compile_program, evaluate, follow_weights
from parsel_core.report import check_program, kept_alone

WIDEN = "param x1 in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x1)\n"
RAISE = ("param x2 in [0, 0.5]\ntranslate(seat, dir=(0, 1, 0), amount=x2)\n"
         "translate(back_rail, dir=(0, 1, 0), amount=x2)\n")

#: Seeds on the bundled chair, solved once each (expert mode, so no language model is involved).
CHAIR_SEEDS = {
    "wider": "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)",
    "deeper": "scale_1d(seat, origin=(0, 0.43, 0), dir=(0, 0, 1), amount=x)",
    "longer legs": "scale_1d('leg.000', origin=(-0.19, 0, 0.18), dir=(0, 1, 0), amount=x)",
    "thicker legs": "scale_2d('leg.000', origin=(-0.19, 0.2075, 0.18), normal=(0, 1, 0), amount=x)",
    "taller back": "scale_1d('back_upright.000', origin=(-0.19, 0.45, -0.19), dir=(0, 1, 0), amount=0.5 * x)",
}


@pytest.fixture(scope="module")
def chair():
    return as_shape("chair")


@pytest.fixture(scope="module")
def solved(chair):
    return {name: edit(chair, seed=seed).program for name, seed in CHAIR_SEEDS.items()}


def joint_keeps_what_each_slider_keeps(shape, program, breaks=(), samples=200) -> None:
    """Every box corner and ``samples`` random joint samples keep each relation every slider keeps alone."""
    report = check_program(shape, program, breaks, samples=samples)
    assert report.box_corners == 2 ** len(program.parameters)
    assert report.samples == report.box_corners + samples
    kept = {s.id for s in report.relations if s.state == "kept"}
    must = kept_alone(shape, program, breaks)
    assert must - kept == set(), [(s.id, s.max_error, s.worst_at) for s in report.relations if s.id in must - kept]


# -- layered programs ------------------------------------------------------------------------


def test_layers_round_trip_through_json_and_text():
    program = Program.from_text(WIDEN).plus(Program.from_text(RAISE))
    assert program.layers == (1, 2) and program.parameter_names == ("x1", "x2")
    assert "\nlayer\n" in program.to_text()
    assert Program.from_text(program.to_text()).layers == (1, 2)
    assert Program.from_json(program.to_json()).layers == (1, 2)
    assert "layers" not in Program.from_text(WIDEN).to_dict()  # plain programs keep their bytes
    assert [len(p.ops) for p in program.layer_programs()] == [1, 2]


@pytest.mark.parametrize("layers, message", [([2, 2], "count 4 ops"), ([0, 3], "positive op counts"),
                                             ("12", "must be a list"), ([1.5, 1.5], "positive op counts")])
def test_bad_layers_are_one_line_errors_naming_the_file(layers, message):
    data = Program.from_text(WIDEN).plus(Program.from_text(RAISE)).to_dict()
    data["layers"] = layers
    with pytest.raises(ProgramFormatError, match=message) as info:
        Program.from_dict(data, source="p.json")
    assert str(info.value).startswith("p.json: ") and "\n" not in str(info.value)


def test_a_layer_line_needs_ops_on_both_sides():
    with pytest.raises(ProgramFormatError, match="must follow at least one op"):
        Program.from_text("layer\n" + WIDEN)
    with pytest.raises(ProgramFormatError, match="no ops after it"):
        Program.from_text(WIDEN + "layer\n")


def test_then_is_sequential_and_refuses_layers():
    layered = Program.from_text(WIDEN).plus(Program.from_text(RAISE))
    with pytest.raises(ProgramFormatError, match="add layers with plus"):
        layered.then(Program.from_text(WIDEN))


def test_layers_add_their_displacements_from_rest(chair):
    first, second = Program.from_text(WIDEN), Program.from_text(RAISE)
    layered = first.plus(second)
    values = {"x1": np.array([0.0, 0.3, 1.0]), "x2": np.array([0.5, 0.1, 0.25])}
    got = evaluate(layered, chair, values).parts
    a = evaluate(first, chair, {"x1": values["x1"]}).parts
    b = evaluate(second, chair, {"x2": values["x2"]}).parts
    rest = chair.rest_corners()
    for pid in rest:
        np.testing.assert_allclose(got[pid], a[pid] + b[pid] - rest[pid], atol=1e-12, err_msg=pid)
    compiled = compile_program(layered, chair, get_cas_backend(None))(values).parts
    for pid in rest:
        np.testing.assert_allclose(compiled[pid], got[pid], atol=1e-12, err_msg=pid)


# -- the joint box ------------------------------------------------------------------------------


def test_joint_samples_start_with_every_box_corner():
    params = tuple(Parameter(f"x{i}", -i, i + 1) for i in range(4))
    program = Program((), params)
    values, corners = joint_samples(program, 10)
    assert corners == 16 and all(len(v) == 26 for v in values.values())
    seen = {tuple(values[p.name][k] for p in params) for k in range(16)}
    assert len(seen) == 16 and all(v in (p.lo, p.hi) for row in seen for v, p in zip(row, params))
    assert joint_samples(Program((), params[:1]), 10)[1] == 0  # one parameter: its samples as before
    assert len(box_corners(tuple(Parameter(f"y{i}") for i in range(12)))["y0"]) == 1024  # capped


def test_check_names_the_worst_joint_sample_of_a_sequential_stack(chair, solved):
    """The old stacking (then): legs thickened about their rest centres after the wider seat moved them out
    slide off the seat's corners."""
    longer = solved["thicker legs"].renamed("x", "x2")
    stacked = solved["wider"].renamed("x", "x1").then(Program(longer.ops, (longer.parameters[0],)))
    report = check_program(chair, stacked)
    broken = [s for s in report.relations if s.state == "broken"]
    assert report.box_corners == 4 and broken
    for state in broken:
        assert set(state.worst_at) == {"x1", "x2"}
        assert state.worst_at["x1"] == stacked.parameter("x1").hi  # the widest seat is where it breaks
    assert "worst_at" in report.to_dict()["relations"][0]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(order=st.permutations(sorted(CHAIR_SEEDS)), count=st.integers(2, 3))
def test_any_stack_of_chair_requests_keeps_what_each_keeps_alone(chair, solved, order, count):
    """Property: the box corners and 200 random joint samples keep every relation each slider keeps."""
    program = None
    for name in order[:count]:
        program, _ = add_layer(chair, program, solved[name], name)
    assert [r["request"] for r in requests_of(program)] == list(order[:count])
    joint_keeps_what_each_slider_keeps(chair, program)
    assert not degenerate_parts(chair, program, joint_samples(program, 64)[0])


def test_a_range_narrows_where_two_layers_would_collapse_a_part(chair):
    thinner = Program.from_text("param x in [0, 0.9]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), "
                                "amount=-x)\n")
    program, name = add_layer(chair, None, thinner, "thinner")
    assert name == "x1"
    program, name = add_layer(chair, program, thinner, "thinner again")
    assert name == "x2"
    x2 = program.parameter("x2")
    assert 0 < x2.hi < 0.9 and x2.lo == 0
    assert not degenerate_parts(chair, program, joint_samples(program, 200)[0])
    assert program.parameter("x1").hi == 0.9  # earlier sliders keep their ranges
    assert fit_joint_range(chair, program, "x2") == program  # already valid: unchanged


def test_layouts_in_both_modes_do_not_combine(chair):
    import dataclasses

    from parsel_core.ops import ChangeCount

    group = next(g for g in chair.virtual_parents)
    top = Program((ChangeCount(group, amount="2 * x", mode="top_down"),))
    bottom = dataclasses.replace(top.ops[0], mode="bottom_up")
    program, _ = add_layer(chair, None, top, "spread")
    with pytest.raises(ParselError, match="one row cannot follow both"):
        add_layer(chair, program, Program((bottom,)), "extend")


# -- proxydural and edit --on -------------------------------------------------------------------


@pytest.mark.parametrize("name", ["chair", "table", "shelf"])
def test_proxydural_corners_and_random_samples_keep_what_each_slider_keeps(name):
    result = proxydural(name, 4)
    assert len(result.used) == 4 and len(result.program.layers) == 4
    breaks = result.program.metadata["breaks"]
    joint_keeps_what_each_slider_keeps(result.shape, result.program, breaks)
    report = result.report.to_dict()
    assert list(report)[:4] == ["tolerance", "samples", "box_corners", "counts"]  # joint states first
    assert report["box_corners"] == 16 and report["samples"] == 216


def max_skew(program, shape, values) -> dict[str, float]:
    return edge_skew(shape, program, values)


def test_proxydural_cabinet_opens_the_widened_doors_about_their_carried_hinges():
    """"Open the doors" turns each door about its own hinge with its handle, the body held;
    as an outer layer it turns the doors the other sliders widened, taller and deeper:
    every corner of the box keeps each relation every slider keeps alone and every part
    stays a box (summed, the turn and the widening shear the doors by 45 degrees)."""
    result = proxydural("cabinet", 4)
    shape, program = result.shape, result.program
    assert result.skipped == [] and [u["request"] for u in result.used][-1] == "open the doors"
    assert program.outer == (3,) and {f.part for f in program.follows} == {"door.000", "door.001"}
    joint_keeps_what_each_slider_keeps(shape, program, program.metadata["breaks"])
    corners = box_corners(program.parameters)
    assert max(max_skew(program, shape, corners).values()) < 1e-9
    # at every corner of the box each door's hinge edge is where the other sliders put it
    beneath = Program(program.ops[:15], program.parameters, {}, program.layers[:3])
    for door, follow in zip(("door.000", "door.001"), program.follows):
        weights = follow_weights(shape, follow)
        moved = np.einsum("k,...ka->...a", weights, evaluate(beneath, shape, corners).parts[door])
        turned = np.einsum("k,...ka->...a", weights, evaluate(program, shape, corners).parts[door])
        np.testing.assert_allclose(turned, moved, atol=1e-12)
    summed = Program(program.ops, program.parameters, {}, program.layers)
    assert max(max_skew(summed, shape, {"x1": 1.0, "x2": 0.0, "x3": 0.0, "x4": 1.0}).values()) > 0.7


#: The cabinet's "wider" (the body widened along world x: on the plinth only by sliding) and a
#: turn of the whole cabinet about a vertical hinge.
CABINET_WIDER = ("param x in [0, 1]\n"
                 "scale_1d(body, origin=(0, 0.4875, -0.0125), dir=(1, 0, 0), amount=x)\n")
CABINET_TURN = "param x in [0, 1]\n" + "".join(
    f"rotate({part!r}, origin=(-0.397, 0.4875, 0.218), axis=(0, -1, 0), amount=pi / 2 * x)\n"
    for part in ("door.000", "door.001", "body", "plinth", "handle.000", "handle.001"))


def test_a_sum_that_breaks_a_sliding_contact_is_refused_and_a_turn_goes_on_top():
    """Each layer keeps body-on-plinth alone; their sum does not (a body widened across the turned
    plinth), which the joint check refuses. add_layer puts the turn on top instead, in either
    order: the widened cabinet turns as one, and body-on-plinth holds."""
    cabinet = as_shape("cabinet")
    wider, turn = Program.from_text(CABINET_WIDER), Program.from_text(CABINET_TURN)
    summed = wider.renamed("x", "x1").plus(turn.renamed("x", "x2"))
    assert "attachment_2" in kept_alone(cabinet, summed)
    assert "attachment_2" in {s.id for s in joint_losses(cabinet, summed)}
    with pytest.raises(ParselError, match=r"'turn' \(x2\) breaks attachment_2 \(body on plinth\)"):
        check_joint_relations(cabinet, wider.renamed("x", "x1"), summed, "x2", "turn")
    for first, second in ((wider, turn), (turn, wider)):
        program, _ = add_layer(cabinet, None, first, "first")
        program, _ = add_layer(cabinet, program, second, "second")
        assert joint_losses(cabinet, program) == [] and len(program.outer) == 1
        assert max(max_skew(program, cabinet, box_corners(program.parameters)).values()) < 1e-9
        assert len({f.part for f in program.follows}) == 1  # the whole cabinet turns as one rigid set


def test_follows_group_parts_that_move_alike_under_their_largest_part():
    cabinet = as_shape("cabinet")
    layer = Program.from_text(
        "rotate('door.000', origin=(-0.397, 0.4875, 0.218), axis=(0, -1, 0), amount=x)\n"
        "rotate('handle.000', origin=(-0.397, 0.4875, 0.218), axis=(0, -1, 0), amount=x)\n"
        "rotate('door.001', origin=(0.397, 0.4875, 0.218), axis=(0, 1, 0), amount=x)\n"
        "translate(body, dir=(0, 0, 1), amount=0.1 * x)\n")
    assert turns_parts(cabinet, layer) and not turns_parts(cabinet, Program.from_text(CABINET_WIDER))
    follows = follows_for(cabinet, layer)
    assert [(f.part, f.ops) for f in follows] == [("door.000", (0, 1)), ("door.001", (2,))]
    assert follows[0].point == (-0.397, 0.4875, 0.218)


def test_edit_on_adds_a_parameter_solved_on_top(tmp_path, capsys, chair):
    first, second = tmp_path / "out", tmp_path / "out2"
    assert main(["edit", "chair", "make the chair wider", "-o", str(first)]) == 0
    assert main(["edit", "chair", "make the legs longer", "--on", str(first / "program.json"), "-o",
                 str(second)]) == 0
    out = capsys.readouterr().out
    assert "x2 in [0, " in out and "4 box corners" in out
    data = json.loads((second / "program.json").read_text())
    assert [p["name"] for p in data["parameters"]] == ["x", "x2"] and len(data["layers"]) == 2
    assert [r["request"] for r in data["metadata"]["requests"]] == ["make the chair wider", "make the legs longer"]
    program = Program.from_dict(data)
    joint_keeps_what_each_slider_keeps(chair, program)
    report = json.loads((second / "report.json").read_text())
    assert report["box_corners"] == 4 and report["counts"]["broken"] == 0
    assert all(set(r["worst_at"]) == {"x", "x2"} for r in report["relations"])
    # a third request on top of the two, given the OUTDIR this time
    assert main(["edit", "chair", "make the chair deeper", "--on", str(second), "-o", str(tmp_path / "out3")]) == 0
    three = Program.from_json((tmp_path / "out3" / "program.json").read_text())
    assert three.parameter_names == ("x", "x2", "x3") and len(three.layers) == 3
    joint_keeps_what_each_slider_keeps(chair, three)


def test_edit_on_bad_programs_are_one_line_errors_naming_the_file(tmp_path, capsys):
    missing = tmp_path / "nothing" / "program.json"
    assert main(["edit", "chair", "make the legs longer", "--on", str(missing), "-o", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(missing) in err and "no such program file" in err
    table = tmp_path / "table"
    assert main(["edit", "tiny_table", "make the table wider", "-o", str(table)]) == 0
    capsys.readouterr()
    assert main(["edit", "chair", "make the legs longer", "--on", str(table / "program.json"), "-o",
                 str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(table / "program.json") in err and "not 'chair'" in err
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    assert main(["edit", "chair", "make the legs longer", "--on", str(bad), "-o", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err
    assert not any((tmp_path / n).exists() for n in "abc")


def test_a_layer_that_does_not_combine_beneath_a_turn_is_tried_with_every_layer_summed(monkeypatch):
    """When the joint check refuses a layer beneath the turn on top (and on top, if it turns
    too), add_layer sums every layer, the turn too, as before turns went on top."""
    import parsel_core.joint as joint

    cabinet = as_shape("cabinet")
    turn = Program.from_text("".join(
        f"rotate({part!r}, origin=({side * 0.397}, 0.4875, 0.218), axis=(0, {-side}, 0), amount=pi / 2 * x)\n"
        for side, parts in ((-1, ("door.000", "handle.000")), (1, ("door.001", "handle.001"))) for part in parts))
    wider = Program.from_text(CABINET_WIDER)
    base, _ = add_layer(cabinet, None, turn, "open")
    assert base.outer == (0,) and len(base.follows) == 2
    real = joint.check_joint_relations

    def refuse_outer(shape, before, program, name, request):
        if program.outer:
            raise ParselError("refused on top")
        return real(shape, before, program, name, request)

    monkeypatch.setattr(joint, "check_joint_relations", refuse_outer)
    program, _ = add_layer(cabinet, base, wider, "wider")
    assert program.outer == () and program.follows == () and program.layers == (4, 1)
    monkeypatch.setattr(joint, "check_joint_relations", lambda *args: (_ for _ in ()).throw(ParselError("no")))
    with pytest.raises(ParselError, match="no"):
        add_layer(cabinet, base, wider, "wider")
