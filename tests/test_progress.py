"""Progress on stderr: a bar on terminals, whole lines (no carriage returns) anywhere else, nothing when quiet."""

from __future__ import annotations

import io

import pytest

from parsel_core import progress as progress_module
from parsel_core.cli import main
from parsel_core.plugins import llm_providers
from parsel_core.progress import LineProgress, NoProgress, progress, working


@pytest.fixture
def at_once(monkeypatch):
    """Progress from the first update (it normally waits 2 s, so quick runs print nothing)."""
    monkeypatch.setattr(progress_module, "DELAY", 0.0)


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_on_a_non_tty_about_every_tenth(at_once):
    stream = io.StringIO()
    bar = progress(25, "cases", stream=stream)
    assert isinstance(bar, LineProgress)
    for i in range(25):
        if i == 24:
            bar.set_postfix_str("failed 1")
        bar.update(1)
    bar.close()
    text = stream.getvalue()
    assert "\r" not in text
    assert text.splitlines() == [f"cases: {n}/25" for n in range(2, 25, 2)] + ["cases: 25/25 (failed 1)"]


def test_a_bar_on_a_terminal_and_nothing_when_quiet(at_once):
    terminal = Terminal()
    bar = progress(3, "frames", stream=terminal)
    bar.update(3)
    bar.close()
    assert "\r" in terminal.getvalue() and "frames" in terminal.getvalue()  # tqdm redraws in place
    quiet = io.StringIO()
    assert isinstance(progress(3, "frames", enabled=False, stream=quiet), NoProgress)
    assert isinstance(progress(0, "frames", stream=quiet), NoProgress) and quiet.getvalue() == ""


@pytest.mark.skipif("offline" not in llm_providers(), reason="needs the offline provider (parsel-offline)")
def test_proxydural_reports_progress_in_lines_off_a_terminal(tmp_path, capsys, at_once):
    assert main(["proxydural", "tiny_table", "-n", "2", "-o", str(tmp_path / "p")]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and err.splitlines()[-1].startswith("requests: ") and err.splitlines()[-1].endswith("/2")
    assert main(["proxydural", "tiny_table", "-n", "2", "-o", str(tmp_path / "q"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_batch_uses_the_same_display(at_once):
    batch = pytest.importorskip("parsel_batch.batch")
    stream = io.StringIO()
    bar = batch.progress_bar(2, True, stream)
    bar.update(1)
    bar.update(1)
    assert isinstance(bar, LineProgress) and stream.getvalue() == "cases: 1/2\ncases: 2/2\n"


def test_apply_sweep_reports_each_file(tmp_path, capsys, at_once):
    program = tmp_path / "p.parsel"
    program.write_text("param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=x)\n")
    assert main(["apply", "tiny_table", str(program), "--sweep", "3", "-o", str(tmp_path / "t.obj")]) == 0
    assert capsys.readouterr().err == "files: 1/3\nfiles: 2/3\nfiles: 3/3\n"


def test_quick_work_prints_nothing():
    stream = io.StringIO()
    bar = progress(3, "files", stream=stream)  # the default 2 s delay
    for _ in range(3):
        bar.update(1)
    bar.close()
    assert stream.getvalue() == ""


def _until(condition, seconds: float = 10.0) -> None:
    import time

    end = time.monotonic() + seconds
    while not condition() and time.monotonic() < end:
        time.sleep(0.01)


def test_work_with_nothing_to_count_says_it_is_working_in_lines(at_once):
    stream = io.StringIO()
    with working("edit", stream=stream, every=0.05):
        _until(lambda: stream.getvalue().count("\n") >= 3)  # the work runs while lines come
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue() and len(lines) >= 4
    assert all(line.startswith("edit: working (") and line.endswith(" s)") for line in lines[:-1])
    assert lines[-1].startswith("edit: done in ")
    failed = io.StringIO()
    with pytest.raises(KeyError), working("edit", stream=failed):
        _until(lambda: failed.getvalue())
        raise KeyError("x")
    assert "done" not in failed.getvalue()  # a failure is not reported as done


def test_working_on_a_terminal_is_one_cleared_line_and_nothing_when_quiet_or_quick(at_once, monkeypatch):
    terminal = Terminal()
    with working("check", stream=terminal):
        _until(lambda: "check: working" in terminal.getvalue())
    assert "check: working" in terminal.getvalue() and "\r" in terminal.getvalue()
    quiet = io.StringIO()
    with working("check", stream=quiet, enabled=False):
        pass
    monkeypatch.setattr(progress_module, "DELAY", 2.0)
    quick = io.StringIO()
    with working("check", stream=quick):
        pass
    assert quiet.getvalue() == quick.getvalue() == ""


def test_edit_says_it_is_working_in_lines_off_a_terminal(tmp_path, capsys, at_once):
    """``parsel edit`` (one solve: seconds to minutes on big shapes) on a non-tty stderr."""
    seed = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"
    assert main(["edit", "tiny_table", "--seed", seed, "-o", str(tmp_path / "e")]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and err.startswith("edit: working (") and "edit: done in " in err
    assert main(["edit", "tiny_table", "--seed", seed, "-o", str(tmp_path / "q"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_check_evaluate_inspect_and_apply_say_they_are_working(tmp_path, capsys, at_once):
    program = tmp_path / "p.parsel"
    program.write_text("param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=x)\n")
    for argv in (["check", "tiny_table", str(program)], ["evaluate", "tiny_table", str(program)],
                 ["inspect", "tiny_table"], ["apply", "tiny_table", str(program), "-o", str(tmp_path / "t.obj")]):
        assert main(argv) == 0
        err = capsys.readouterr().err
        assert "\r" not in err and f"{argv[0]}: working (" in err and f"{argv[0]}: done in " in err, (argv, err)
        assert main([*argv, "--quiet"]) == 0
        assert capsys.readouterr().err == "", argv


def test_fit_counts_its_searches_in_lines_off_a_terminal(tmp_path, capsys, at_once):
    pytest.importorskip("parsel_fit")
    import numpy as np

    from parsel_core.examples import tiny_table
    from parsel_core.program import Program, evaluate
    from parsel_fit.surface import SurfaceSampler

    program = Program.from_text("param x in [0, 1]\nscale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n")
    shape = tiny_table()
    points = SurfaceSampler.of(shape, 1024, 5).points(shape, evaluate(program, shape, {"x": 0.3}))
    np.savetxt(tmp_path / "target.xyz", points)
    (tmp_path / "p.parsel").write_text(program.to_text())
    assert main(["fit", "tiny_table", str(tmp_path / "p.parsel"), str(tmp_path / "target.xyz"), "--starts", "3",
                 "--points", "256", "-o", str(tmp_path / "fitted.json")]) == 0
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert "\r" not in err and lines and all(line.startswith("fit searches: ") for line in lines)
    assert lines[-1].split(" (")[0] == "fit searches: 5/5"  # 3 starts, 2 polished


def test_render_remesh_and_eval_count_in_lines_off_a_terminal(tmp_path, capsys, at_once):
    """Two of the commands the issue saw silent: ``render --remesh`` (seconds per frame) and ``eval``."""
    import json

    program = tmp_path / "p.parsel"
    program.write_text("param x in [0, 1]\ntranslate(top, dir=(0, 1, 0), amount=0.2 * x)\n")
    from importlib.util import find_spec

    if find_spec("parsel_view") and find_spec("parsel_remesh"):
        assert main(["render", "tiny_table", str(program), "-o", str(tmp_path / "s.png"), "--frames", "2",
                     "--remesh", "--resolution", "24"]) == 0
        err = capsys.readouterr().err
        assert "\r" not in err and err.splitlines() == ["frames: 1/2", "frames: 2/2"]
    pytest.importorskip("parsel_batch")
    cases = tmp_path / "cases.jsonl"
    cases.write_text(json.dumps({"id": "c", "shape": "tiny_table",
                                 "seed": "translate(top, dir=(0, 1, 0), amount=x)"}) + "\n")
    assert main(["eval", str(cases)]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err and err.splitlines() == ["cases: 1/1"]
