"""benchmarks/bench_cli.py: the instruction counts it reads from ``perf stat``."""

from __future__ import annotations

import os
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


def _plugin(tree: Path, folder: str, names: dict[str, str]) -> None:
    (tree / "plugins" / folder).mkdir(parents=True)
    lines = "".join(f'{name} = "{module}"\n' for name, module in names.items())
    (tree / "plugins" / folder / "pyproject.toml").write_text(
        f'[project]\nname = "{folder}"\n\n[project.entry-points.parsel]\n{lines}\n'
        f'[project.entry-points."parsel.commands"]\nnot-a-plugin = "x"\n')


def test_a_base_without_a_plugin_added_since_runs_with_its_own_plugins_only(tmp_path):
    _plugin(tmp_path, "parsel-aep", {"aep": "parsel_aep"})
    _plugin(tmp_path, "parsel-mesh", {"mesh": "parsel_mesh", "cage": "parsel_mesh.cage"})
    assert bench_cli.tree_plugins(tmp_path) == {"aep", "mesh", "cage"}
    # a plugin of the base's that is no longer installed cannot load anyway
    assert bench_cli.base_plugins(tmp_path, {"aep", "mesh", "cage", "fit"}) == {"aep", "mesh", "cage"}
    assert bench_cli.base_plugins(tmp_path, {"aep", "fit"}) == {"aep"}
    assert bench_cli.base_plugins(tmp_path, {"aep", "mesh"}) is None  # it has them all: nothing to limit


def test_a_side_s_environment_names_its_plugins_and_drops_the_caller_s_parsel_settings(tmp_path, monkeypatch):
    monkeypatch.setenv("PARSEL_PLUGINS", "aep")
    monkeypatch.setenv("PARSEL_CACHE_DIR", str(tmp_path))
    unlimited = bench_cli.side_env(tmp_path, tmp_path / "pycache")
    assert not any(name.startswith("PARSEL_") for name in unlimited)
    assert unlimited["PYTHONPATH"].split(os.pathsep)[0] == str(tmp_path)
    limited = bench_cli.side_env(tmp_path, tmp_path / "pycache", {"mesh", "aep"})
    assert limited["PARSEL_PLUGINS"] == "aep,mesh"


def test_the_plugins_of_a_real_tree_are_read_from_its_plugin_folders():
    declared = bench_cli.tree_plugins(ROOT)
    assert {"aep", "fit", "mesh", "shapeassembly", "symengine", "sympy"} <= declared
    assert len(declared) == len(list(ROOT.glob("plugins/*/pyproject.toml")))  # one entry point each
