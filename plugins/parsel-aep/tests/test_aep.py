"""Analytical Edit Propagation on designed cases with known answers."""

import json

import numpy as np
import pytest

from parsel_core import Part, Program, ShapeGraph, evaluate
from parsel_core.cli import main
from parsel_core.errors import ParselError, UnknownPartError
from parsel_core.examples import attachment, box, ground, reflection, tiny_table
from parsel_core.interfaces import SolveRequest
from parsel_core.plugins import solvers
from parsel_core.report import check_program


def solve(shape, seed_text, **kwargs):
    return solvers()["aep"].run(SolveRequest(shape, Program.from_text(seed_text), **kwargs))


def ops_on(program, part):
    return [op for op in program.ops if op.operand == part]


def test_widen_table_top_moves_legs_apart_mirrored_and_keeps_everything(parsel_backend):
    shape = tiny_table()
    result = solve(shape, "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)",
                   options={"backend": parsel_backend.name})
    program = result.program
    assert result.rejected == []
    report = check_program(shape, program)
    assert report.counts() == {"kept": 26, "broken_on_purpose": 0, "broken": 0}
    for leg in ("leg_bl", "leg_br", "leg_fl", "leg_fr"):
        (op,) = ops_on(program, leg)
        assert op.name == "translate" and abs(op.dir[0]) == 1.0  # legs move, they do not stretch
    corners = evaluate(program, shape, {"x": 0.5}).parts
    assert np.allclose(corners["leg_br"].mean(axis=0), (0.45 * 1.5, 0.35, -0.25))
    assert np.allclose(corners["leg_bl"].mean(axis=0), (-0.45 * 1.5, 0.35, -0.25))
    (rail,) = ops_on(program, "rail_back")
    assert rail.name == "scale_1d"
    # the slat row is laid out again through its virtual parent: more slats, same width
    assert [op.name for op in ops_on(program, "slat_row")] == ["scale_1d", "change_count"]
    slats = evaluate(program, shape, {"x": 1.0}).instances["slat_row"]
    assert len(slats) == 7 and np.allclose(np.ptp(slats[:, :, 0], axis=1), 0.06)


def test_raise_table_top_lengthens_legs_instead_of_moving_them():
    shape = tiny_table()
    program = solve(shape, "translate(top, dir=(0, 1, 0), amount=x)").program
    for leg in ("leg_bl", "leg_br", "leg_fl", "leg_fr"):
        (op,) = ops_on(program, leg)
        assert op.name in ("scale_1d", "translate") and (op.name == "scale_1d" or op.feature == "v+")
    corners = evaluate(program, shape, {"x": 0.3}).parts
    assert corners["leg_fl"][:, 1].min() == pytest.approx(0.0)
    assert corners["leg_fl"][:, 1].max() == pytest.approx(1.0)
    assert check_program(shape, program).counts()["broken"] == 0


def cabinet() -> ShapeGraph:
    body = Part("body", "body", box((-0.4, 0.0, -0.2), (0.4, 0.9, 0.2)))
    door_l = Part("door_l", "door", box((-0.4, 0.05, 0.2), (0.0, 0.85, 0.22)))
    door_r = Part("door_r", "door", box((0.0, 0.05, 0.2), (0.4, 0.85, 0.22)))
    handle_l = Part("handle_l", "handle", box((-0.06, 0.4, 0.22), (-0.04, 0.5, 0.25)))
    handle_r = Part("handle_r", "handle", box((0.04, 0.4, 0.22), (0.06, 0.5, 0.25)))
    relations = [reflection("mirror_doors", door_l, door_r, (0, 0, 0), (1, 0, 0)),
                 reflection("mirror_handles", handle_l, handle_r, (0, 0, 0), (1, 0, 0)),
                 attachment("door_l_body", door_l, body, "face"), attachment("door_r_body", door_r, body, "face"),
                 attachment("handle_on_l", handle_l, door_l), attachment("handle_on_r", handle_r, door_r),
                 ground("ground_body", body)]
    return ShapeGraph([body, door_l, door_r, handle_l, handle_r], relations, name="cabinet")


OPEN_DOOR = "rotate(door_l, origin=(-0.4, 0.45, 0.2), axis=(0, 1, 0), amount=x)"


def test_handle_follows_its_door_about_the_hinge_with_nhbd_edits():
    shape = cabinet()
    result = solve(shape, OPEN_DOOR, breaks=("door_l_body", "door_r_body"))
    (handle,) = ops_on(result.program, "handle_l")
    assert handle.name == "rotate" and handle.origin == (-0.4, 0.45, 0.2) and handle.axis == (0.0, 1.0, 0.0)
    assert handle.amount == "x"
    assert result.stats["nhbd_edits"] >= 1
    report = check_program(shape, result.program, ("door_l_body", "door_r_body"))
    states = report.states()
    assert states["handle_on_l"] == states["handle_on_r"] == "kept"
    assert states["door_l_body"] == "broken_on_purpose"


def test_without_nhbd_the_handle_comes_off():
    shape = cabinet()
    result = solve(shape, OPEN_DOOR, breaks=("door_l_body", "door_r_body"), options={"nhbd": False})
    assert not ops_on(result.program, "handle_l")
    assert "handle_on_l" in result.rejected
    assert check_program(shape, result.program).states()["handle_on_l"] == "broken"


def test_impossible_request_yields_a_breaking_edit_and_says_what_broke():
    # legs may only translate, so they cannot both stay on the floor and follow a raised top
    shape = tiny_table()
    hints = {leg: "translate" for leg in ("leg_bl", "leg_br", "leg_fl", "leg_fr")}
    result = solve(shape, "translate(top, dir=(0, 1, 0), amount=x)", hints=hints)
    assert result.stats["breaking_edits"] >= 1
    broken = set(result.rejected)
    assert broken and broken <= {r for r in shape.relations if r.startswith(("ground_", "attach_top_"))}
    states = check_program(shape, result.program).states()
    assert all(states[r] == "broken" for r in broken)
    without = solve(shape, "translate(top, dir=(0, 1, 0), amount=x)", hints=hints, options={"breaking": False})
    assert without.stats["breaking_edits"] == 0


def test_keep_hint_fixes_a_part():
    shape = tiny_table()
    result = solve(shape, "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)",
                   hints={"rail_back": "keep"})
    assert [op.name for op in ops_on(result.program, "rail_back")] == ["keep_fixed"]
    # legs cannot stay on a fixed rail and under a widening top at once: what breaks is reported
    states = check_program(shape, result.program).states()
    assert result.rejected and set(result.rejected) == {r for r, state in states.items() if state == "broken"}
    assert result.stats["breaking_edits"] >= 1


def test_tau_is_chosen_before_the_seed_collapses_a_part():
    shape = tiny_table()
    result = solve(shape, "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=-x)")
    tau = result.program.parameters[0].hi
    assert 0.9 <= tau < 0.95  # the top's width (1 - x) drops below 5% of itself at x = 0.95


@pytest.mark.parametrize("hints, breaks, message", [
    ({"seat": "scale"}, (), "no part 'seat'"),
    ({"top": "stretch"}, (), "unknown hint type 'stretch'"),
    ({}, ("no_such_relation",), "no relation 'no_such_relation'"),
])
def test_bad_requests_are_named(hints, breaks, message):
    with pytest.raises((ParselError, UnknownPartError), match=message):
        solve(tiny_table(), "translate(top, dir=(0, 1, 0), amount=x)", hints=hints, breaks=breaks)


SEED = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"


def test_edit_command_writes_program_and_report_deterministically(tmp_path, capsys):
    outputs = []
    for name in ("a", "b"):
        assert main(["edit", "tiny_table", "--seed", SEED, "-o", str(tmp_path / name)]) == 0
        outputs.append((tmp_path / name / "program.json").read_bytes())
    assert outputs[0] == outputs[1]
    report = json.loads((tmp_path / "a" / "report.json").read_text())
    assert report["counts"] == {"kept": 26, "broken_on_purpose": 0, "broken": 0}
    assert {"screen", "derive", "evaluate", "verify", "total"} <= set(report["stats"]["time_s"])
    assert report["stats"]["candidates_screened"] > 100
    assert len(report["relations"]) == 26 and report["relations"][0]["state"] == "kept"
    capsys.readouterr()
    assert main(["check", "tiny_table", str(tmp_path / "a" / "program.json"), "--json"]) == 0
    checked = json.loads(capsys.readouterr().out)
    assert checked["counts"] == report["counts"]


@pytest.mark.parametrize("argv, fragment", [
    (["--seed", "translate(seat, dir=(1, 0, 0), amount=x)"], "no part 'seat'"),
    (["--seed", "translate(top, dir=(1, 0, 0), amount=x"], "--seed:1"),
    (["--seed", SEED, "--hint", "top=wiggle"], "unknown hint type 'wiggle'"),
    (["--seed", SEED, "--hint", "nope"], "--hint 'nope'"),
    (["--seed", SEED, "--break", "glue_9"], "no relation 'glue_9'"),
    (["--seed", SEED, "--backend", "maple"], "unknown CAS backend"),
    (["--seed", SEED, "--solver", "oracle"], "unknown solver 'oracle'"),
    (["--seed", SEED, "--solver-option", "joint"], "--solver-option 'joint': expected NAME=VALUE"),
    (["--seed", SEED, "--solver-option", "joint=1.5"], "AEP option joint: expected a whole number"),
    (["--seed", SEED, "--solver-option", "joint=two"], "AEP option joint: expected a whole number from 0 to 10, "
                                                          "got 'two'"),
    (["--seed", SEED, "--solver-option", "samples=1"], "AEP option samples"),
    (["--seed", SEED, "--solver-option", "jiont=0"], "unknown AEP option(s): jiont"),
])
def test_edit_bad_input_is_one_line_exit_2_and_no_outdir(tmp_path, capsys, argv, fragment):
    out = tmp_path / "out"
    assert main(["edit", "tiny_table", *argv, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err, err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == []


def shelf() -> ShapeGraph:
    from parsel_core.relations import TranslationSymmetry

    sides = [Part("side_l", "side", box((-0.4, 0.0, -0.15), (-0.38, 1.6, 0.15))),
             Part("side_r", "side", box((0.38, 0.0, -0.15), (0.4, 1.6, 0.15)))]
    boards = [Part(f"board_{j}", "board", box((-0.38, 0.05 + 0.383 * j, -0.14), (0.38, 0.068 + 0.383 * j, 0.14)))
              for j in range(5)]
    relations = [reflection("mirror_sides", sides[0], sides[1], (0, 0, 0), (1, 0, 0)),
                 TranslationSymmetry("boards", tuple(b.id for b in boards), step=(0.0, 0.383, 0.0),
                                     correspondence=tuple(tuple(range(8)) for _ in boards)),
                 ground("ground_l", sides[0]), ground("ground_r", sides[1])]
    relations += [attachment(f"{b.id}_{s.id}", b, s) for b in boards for s in sides]
    return ShapeGraph(sides + boards, relations, name="shelf")


def test_stretching_a_shelf_adds_boards_with_change_count():
    shape = shelf()
    result = solve(shape, "scale_1d(side_l, origin=(-0.39, 0, 0), dir=(0, 1, 0), amount=x)")
    names = [op.name for op in ops_on(result.program, "boards")]
    assert names == ["scale_1d", "change_count"]
    assert result.rejected == []
    report = check_program(shape, result.program)
    assert report.counts()["broken"] == 0
    low, high = evaluate(result.program, shape, {"x": 0.0}), evaluate(result.program, shape, {"x": 1.0})
    assert len(low.instances["boards"]) == 5 and len(high.instances["boards"]) == 9
    spacing = np.diff(high.instances["boards"].mean(axis=1)[:, 1])
    assert np.allclose(spacing, spacing[0]) and abs(spacing[0] - 0.383) < 0.383 / 8
    thickness = np.ptp(high.instances["boards"][0][:, 1])
    assert thickness == pytest.approx(0.018)  # boards keep their shape
    top = high.instances["boards"][-1].mean(axis=0)[1]
    assert top == pytest.approx((0.05 + 0.383 * 4 + 0.009) * 2)  # the last board follows the stretched sides


@pytest.mark.parametrize("options, message", [
    ({"joint": "0"}, "AEP option joint: expected a whole number from 0 to 10, got '0'"),
    ({"joint": 11}, "AEP option joint"),
    ({"repair": True}, "AEP option repair"),
    ({"samples": 2}, "AEP option samples: expected a whole number from 3 to 1000"),
    ({"nhbd": "no"}, "AEP option nhbd: expected true or false"),
    ({"tau": 0.0}, "AEP option tau: expected a positive number"),
    ({"tau_max": float("inf")}, "AEP option tau_max"),
    ({"relative_tolerance": 1.5}, "AEP option relative_tolerance: expected a number between 0 and 1"),
    ({"backend": 3}, "AEP option backend"),
    ({"joint": 1, "speed": "max"}, r"unknown AEP option\(s\): speed \(known: backend, breaking"),
])
def test_options_are_checked_before_solving_with_the_option_named(options, message):
    with pytest.raises(ParselError, match=message):
        solve(tiny_table(), SEED, options=options)


def test_options_take_numpy_numbers_and_none():
    from parsel_aep.options import AEPOptions

    options = AEPOptions.from_mapping({"joint": np.int64(0), "tau": None, "tau_max": np.float64(0.5), "samples": 9})
    assert (options.joint, options.tau, options.tau_max, options.samples) == (0, None, 0.5, 9)


#: Python for a fresh interpreter: a solve of the tiny table that takes breaking-edits
#: (its top raised, its legs hinted to translate), its result as ``result``.
BREAKING_EDIT = ("from parsel_core import Program\nfrom parsel_core.examples import tiny_table\n"
                 "from parsel_core.interfaces import SolveRequest\nfrom parsel_core.plugins import solvers\n"
                 "hints = {leg: 'translate' for leg in ('leg_bl', 'leg_br', 'leg_fl', 'leg_fr')}\n"
                 "seed = Program.from_text('translate(top, dir=(0, 1, 0), amount=x)')\n"
                 "result = solvers()['aep'].run(SolveRequest(tiny_table(), seed, hints=hints))\n")


def test_a_breaking_edit_does_not_import_numpy_masked_arrays(parsel_fresh_python):
    """``numpy.ma`` (20-30 ms of a command's start-up) stays unloaded by a solve that takes
    breaking-edits (breaking.py groups its rows without ``np.unique``)."""
    code = ("import sys\n" + BREAKING_EDIT
            + "print(result.stats['breaking_edits'] >= 1, 'numpy.ma' in sys.modules)")
    assert parsel_fresh_python(code).split() == ["True", "False"]


def test_the_lapack_wrappers_blas_runs_on_one_thread_in_a_solve(parsel_fresh_python):
    """gelsy comes with scipy's own OpenBLAS: in a process whose BLAS was not started on
    one thread, a solve still runs it on one thread (one_blas_thread finds it)."""
    code = ("import os\n"
            "for name in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):\n"
            "    os.environ.pop(name, None)\n"
            "from threadpoolctl import threadpool_info\n"
            "from parsel_aep import cluster\n"
            "pools = []\n"
            "gelsy = cluster._orthogonal_lstsq\n"
            "def spy(*a, **k):\n"
            "    pools.extend(i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas')\n"
            "    return gelsy(*a, **k)\n"
            "cluster._orthogonal_lstsq = spy\n"
            + BREAKING_EDIT + "print(len(pools) > 1, set(pools) == {1})")
    assert parsel_fresh_python(code).split() == ["True", "True"]
