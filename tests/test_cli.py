"""The command line: the demo, evaluate, convert, and one-line errors with exit status 2."""

import json

import numpy as np
import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.examples import tiny_table
from parsel_core.program import Program

PROGRAM = "param x in [0, 0.5] default 0.2\nscale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n"


@pytest.fixture
def files(tmp_path):
    program = tmp_path / "widen.parsel"
    program.write_text(PROGRAM)
    shape = tmp_path / "table.shape.json"
    shape.write_text(json.dumps(tiny_table().to_dict()))
    return tmp_path, program, shape


def test_demo_runs_the_whole_job_and_keeps_every_relation(capsys, tmp_path):
    assert main(["demo", "-o", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert 'request: "make the chair wider"' in out and "x = 1: corners of seat" in out
    assert "0 broken on purpose, 0 broken" in out
    assert {"program.json", "report.json", "record.jsonl"} <= {p.name for p in (tmp_path / "demo").iterdir()}


def test_demo_in_expert_mode_on_the_builtin_table(capsys, tmp_path):
    assert main(["demo", "--shape", "tiny_table", "--seed", "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), "
                 "amount=x)", "-o", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "relations over [0, 1]: 26 kept, 0 broken on purpose, 0 broken" in out
    assert "(-1.0000,  0.7000, -0.3000)" in out  # the top's corner 0 at x = 1: -0.5 * 2


@pytest.mark.parametrize("backend", ["sympy", "symengine"])
def test_evaluate_json_on_a_shape_file(files, capsys, backend):
    _, program, shape = files
    assert main(["evaluate", str(shape), str(program), "--set", "x=0.4", "--json", "--backend", backend]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["values"] == {"x": 0.4}
    assert np.allclose(np.array(data["parts"]["top"])[:, 0], [-0.7] * 4 + [0.7] * 4)


def test_convert_text_to_json_and_back(files, capsys):
    tmp, program, _ = files
    assert main(["convert", str(program), str(tmp / "p.json")]) == 0
    assert main(["convert", str(tmp / "p.json"), str(tmp / "p.parsel")]) == 0
    from parsel_core.program import Program

    assert (tmp / "p.parsel").read_text() == Program.from_text(PROGRAM).to_text()
    assert Program.from_json((tmp / "p.json").read_text()) == Program.from_text(PROGRAM)


def one_line_error(capsys, argv, *fragments):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("parsel: error: "), err
    for fragment in fragments:
        assert fragment in err, err


def test_bad_input_gives_one_line_and_exit_2(files, capsys):
    tmp, program, shape = files
    unknown_part = tmp / "unknown.parsel"
    unknown_part.write_text("translate(seat, dir=(1, 0, 0), amount=x)\n")
    one_line_error(capsys, ["evaluate", "tiny_table", str(unknown_part)], "no part 'seat'", "op 0")
    malformed = tmp / "bad.json"
    malformed.write_text('{"format": "parsel.program", "version": 1, "ops": [{"op": "translate"}]}')
    one_line_error(capsys, ["evaluate", "tiny_table", str(malformed)], "bad.json", "ops[0]", "operand")
    broken_text = tmp / "bad.parsel"
    broken_text.write_text("param x in [0, 1]\nscale_1d(top, dir=(1, 0, 0), amount=x\n")
    one_line_error(capsys, ["evaluate", "tiny_table", str(broken_text)], "bad.parsel:2")
    one_line_error(capsys, ["evaluate", "tiny_table", str(program), "--set", "x=0.9"],
                   "parameter 'x'", "outside its range [0, 0.5]")
    one_line_error(capsys, ["evaluate", "tiny_table", str(program), "--backend", "maple"],
                   "unknown CAS backend 'maple'")
    one_line_error(capsys, ["evaluate", "no_such_shape", str(program)], "no_such_shape")
    one_line_error(capsys, ["evaluate", "tiny_table", str(tmp / "missing.parsel")], "missing.parsel")
    one_line_error(capsys, ["evaluate", "tiny_table", str(program), "--set", "x"], "--set 'x'")
    bad_shape = tmp / "bad.shape.json"
    bad_shape.write_text('{"format": "parsel.shape", "version": 1, "parts": [{"id": "a", "corners": [[0, 0]]}]}')
    one_line_error(capsys, ["evaluate", str(bad_shape), str(program)], "bad.shape.json", "parts[0]")


def test_convert_to_unwritable_place_leaves_nothing(files, capsys):
    tmp, program, _ = files
    one_line_error(capsys, ["convert", str(program), str(tmp / "nope" / "p.json")], "does not exist")
    assert not (tmp / "nope").exists()


def test_inspect_table_json_and_png(capsys, tmp_path):
    assert main(["inspect", "tiny_table"]) == 0
    out = capsys.readouterr().out
    assert "tiny_table: 11 parts, 26 relations" in out
    assert "attach_slat_0_rail_back" in out and "attachment (line)" in out
    png = tmp_path / "table.png"
    assert main(["inspect", "tiny_table", "--json", "--png", str(png)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["format"] == "parsel.inspect" and len(data["parts"]) == 11
    assert {"id", "name", "label", "corners"} <= set(data["parts"][0])
    assert {r["kind"] for r in data["relations"]} == {"reflection", "translation", "attachment", "ground"}
    assert data["groups"][0]["id"] == "slat_row"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    one_line_error(capsys, ["inspect", "tiny_table", "--png", str(tmp_path / "missing" / "x.png")], "does not exist")


def test_edit_from_words_writes_program_report_and_record(tmp_path, capsys):
    out = tmp_path / "wider"
    assert main(["edit", "chair", "make the chair wider", "-o", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["counts"]["broken"] == 0 and report["language"]
    program = json.loads((out / "program.json").read_text())
    assert program["metadata"]["request"] == "make the chair wider"
    assert program["ops"][0]["operand"] == "seat"
    records = [json.loads(line) for line in (out / "record.jsonl").read_text().splitlines()]
    assert {r["task"] for r in records} >= {"seed_edit"} and all(r["prompt"] for r in records)


def test_edit_from_words_one_shot_skips_the_solver(tmp_path):
    out = tmp_path / "oneshot"
    assert main(["edit", "chair", "make the chair wider", "--mode", "one-shot", "-o", str(out)]) == 0
    program = json.loads((out / "program.json").read_text())
    assert program["metadata"]["solver"] == "none (one-shot)"


def test_edit_not_understood_is_exit_2_with_the_record_kept(tmp_path, capsys):
    out = tmp_path / "fly"
    assert main(["edit", "chair", "make it fly", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fly" in err and "fly.failed-record.jsonl" in err
    assert not out.exists()  # a failure writes no OUTDIR; its record lies beside it, named as such
    records = (tmp_path / "fly.failed-record.jsonl").read_text().splitlines()
    assert records and all(json.loads(line)["prompt"] for line in records)
    one_line_error(capsys, ["edit", "chair", "-o", str(tmp_path / "none")], "needs a request")


def test_proxydural_stacks_one_program_per_request_with_its_own_slider(tmp_path, capsys):
    out = tmp_path / "proxy"
    assert main(["proxydural", "chair", "-n", "3", "-o", str(out)]) == 0
    program = json.loads((out / "program.json").read_text())
    assert [p["name"] for p in program["parameters"]] == ["x1", "x2", "x3"]
    report = json.loads((out / "report.json").read_text())
    assert len(report["requests"]) == 3
    for name, counts in report["per_slider"].items():
        assert counts["broken"] == 0, name


def test_variations_write_one_program_per_variant(tmp_path):
    out = tmp_path / "family"
    assert main(["variations", "chair", "make the chair wider", "-n", "3", "-o", str(out)]) == 0
    family = json.loads((out / "variations.json").read_text())
    programs = [v["program"] for v in family["variants"] if "program" in v]
    assert len(programs) == 3
    for name in programs:
        data = json.loads((out / name).read_text())
        assert data["metadata"]["family"] == "make the chair wider"
        assert data["ops"][0]["operand"] == "seat"  # every variant keeps the primary edit


def test_renaming_a_parameter_renames_it_in_every_amount():
    from parsel_core.program import Program

    program = Program.from_text("translate(a, dir=(1, 0, 0), amount=0.5 * x)\nscale_3d(b, amount=sin(x))")
    renamed = program.renamed("x", "x1")
    assert renamed.parameter_names == ("x1",)
    assert [op.amount for op in renamed.ops] == ["0.5 * x1", "sin(x1)"]
    assert program.ops[0].amount == "0.5 * x"  # the original (and the parser's cache) untouched
    assert Program.from_text("translate(a, dir=(1, 0, 0), amount=0.5 * x)").ops[0].amount == "0.5 * x"


def test_apply_output_errors_leave_nothing_behind(files, capsys):
    tmp, program, shape = files
    (tmp / "taken.hex.json").mkdir()
    one_line_error(capsys, ["apply", str(shape), str(program), "-o", str(tmp / "taken.hex.json")], "is a directory")
    # a sweep writes all its files or none: step 2 of 3 cannot be written
    (tmp / "s_001.hex.json").mkdir()
    before = sorted(p.name for p in tmp.iterdir())
    one_line_error(capsys, ["apply", str(shape), str(program), "--sweep", "3", "-o", str(tmp / "s.hex.json")],
                   "s_001.hex.json", "is a directory")
    assert sorted(p.name for p in tmp.iterdir()) == before
    one_line_error(capsys, ["apply", str(shape), str(program), "--sweep", "0", "-o", str(tmp / "s.hex.json")],
                   "--sweep must be an integer >= 2, got '0'")
    constant = tmp / "constant.json"
    data = json.loads(Program.from_text(PROGRAM).to_json())
    data["parameters"], data["ops"][0]["amount"] = [], "0.1"
    constant.write_text(json.dumps(data))
    one_line_error(capsys, ["apply", str(shape), str(constant), "--sweep", "2", "-o", str(tmp / "c.hex.json")],
                   "constant.json", "no parameter to sweep")
    assert sorted(p.name for p in tmp.iterdir()) == sorted([*before, "constant.json"])
    # and a sweep that can be written writes every step
    assert main(["apply", str(shape), str(program), "--sweep", "3", "-o", str(tmp / "ok.hex.json")]) == 0
    written = [json.loads((tmp / f"ok_{i:03d}.hex.json").read_text()) for i in range(3)]
    assert [w["parts"]["top"][7][0] for w in written] == pytest.approx([0.5, 0.625, 0.75])  # x = 0, 0.25, 0.5


def test_outputs_in_places_that_cannot_be_written(files, capsys, tmp_path):
    _, program, shape = files
    one_line_error(capsys, ["edit", "tiny_table", "--seed", "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), "
                            "amount=x)", "-o", "/proc/parsel-out"], "/proc/parsel-out", "cannot write")
    one_line_error(capsys, ["inspect", "tiny_table", "--png", str(tmp_path / "x.xyz")], "unknown picture format")
    assert main(["inspect", "tiny_table", "--png", str(tmp_path / "x.svg")]) == 0
    assert b"<svg" in (tmp_path / "x.svg").read_bytes()[:1000]


@pytest.mark.parametrize("value", ['"abc"', "-1", "nan", "0"])
def test_a_bad_relation_tolerance_is_named(value, capsys, tmp_path, monkeypatch):
    config = tmp_path / "parsel.toml"
    config.write_text(f"[parsel]\nrelation_tolerance = {value}\n")
    monkeypatch.setenv("PARSEL_CONFIG", str(config))
    one_line_error(capsys, ["inspect", "chair"], "parsel.toml", "relation_tolerance must be a positive number")


def failing_on_call(monkeypatch, n: int) -> None:
    """Make the n-th os.replace from now fail as a full disk would."""
    import os

    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == n:
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)


def test_a_sweep_that_fails_midway_keeps_the_previous_files(files, capsys, monkeypatch):
    tmp, program, shape = files
    argv = ["apply", str(shape), str(program), "--sweep", "3", "-o", str(tmp / "out.hex.json")]
    assert main(argv) == 0
    outputs = [tmp / f"out_{i:03d}.hex.json" for i in range(3)]
    for path in outputs:
        path.write_text("previous run")
    before = sorted(p.name for p in tmp.iterdir())
    failing_on_call(monkeypatch, 7)  # 3 staged writes; set aside 0, move 0, set aside 1; moving 1 fails
    one_line_error(capsys, argv, "out_001.hex.json: cannot write: No space left on device")
    assert sorted(p.name for p in tmp.iterdir()) == before
    assert [p.read_text() for p in outputs] == ["previous run"] * 3


def test_a_failed_outdir_swap_keeps_the_previous_outdir(tmp_path, monkeypatch):
    from parsel_core.outputs import write_outdir

    target = tmp_path / "out"
    write_outdir(str(target), {"a.txt": "old"})
    failing_on_call(monkeypatch, 2)  # the previous a.txt is set aside, then the new one cannot take its place
    with pytest.raises(ParselError, match="out/a.txt: cannot write: No space left on device"):
        write_outdir(str(target), {"a.txt": "new"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (target / "a.txt").read_text() == "old"


def test_online_solver_reports_the_relations_of_its_own_solve(tmp_path):
    """The online baseline's program is only the seed; its report must count what its
    per-value solves keep, not what the seed alone keeps."""
    out = tmp_path / "online"
    seed = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=0.5*x)"
    assert main(["edit", "tiny_table", "--seed", seed, "--solver", "online", "-o", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    from parsel_core import Program
    from parsel_core.loading import load_shape
    from parsel_core.report import check_program

    seed_only = check_program(load_shape("tiny_table"), Program.from_text(seed)).counts()
    assert report["counts"]["kept"] > seed_only["kept"]
    broken = {r["id"] for r in report["relations"] if r["state"] == "broken"}
    assert broken == set(report["rejected"])
