"""Single outputs on stdout (``-o -``), ``--backend`` where programs are evaluated, ``--quiet``, ``--verbose``."""

from __future__ import annotations

import json

import pytest

from parsel_core import program as program_module
from parsel_core import progress as progress_module
from parsel_core.cli import main
from parsel_core.program import Program

from .test_cli import one_line_error

SEED = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"
RAISE = "param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=x)\n"


@pytest.fixture
def raise_top(tmp_path):
    path = tmp_path / "raise.parsel"
    path.write_text(RAISE)
    return path


@pytest.fixture
def backends_used(monkeypatch):
    """The CAS backends programs were compiled with during the test."""
    used: list[str] = []
    original = program_module.compile_program

    def spy(program, shape, backend):
        used.append(backend.name)
        return original(program, shape, backend)

    monkeypatch.setattr(program_module, "compile_program", spy)
    return used


@pytest.mark.parametrize("output", [["-o", "-"], []])
def test_edit_prints_the_program_on_stdout(tmp_path, capsys, monkeypatch, output):
    monkeypatch.chdir(tmp_path)
    assert main(["edit", "tiny_table", "--seed", SEED, *output]) == 0
    captured = capsys.readouterr()
    program = Program.from_json(captured.out)  # stdout is the program and nothing else
    assert json.loads(captured.out)["format"] == "parsel.program" and len(program.ops) >= 5
    assert "relations:" in captured.err and "-> stdout" in captured.err  # the summary is a note on stderr
    assert list(tmp_path.iterdir()) == []  # no OUTDIR, no stray file


def test_edit_to_stdout_quiet_prints_only_the_program(capsys):
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", "-", "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and Program.from_json(captured.out).ops


def test_edit_to_stdout_refuses_json_summary(capsys):
    one_line_error(capsys, ["edit", "tiny_table", "--seed", SEED, "-o", "-", "--json"], "-o - prints the program")


def test_edit_verbose_prints_solver_statistics(tmp_path, capsys):
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", str(tmp_path / "e")]) == 0
    plain = capsys.readouterr()
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", str(tmp_path / "v"), "--verbose"]) == 0
    verbose = capsys.readouterr()
    assert plain.err == "" and verbose.out.split(" -> ")[0] == plain.out.split(" -> ")[0]
    assert "parsel: timings: load" in verbose.err and "parsel: aep: candidates screened" in verbose.err
    assert "parsel: aep time:" in verbose.err


def test_edit_verbose_names_why_a_relation_was_lost(tmp_path, capsys):
    # keeping the legs fixed while the top widens loses their attachments; --verbose says why
    argv = ["edit", "tiny_table", "--seed", SEED, "--hint", "leg_fl=keep", "-o", str(tmp_path / "e"), "-v"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "broken: attach_top_leg_fl" in captured.out
    assert "parsel: lost: attach_top_leg_fl: " in captured.err


@pytest.mark.parametrize("backend", ["sympy", "symengine"])
def test_check_evaluates_with_the_backend_named(raise_top, capsys, backends_used, backend):
    assert main(["check", "tiny_table", str(raise_top), "--json"]) == 0
    reference = json.loads(capsys.readouterr().out)
    assert backends_used == []  # no --backend: the numpy reference
    assert main(["check", "tiny_table", str(raise_top), "--json", "--backend", backend]) == 0
    report = json.loads(capsys.readouterr().out)
    assert backends_used == [backend]
    assert report["counts"] == reference["counts"]
    for a, b in zip(report["relations"], reference["relations"]):
        assert a["id"] == b["id"] and a["max_error"] == pytest.approx(b["max_error"], abs=1e-9)


def test_check_verbose_says_how_it_evaluated(raise_top, capsys):
    assert main(["check", "tiny_table", str(raise_top), "--backend", "sympy", "--verbose"]) == 0
    assert "evaluated 1 ops at 50 parameter values with sympy" in capsys.readouterr().err


@pytest.mark.parametrize("verb", ["check", "apply"])
def test_an_unknown_backend_is_a_one_line_error(raise_top, capsys, tmp_path, verb):
    argv = [verb, "tiny_table", str(raise_top), "--backend", "nope"]
    argv += ["-o", str(tmp_path / "t.obj")] if verb == "apply" else []
    one_line_error(capsys, argv, "unknown CAS backend 'nope'")
    assert not (tmp_path / "t.obj").exists()


def test_apply_with_a_backend_writes_the_same_file(raise_top, tmp_path, capsys, backends_used):
    for name, extra in (("numpy.obj", []), ("sympy.obj", ["--backend", "sympy"])):
        assert main(["apply", "tiny_table", str(raise_top), "--set", "x=0.4", "-o", str(tmp_path / name),
                     *extra]) == 0
    assert backends_used == ["sympy"]
    assert (tmp_path / "numpy.obj").read_text() == (tmp_path / "sympy.obj").read_text()


def test_apply_to_stdout_needs_a_format(raise_top, tmp_path, capsys):
    assert main(["apply", "tiny_table", str(raise_top), "--set", "x=0.4", "-o", str(tmp_path / "t.obj")]) == 0
    capsys.readouterr()
    assert main(["apply", "tiny_table", str(raise_top), "--set", "x=0.4", "-o", "-", "--format", "obj"]) == 0
    assert capsys.readouterr().out == (tmp_path / "t.obj").read_text()
    one_line_error(capsys, ["apply", "tiny_table", str(raise_top), "-o", "-"], "-o -: name the format with --format")
    one_line_error(capsys, ["apply", "tiny_table", str(raise_top), "-o", "-", "--format", "bmp"],
                   "--format 'bmp': unknown format")
    one_line_error(capsys, ["apply", "tiny_table", str(raise_top), "-o", "-", "--format", "obj", "--sweep", "3"],
                   "-o - writes one file to stdout")


def test_quiet_turns_progress_off_and_verbose_adds_timings(raise_top, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(progress_module, "DELAY", 0.0)  # progress from the first file
    argv = ["apply", "tiny_table", str(raise_top), "--sweep", "3"]
    assert main([*argv, "-o", str(tmp_path / "a.obj")]) == 0
    assert capsys.readouterr().err == "files: 1/3\nfiles: 2/3\nfiles: 3/3\n"
    assert main([*argv, "-o", str(tmp_path / "b.obj"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main([*argv, "-o", str(tmp_path / "c.obj"), "--verbose"]) == 0
    err = capsys.readouterr().err
    assert "files: 3/3" in err and "parsel: exporter hexahedra-obj" in err and err.count(" s\n") >= 3


def test_quiet_and_verbose_exclude_each_other(raise_top, capsys):
    with pytest.raises(SystemExit) as done:
        main(["check", "tiny_table", str(raise_top), "--quiet", "--verbose"])
    assert done.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_command_run_by_another_logs_each_line_once(capsys):
    """``parsel demo`` runs edit, view and render through main(): their notes are not doubled."""
    from parsel_core.verbosity import NORMAL, VERBOSE, logger, verbosity

    with verbosity(NORMAL), verbosity(VERBOSE):
        logger.debug("inner")
    with verbosity(NORMAL):
        logger.info("outer")
        logger.debug("hidden")
    assert capsys.readouterr().err == "parsel: inner\nparsel: outer\n"
