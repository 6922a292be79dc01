"""benchmarks/bench_cli.py: the instruction counts it reads from ``perf stat``."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_cli  # noqa: E402


def test_the_count_is_read_from_perf_s_csv_output():
    counted = "# started on Tue Dec  1 15:38:42 2026\n\n1498420964,,instructions:u,20184250,100.00,,\n"
    assert bench_cli.perf_count(counted) == 1498420964.0
    for refused in ("<not supported>,,instructions:u,0,100.00,,\n", "<not counted>,,instructions:u,0,0.00,,\n",
                    "", "# started on Tue Dec  1 15:38:42 2026\n"):
        assert bench_cli.perf_count(refused) is None, refused


def test_a_machine_without_perf_counts_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(bench_cli, "PERF", [str(tmp_path / "no-such-perf"), "stat"])
    assert bench_cli.count_once([sys.executable, "-c", "pass"], [], {}, tmp_path) is None


def test_a_process_is_counted_where_perf_can_count(tmp_path):
    if shutil.which("perf") is None:
        pytest.skip("no perf on this machine")
    probe = subprocess.run([*bench_cli.PERF, "--", "true"], capture_output=True, text=True)
    if probe.returncode != 0 or bench_cli.perf_count(probe.stderr) is None:
        pytest.skip("perf may not count here")
    count = bench_cli.count_once([sys.executable, "-c", "pass"], [], {}, tmp_path)
    assert count is not None and count > 1e6  # an interpreter's start-up: tens of millions
