"""Progress on stderr: a bar on terminals, whole lines (no carriage returns) anywhere else, nothing when quiet."""

from __future__ import annotations

import io

import pytest

from parsel_core import progress as progress_module
from parsel_core.cli import main
from parsel_core.plugins import llm_providers
from parsel_core.progress import LineProgress, NoProgress, progress


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
