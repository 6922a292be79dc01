"""``parsel batch`` and ``parsel eval``: local processes vs Dask, kill and resume, output repair."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from parsel_batch.batch import RESULTS, OutputDir, read_results
from parsel_batch.cases import read_cases
from parsel_batch.runner import deterministic
from parsel_core.cli import main
from parsel_core.program import Program

TOP = "origin=(0, 0.725, 0)"
SEEDS = [
    f"scale_1d(top, {TOP}, dir=(1, 0, 0), amount=x)",
    "translate(top, dir=(0, 1, 0), amount=x)",
    "translate(top, dir=(0, 1, 0), amount=0.2*x)",
    "scale_1d(leg_bl, origin=(-0.45, 0, -0.25), dir=(0, 1, 0), amount=x)",
    "translate(top, dir=(0, 1, 0), amount=0.5*x)",
    "scale_1d(leg_fr, origin=(0.45, 0, 0.25), dir=(0, 1, 0), amount=0.5*x)",
    "translate(top, dir=(0, 1, 0), amount=0.3*x)",
    "scale_1d(leg_br, origin=(0.45, 0, -0.25), dir=(0, 1, 0), amount=0.25*x)",
    "translate(top, dir=(0, 1, 0), amount=0.7*x)",
    "scale_1d(leg_fl, origin=(-0.45, 0, 0.25), dir=(0, 1, 0), amount=0.75*x)",
]


def cases_file(tmp_path, seeds, extra=()):
    ground_truth = tmp_path / "raise.parsel"
    ground_truth.write_text("translate(top, dir=(0, 1, 0), amount=x)\n")
    lines = [{"id": f"case-{i:02d}", "shape": "tiny_table", "seed": seed} for i, seed in enumerate(seeds)]
    if len(lines) > 1:
        lines[1]["ground_truth"] = "raise.parsel"
    lines += list(extra)
    path = tmp_path / "cases.jsonl"
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def outputs(outdir: Path) -> dict[str, dict[str, str]]:
    """Every case folder's files (all deterministic)."""
    return {d.name: {f.name: f.read_text() for f in sorted(d.iterdir())}
            for d in sorted(outdir.iterdir()) if d.is_dir()}


def results_by_id(outdir: Path) -> dict[str, dict]:
    records = read_results(outdir)
    ids = [r["id"] for r in records]
    assert len(ids) == len(set(ids)), "a case is in results.jsonl twice"
    return {r["id"]: deterministic(r) for r in records}


def test_batch_on_a_dask_cluster_matches_local_processes(tmp_path):
    distributed = pytest.importorskip("distributed")
    failing = {"id": "broken-case", "shape": "tiny_table", "seed": "translate(nope, amount=x)"}
    path = cases_file(tmp_path, SEEDS[:4], [failing])
    local, remote = tmp_path / "local", tmp_path / "dask"
    assert main(["batch", str(path), "-o", str(local), "--workers", "2", "--no-progress"]) == 1  # one case fails
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        assert main(["batch", str(path), "-o", str(remote), "--dask", cluster.scheduler_address,
                     "--no-progress"]) == 1
    assert outputs(local) == outputs(remote)
    assert results_by_id(local) == results_by_id(remote)
    records = results_by_id(local)
    assert len(records) == 5 and records["broken-case"]["status"] == "failed"
    assert records["case-01"]["metrics"]["J_prog"] == pytest.approx(1 / 8)
    for case_id in ("case-00", "case-01", "case-02", "case-03"):
        Program.from_json((local / case_id / "program.json").read_text())
    assert (local / "broken-case" / "error.txt").read_text().startswith("Traceback")


def test_killed_run_resumes_and_finishes_every_case_exactly_once(tmp_path):
    path = cases_file(tmp_path, SEEDS)
    outdir = tmp_path / "out"
    command = [sys.executable, "-m", "parsel_core.cli", "batch", str(path), "-o", str(outdir), "--workers", "1",
               "--no-progress"]
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    results = outdir / RESULTS
    deadline = time.monotonic() + 240
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if results.exists() and results.read_text().count("\n") >= 3:
                break
            time.sleep(0.02)
        assert process.poll() is None, "the batch ended before it could be killed: " + process.stderr.read().decode()
        os.killpg(process.pid, signal.SIGKILL)  # the run and its worker process, mid-case
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        process.stderr.close()
    finished = {d.name for d in outdir.iterdir() if (d / "result.json").is_file()}
    assert 3 <= len(finished) < len(SEEDS)
    logged = [json.loads(line)["id"] for line in results.read_text().splitlines() if line.strip()]
    assert set(logged) <= finished

    resumed = subprocess.run(command, capture_output=True, text=True, timeout=240)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(SEEDS) - len(finished)} run" in resumed.stdout
    assert f"{len(finished)} already done" in resumed.stdout
    records = results_by_id(outdir)  # asserts each case is logged once
    assert sorted(records) == [f"case-{i:02d}" for i in range(len(SEEDS))]
    assert all(r["status"] == "ok" for r in records.values())
    for case_id in records:
        Program.from_json((outdir / case_id / "program.json").read_text())
        json.loads((outdir / case_id / "report.json").read_text())
    assert not [p for p in outdir.iterdir() if p.name.startswith(".")]  # no staging folder left behind


CRASHING_RUNNER = """
import os

from parsel_batch.runner import run_case


def run(case, defaults):
    if case.id == "case-01":
        os._exit(3)  # the worker process dies, as in a crash in native code or an OOM kill
    return run_case(case, defaults)
"""


def test_a_dying_worker_fails_its_own_case_only(tmp_path, monkeypatch):
    (tmp_path / "crashing_runner.py").write_text(CRASHING_RUNNER)
    monkeypatch.syspath_prepend(str(tmp_path))  # spawned workers get the parent's sys.path
    import crashing_runner

    import parsel_batch.batch as batch

    monkeypatch.setattr(batch, "run_case", crashing_runner.run)
    path = cases_file(tmp_path, SEEDS[:4])
    summary = batch.run_batch(read_cases(path), tmp_path / "out", workers=2, progress=False)
    records = {r["id"]: r for r in summary.records}
    assert sorted(records) == ["case-00", "case-01", "case-02", "case-03"]
    assert [i for i, r in records.items() if r["status"] != "ok"] == ["case-01"]
    assert "died" in records["case-01"]["error"]["where"]


def test_reopening_repairs_results_jsonl(tmp_path):
    path = cases_file(tmp_path, SEEDS[:3])
    cases = read_cases(path)
    outdir = tmp_path / "out"
    assert main(["batch", str(path), "-o", str(outdir), "--workers", "0", "--no-progress"]) == 0
    lines = (outdir / RESULTS).read_text().splitlines(keepends=True)
    # a case from another cases file, a record logged twice, a kill between a folder's
    # rename and its append (case-02), and an append cut off mid-line (case-01)
    other = json.dumps({"id": "other", "status": "ok"}) + "\n"
    (outdir / RESULTS).write_text(other + lines[0] + lines[0] + lines[1][:40])
    (outdir / ".staging-case-02-abc").mkdir()
    reopened = OutputDir.open(outdir, cases)
    assert sorted(reopened.done) == ["case-00", "case-01", "case-02"]
    assert sorted(results_by_id(outdir)) == ["case-00", "case-01", "case-02", "other"]
    assert not (outdir / ".staging-case-02-abc").exists()
    # a folder without its result.json (never renamed into place) is not done
    (outdir / "case-02" / "result.json").unlink()
    assert sorted(OutputDir.open(outdir, cases).done) == ["case-00", "case-01"]
    assert sorted(results_by_id(outdir)) == ["case-00", "case-01", "other"]


def test_failed_cases_are_skipped_on_resume_unless_retried(tmp_path, capsys):
    bad = {"id": "bad", "shape": "tiny_table", "seed": "translate(nope, amount=x)"}
    path = cases_file(tmp_path, SEEDS[:1], [bad])
    outdir = tmp_path / "out"
    assert main(["batch", str(path), "-o", str(outdir), "--workers", "0", "--no-progress"]) == 1
    assert "failed: bad: UnknownPartError" in capsys.readouterr().out
    assert main(["batch", str(path), "-o", str(outdir), "--workers", "0", "--no-progress"]) == 1
    assert "0 run" in capsys.readouterr().out
    assert main(["batch", str(path), "-o", str(outdir), "--workers", "0", "--no-progress", "--retry-failed"]) == 1
    assert "1 run" in capsys.readouterr().out
    assert len(read_results(outdir)) == 2


def test_eval_prints_a_table_and_a_summary(tmp_path, capsys):
    bad = {"id": "bad", "shape": "tiny_table", "seed": "translate(nope, amount=x)"}
    path = cases_file(tmp_path, SEEDS[:2], [bad])
    assert main(["eval", str(path)]) == 1
    out = capsys.readouterr().out
    assert "J(prog)" in out and "D(geo)" in out and "%Rel" in out
    assert "UnknownPartError" in out
    assert "3 cases: 2 ok, 1 failed" in out
    assert main(["eval", str(path), "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert data["format"] == "parsel.eval"
    assert [c["id"] for c in data["cases"]] == ["case-00", "case-01", "bad"]
    assert data["summary"]["metrics"]["J_prog"] == {"mean": pytest.approx(1 / 8), "cases": 1}
    # scoring a batch's records without running again
    outdir = tmp_path / "out"
    main(["batch", str(path), "-o", str(outdir), "--workers", "0", "--no-progress"])
    capsys.readouterr()
    assert main(["eval", str(path), "--results", str(outdir), "--json"]) == 1
    again = json.loads(capsys.readouterr().out)
    assert [deterministic(c) for c in again["cases"]] == [deterministic(c) for c in data["cases"]]


def test_bad_cases_file_is_exit_status_2(tmp_path, capsys):
    path = tmp_path / "cases.jsonl"
    path.write_text('{"shape": "tiny_table"}\n')
    assert main(["batch", str(path), "-o", str(tmp_path / "out")]) == 2
    assert "cases.jsonl:1" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_batch_json_summary(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("parsel_core.progress.DELAY", 0.0)  # progress from the first case
    bad = {"id": "bad", "shape": "tiny_table", "seed": "translate(nope, amount=x)"}
    path = cases_file(tmp_path, SEEDS[:1], [bad])
    assert main(["batch", str(path), "-o", str(tmp_path / "out"), "--workers", "0", "--json"]) == 1
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert (data["cases"], data["ran"], data["failed"], data["skipped"]) == (2, 2, 1, 0)
    assert data["failures"][0]["id"] == "bad" and data["failures"][0]["type"] == "UnknownPartError"
    assert data["summary"]["ok"] == 1 and data["where"] == "this process"
    assert "\r" not in captured.err and captured.err.splitlines()[-1].startswith("cases: 2/2")  # lines, not a bar


def _children(pid: int) -> set[int]:
    """Process ids whose parent is ``pid`` (from /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.add(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _batch_with_workers(tmp_path, workers: int = 2):
    """A running ``parsel batch`` (own session) and its worker processes, once they are working.

    The batch is long (the seeds 40 times over), so it is still running when the caller
    signals it, however fast the machine."""
    path = cases_file(tmp_path, SEEDS * 40)
    command = [sys.executable, "-m", "parsel_core.cli", "batch", str(path), "-o", str(tmp_path / "out"),
               "--workers", str(workers), "--no-progress"]
    # A test run started in the background (`make test &`) inherits SIGINT ignored, and so
    # would the batch: it gets Ctrl-C's default action back, as in a terminal.
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 240
    results = tmp_path / "out" / RESULTS
    while time.monotonic() < deadline and process.poll() is None:
        if results.exists() and results.read_text().count("\n") >= 1:
            break
        time.sleep(0.02)
    assert process.poll() is None, "the batch ended too early: " + process.stderr.read().decode()
    workers_now = {pid for pid in _children(process.pid) if _alive(pid)}
    assert workers_now, "no worker process found"
    return process, workers_now


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_batch_killed_with_sigkill_leaves_no_worker_process(tmp_path):
    process, workers = _batch_with_workers(tmp_path)
    try:
        os.kill(process.pid, signal.SIGKILL)  # the parent only: nobody signals the workers
        process.wait()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
            time.sleep(0.05)
        assert not [pid for pid in workers if _alive(pid)], "workers outlived their batch"
    finally:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except OSError:
            pass
        process.stderr.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_stops_a_batch_and_its_workers_quietly(tmp_path):
    process, workers = _batch_with_workers(tmp_path)
    try:
        os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole process group
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    err = err.decode()
    assert process.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert "interrupted" in err
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.05)
    assert not [pid for pid in workers if _alive(pid)]


def test_a_folder_of_other_files_is_not_taken_for_a_batch_outdir(tmp_path, capsys):
    path = cases_file(tmp_path, SEEDS[:1])
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "thesis.txt").write_text("years of work")
    assert main(["batch", str(path), "-o", str(docs), "--workers", "0", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "thesis.txt" in err
    assert sorted(p.name for p in docs.iterdir()) == ["thesis.txt"]


def test_a_bad_dask_address_is_refused_before_outdir_is_made(tmp_path, capsys):
    path = cases_file(tmp_path, SEEDS[:1])
    for address in ("nonsense", "tcp://:-1", "tcp://host:70000"):
        assert main(["batch", str(path), "-o", str(tmp_path / "res"), "--dask", address, "--no-progress"]) == 2
        assert "expected a scheduler address" in capsys.readouterr().err
    assert not (tmp_path / "res").exists()


def test_batch_and_eval_verbose_print_each_case_and_quiet_prints_nothing(tmp_path, capsys, monkeypatch):
    from parsel_core import progress as progress_module

    monkeypatch.setattr(progress_module, "DELAY", 0.0)  # progress from the first case
    path = cases_file(tmp_path, SEEDS[:2])
    assert main(["batch", str(path), "-o", str(tmp_path / "v"), "--workers", "0", "--verbose"]) == 0
    err = capsys.readouterr().err
    assert "parsel: case case-00: ok, " in err and "parsel: case case-01: ok, " in err and "cases: 2/2" in err
    assert main(["batch", str(path), "-o", str(tmp_path / "q"), "--workers", "0", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["eval", str(path), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["eval", str(path), "-v"]) == 0
    assert "parsel: case case-01: ok, " in capsys.readouterr().err
