"""Output folders: parsel never deletes or replaces a file it did not write."""

from __future__ import annotations

import json
import os
import stat

import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.outputs import MANIFEST, write_outdir

SEED = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"


def _user_folder(path):
    path.mkdir()
    (path / "thesis.txt").write_text("years of work")
    (path / "photos").mkdir()
    (path / "photos" / "a.jpg").write_bytes(b"\xff\xd8")
    return sorted(p.name for p in path.rglob("*"))


def test_edit_onto_a_folder_of_other_files_is_refused_and_leaves_them(tmp_path, capsys):
    docs = tmp_path / "mydocs"
    before = _user_folder(docs)
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", str(docs)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mydocs" in err and "--force" in err
    assert sorted(p.name for p in docs.rglob("*")) == before
    assert (docs / "thesis.txt").read_text() == "years of work"


def test_force_writes_beside_other_files_and_replaces_only_its_own(tmp_path, capsys):
    docs = tmp_path / "mydocs"
    before = _user_folder(docs)
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", str(docs), "--force"]) == 0
    after = sorted(p.name for p in docs.rglob("*"))
    assert sorted(set(after) - set(before)) == sorted([MANIFEST, "program.json", "report.json"])
    assert (docs / "thesis.txt").read_text() == "years of work"
    # Once parsel's manifest is there, the folder is a parsel output: no --force needed to rewrite it.
    assert main(["edit", "tiny_table", "--seed", SEED.replace("amount=x", "amount=0.5*x"), "-o", str(docs)]) == 0
    assert "0.5*x" in (docs / "program.json").read_text()
    assert sorted(p.name for p in docs.rglob("*")) == after


@pytest.mark.parametrize("outdir", ["", ".", "  "])
def test_the_working_directory_is_refused(outdir, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["edit", "tiny_table", "--seed", SEED, "-o", outdir]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_a_parent_of_the_working_directory_is_refused(tmp_path, monkeypatch):
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    with pytest.raises(ParselError, match="working directory"):
        write_outdir("..", {"a.txt": "x"})


def test_a_failed_edit_keeps_the_earlier_results_and_writes_its_record_beside(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["edit", "chair", "make the chair wider", "-o", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["edit", "chair", "make it fly", "-o", str(out)]) == 2
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert (tmp_path / "out.failed-record.jsonl").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "out.failed-record.jsonl"]


def test_files_an_earlier_run_wrote_and_this_one_does_not_are_removed_others_stay(tmp_path):
    out = tmp_path / "out"
    write_outdir(str(out), {"a.txt": "1", "b.txt": "1"})
    (out / "notes.txt").write_text("mine")
    write_outdir(str(out), {"a.txt": "2"})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "a.txt", "notes.txt"]
    assert json.loads((out / MANIFEST).read_text())["files"] == ["a.txt"]


def test_a_new_outdir_gets_the_usual_permissions_and_no_staging_is_left(tmp_path):
    mask = os.umask(0o022)
    try:
        write_outdir(str(tmp_path / "out"), {"a.txt": "1"})
    finally:
        os.umask(mask)
    assert stat.S_IMODE((tmp_path / "out").stat().st_mode) == 0o755
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_staging_left_by_a_killed_run_is_removed_by_the_next(tmp_path):
    out = tmp_path / "out"
    dead = 2**22 + 12345  # above the default pid_max: no such process
    (tmp_path / f".out.parsel-{dead}-abc").mkdir()
    (tmp_path / ".out.parsel-notapid").mkdir()  # not a staging name: left alone
    write_outdir(str(out), {"a.txt": "1"})
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.parsel-notapid", "out"]
    (out / f".parsel-staging-{dead}-abc").mkdir()
    write_outdir(str(out), {"a.txt": "2"})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "a.txt"]


def test_a_failed_write_into_a_parsel_outdir_puts_every_file_back(tmp_path, monkeypatch):
    out = tmp_path / "out"
    write_outdir(str(out), {"a.txt": "old a", "b.txt": "old b"})
    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == 3:  # a set aside, a moved, b set aside; then the disk is full
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(ParselError, match="b.txt: cannot write: No space left on device"):
        write_outdir(str(out), {"a.txt": "new a", "b.txt": "new b"})
    monkeypatch.undo()
    assert {p.name: p.read_text() for p in out.iterdir() if p.name != MANIFEST} == {"a.txt": "old a",
                                                                                    "b.txt": "old b"}
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "a.txt", "b.txt"]
