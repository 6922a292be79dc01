"""Exit statuses, numeric option checks and --json output of the core verbs."""

from __future__ import annotations

import json

import pytest

from parsel_core.cli import main
from parsel_core.examples import tiny_table
from parsel_core.plugins import llm_providers
from parsel_core.program import Program

from .test_cli import PROGRAM, one_line_error

#: A seed that widens the table top.
TOP_ONLY = "param x in [0, 0.5]\nscale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n"


@pytest.fixture
def files(tmp_path):
    program = tmp_path / "widen.parsel"
    program.write_text(PROGRAM)
    shape = tmp_path / "table.shape.json"
    shape.write_text(json.dumps(tiny_table().to_dict()))
    return tmp_path, program, shape


def test_check_strict_fails_on_broken_relations_only(files, capsys, tmp_path):
    _, program, shape = files  # the top widens alone: the legs and rails no longer meet it
    assert main(["check", str(shape), str(program)]) == 0  # without --strict: a report, status 0
    out = capsys.readouterr().out
    broken = int(out.split(" broken on purpose, ")[1].split(" broken")[0])
    assert broken > 0
    assert main(["check", str(shape), str(program), "--strict"]) == 1
    capsys.readouterr()
    assert main(["check", str(shape), str(program), "--strict", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["counts"]["broken"] == broken
    # the same seed propagated by AEP keeps everything, and passes --strict
    assert main(["edit", str(shape), "--seed", TOP_ONLY.splitlines()[1], "-o", str(tmp_path / "kept")]) == 0
    assert main(["check", str(shape), str(tmp_path / "kept" / "program.json"), "--strict"]) == 0


@pytest.mark.parametrize("argv, message", [
    (["check", "tiny_table", "PROGRAM", "--steps", "0"], "--steps must be an integer from 2 to 100000, got '0'"),
    (["check", "tiny_table", "PROGRAM", "--steps", "-3"], "--steps must be an integer from 2 to 100000, got '-3'"),
    (["check", "tiny_table", "PROGRAM", "--steps", "many"], "--steps must be an integer from 2 to 100000"),
    (["check", "tiny_table", "PROGRAM", "--samples", "1"], "--samples must be an integer from 2 to 100000"),
    (["check", "tiny_table", "PROGRAM", "--samples", "0"], "--samples must be an integer from 2 to 100000, got '0'"),
    (["edit", "tiny_table", "wider", "--samples", "0", "-o", "OUT"], "--samples must be an integer from 1 to 100"),
    (["proxydural", "tiny_table", "-n", "0", "-o", "OUT"], "-n must be an integer from 1 to 20, got '0'"),
    (["proxydural", "tiny_table", "-n", "99", "-o", "OUT"], "-n must be an integer from 1 to 20, got '99'"),
    (["variations", "tiny_table", "wider", "-n", "0", "-o", "OUT"], "-n must be an integer from 1 to 20, got '0'"),
])
def test_numeric_options_are_checked_in_one_line(files, capsys, tmp_path, argv, message):
    _, program, _ = files
    argv = [str(program) if a == "PROGRAM" else str(tmp_path / "out") if a == "OUT" else a for a in argv]
    one_line_error(capsys, argv, message)
    assert not (tmp_path / "out").exists()


def test_edit_and_apply_json(files, capsys, tmp_path):
    _, program, shape = files
    assert main(["edit", str(shape), "--seed", TOP_ONLY.splitlines()[1], "-o", str(tmp_path / "e"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["output"] == str(tmp_path / "e") and summary["files"] == ["program.json", "report.json"]
    assert summary["relations"]["broken"] == 0 and summary["ops"] >= 5  # the legs and rails follow the top
    assert summary["parameters"][0]["name"] == "x" and set(summary["timings"]) == {"load_s", "solve_s", "check_s"}
    assert main(["apply", str(shape), str(program), "--set", "x=0.3", "-o", str(tmp_path / "t.obj"), "--json"]) == 0
    written = json.loads(capsys.readouterr().out)
    assert written == {"written": [str(tmp_path / "t.obj")], "values": {"x": 0.3}}
    assert (tmp_path / "t.obj").stat().st_size > 0


@pytest.mark.skipif("offline" not in llm_providers(), reason="needs the offline provider (parsel-offline)")
def test_proxydural_json(capsys, tmp_path):
    assert main(["proxydural", "tiny_table", "-n", "2", "-o", str(tmp_path / "p"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [s["parameter"] for s in summary["sliders"]] == ["x1", "x2"][: len(summary["sliders"])]
    assert set(summary["per_slider"]) == {s["parameter"] for s in summary["sliders"]}


@pytest.mark.skipif("offline" not in llm_providers(), reason="needs the offline provider (parsel-offline)")
def test_removing_a_slat_leaks_no_numpy_warning(tmp_path):
    """The removed slat's corners are NaN; its Jacobians are NaN too, quietly."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-m", "parsel_core.cli", "edit", "chair",
                           "remove a slat", "-o", str(tmp_path / "out")], capture_output=True, text=True,
                          cwd=tmp_path, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "Warning" not in done.stderr and "warning" not in done.stderr


def test_corner_jacobians_of_nan_corners_are_nan_without_a_warning():
    import warnings

    import numpy as np

    from parsel_core.hexahedron import corner_jacobians

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(corner_jacobians(np.full((8, 3), np.nan))).all()


def _json_invocations(tmp_path, program, shape):
    """verb -> (argv, a check of the parsed document) for every verb that lists --json."""
    out = str(tmp_path)
    cases = tmp_path / "cases.jsonl"
    cases.write_text(json.dumps({"id": "c", "shape": "tiny_table", "seed": TOP_ONLY.splitlines()[1]}) + "\n")
    target = tmp_path / "target.shape.json"
    target.write_text(shape.read_text())
    seed = TOP_ONLY.splitlines()[1]
    return {
        "plugins": (["plugins", "--json"], lambda d: "plugins" in d),
        "evaluate": (["evaluate", "tiny_table", str(program), "--json"], lambda d: d["values"] == {"x": 0.2}),
        "edit": (["edit", "tiny_table", "--seed", seed, "-o", f"{out}/e", "--json"], lambda d: d["ops"] >= 5),
        "proxydural": (["proxydural", "tiny_table", "-n", "1", "-o", f"{out}/p", "--json"], lambda d: d["sliders"]),
        "variations": (["variations", "tiny_table", "make the table wider", "-n", "2", "-o", f"{out}/v", "--json"],
                       lambda d: d["output"] == f"{out}/v" and len(d["variants"]) == 2),
        "check": (["check", "tiny_table", str(program), "--json"], lambda d: d["counts"]["broken"] > 0),
        "apply": (["apply", "tiny_table", str(program), "-o", f"{out}/a.obj", "--json"],
                  lambda d: d["written"] == [f"{out}/a.obj"]),
        "inspect": (["inspect", "tiny_table", "--json"], lambda d: d["format"] == "parsel.inspect"),
        "new-plugin": (["new-plugin", "bend", "-o", f"{out}/parsel-bend", "--json"],
                       lambda d: any(p.endswith("pyproject.toml") for p in d["written"])),
        "view": (["view", str(program), "--shape", "tiny_table", "-o", f"{out}/page.html", "--json"],
                 lambda d: d["written"] == [f"{out}/page.html"] and d["parameters"] == ["x"]),
        "render": (["render", "tiny_table", str(program), "-o", f"{out}/strip.png", "--frames", "2", "--json"],
                   lambda d: d["written"] == [f"{out}/strip.png"] and d["parameter"] == "x" and d["frames"] == 2),
        "fit": (["fit", "tiny_table", str(program), str(target), "-o", f"{out}/fitted.json", "--starts", "1",
                 "--points", "64", "--json"],
                lambda d: d["output"] == f"{out}/fitted.json" and set(d["values"]) == {"x"}
                and d["distance_after"] <= d["distance_before"]),
        "eval": (["eval", str(cases), "--json"], lambda d: d["format"] == "parsel.eval"),
        "batch": (["batch", str(cases), "-o", f"{out}/b", "--workers", "0", "--json"], lambda d: d["cases"] == 1),
    }


def test_every_verb_with_json_prints_one_document(files, capsys, tmp_path):
    """Each verb that lists --json prints a JSON document a program can read (and nothing else on stdout)."""
    from .test_cli_help import verbs

    _, program, shape = files
    invocations = _json_invocations(tmp_path, program, shape)
    listing = {name for name, parser in verbs().items()
               if any("--json" in action.option_strings for action in parser._actions)}
    assert listing <= set(invocations), f"verbs with --json but no test: {sorted(listing - set(invocations))}"
    assert {"edit", "apply", "batch", "proxydural", "variations", "check", "fit"} & set(verbs()) <= listing
    for verb in sorted(listing):
        argv, check = invocations[verb]
        if verb in ("proxydural", "variations") and "offline" not in llm_providers():
            continue
        assert main(argv) in (0, 1), verb  # check: 1 for nothing; only --strict fails
        data = json.loads(capsys.readouterr().out)
        assert check(data), (verb, data)


def test_convert_writes_to_o_or_to_stdout_in_the_other_form(files, capsys, tmp_path):
    _, program, _ = files
    assert main(["convert", str(program), "-o", str(tmp_path / "p.json")]) == 0
    assert main(["convert", str(program)]) == 0  # no -o: stdout, the other form (text in, JSON out)
    assert capsys.readouterr().out == (tmp_path / "p.json").read_text()
    assert main(["convert", str(tmp_path / "p.json"), "-o", "-"]) == 0  # JSON in, text out
    assert capsys.readouterr().out == Program.from_text(PROGRAM).to_text()
    assert main(["convert", str(program), "--format", "text"]) == 0
    assert capsys.readouterr().out.startswith("# parsel program\n")
    assert main(["convert", str(program), str(tmp_path / "old.json")]) == 0  # the old positional still works
    assert (tmp_path / "old.json").read_text() == (tmp_path / "p.json").read_text()
    one_line_error(capsys, ["convert", str(program), "-o", str(tmp_path / "x.parsel"), "--format", "json"],
                   "--format is for -o -")
    one_line_error(capsys, ["convert", str(program), str(tmp_path / "a.json"), "-o", str(tmp_path / "b.json")],
                   "not both")


def test_apply_without_o_writes_stdout_with_a_format(files, capsys, tmp_path):
    _, program, _ = files
    assert main(["apply", "tiny_table", str(program), "-o", str(tmp_path / "t.obj")]) == 0
    capsys.readouterr()
    assert main(["apply", "tiny_table", str(program), "--format", "obj"]) == 0
    assert capsys.readouterr().out == (tmp_path / "t.obj").read_text()
    one_line_error(capsys, ["apply", "tiny_table", str(program)], "no -o FILE: name an output file, or the format")


def test_name_value_options_are_typed_as_json_scalars_else_kept_as_text():
    from parsel_core.errors import ParselError
    from parsel_core.loading import parse_options

    items = ["joint=0", "tau=0.5", "nhbd=false", "tau_max=null", "backend=sympy", 'name="a b"', "list=[1, 2]"]
    assert parse_options(items, "--option") == {"joint": 0, "tau": 0.5, "nhbd": False, "tau_max": None,
                                                "backend": "sympy", "name": "a b", "list": "[1, 2]"}
    for bad in ("joint", "=1", "joint="):
        with pytest.raises(ParselError, match=f"--option '{bad}': expected NAME=VALUE"):
            parse_options([bad], "--option")
