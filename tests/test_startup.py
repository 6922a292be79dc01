"""Start-up cost: commands import only what they use (measured in benchmarks/bench_cli.py).

Each check runs a fresh interpreter and looks at ``sys.modules``, so it catches a heavy
import creeping back in, whichever module brings it.
"""

import argparse
import json
import os
import re
import subprocess
import sys
from importlib import metadata

import pytest

from parsel_core import plugins

HEAVY = ("trimesh", "scipy", "sympy", "networkx", "matplotlib", "litellm", "symengine", "skimage", "dask")


def imported_after(code: str) -> dict:
    """Top-level package names in ``sys.modules`` after running ``code``, and what it printed."""
    probe = (f"{code}\nimport json, sys\n"
             "print(json.dumps(sorted({m.split('.')[0] for m in list(sys.modules)})))")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return set(json.loads(result.stdout.strip().splitlines()[-1]))


def plugin_packages() -> set[str]:
    return {ep.value.split(":")[0].split(".")[0] for ep in metadata.entry_points(group=plugins.ENTRY_POINT_GROUP)}


def run_cli(*args: str) -> str:
    return ("import contextlib, io\nfrom parsel_core.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    try:\n        status = main({list(args)!r})\n    except SystemExit as exc:\n"
            "        status = exc.code\nassert status == 0, status")


def test_help_imports_no_plugin_and_no_heavy_dependency():
    modules = imported_after(run_cli("--help"))
    assert "parsel_core" in modules
    assert not modules & plugin_packages(), modules & plugin_packages()
    assert not modules & {*HEAVY, "numpy"}


def test_help_lists_the_commands_plugins_declare():
    help_text = subprocess.run([sys.executable, "-m", "parsel_core.cli", "--help"], capture_output=True, text=True,
                               timeout=120).stdout
    for command, plugin in (("view", "parsel-view"), ("render", "parsel-view"), ("eval", "parsel-batch"),
                            ("batch", "parsel-batch")):
        entry = re.search(rf"\n    {command} +(.*?)(?=\n    \S|\n\n)", help_text, re.S)  # up to the next command
        line = " ".join(entry.group(1).split())
        assert line.endswith(f"({plugin})") and len(line.split()) > 5, line  # what it does, from which plugin


def test_every_plugin_command_is_declared_for_help():
    """A plugin command missing from ``parsel.commands`` would vanish from ``parsel --help``."""

    class Names:
        def __init__(self):
            self.names = set()

        def add_parser(self, name, **kwargs):
            self.names.add(name)
            return argparse.ArgumentParser(prog=name, add_help=False)

    registered = Names()
    plugins.get_plugin_manager().hook.parsel_register_commands(subparsers=registered)
    assert registered.names == set(plugins.declared_commands())


def test_declared_commands_follow_parsel_plugins(monkeypatch):
    monkeypatch.setenv("PARSEL_PLUGINS", "view")
    assert sorted(plugins.declared_commands()) == ["render", "view"]
    monkeypatch.setenv("PARSEL_PLUGINS", "")
    assert plugins.declared_commands() == {}


def test_builtin_command_help_loads_no_plugin():
    modules = imported_after(run_cli("edit", "--help"))
    assert not modules & plugin_packages()


def test_importing_the_package_is_cheap_and_its_names_load_on_use():
    import parsel_core

    assert not imported_after("import parsel_core") & {*HEAVY, "numpy"}
    assert parsel_core.Program is __import__("parsel_core.program").program.Program
    assert set(parsel_core.__all__) <= set(dir(parsel_core))
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        parsel_core.Nope  # noqa: B018


@pytest.mark.parametrize("entry_point", sorted(ep.name for ep in metadata.entry_points(group="parsel")))
def test_registering_a_plugin_imports_no_heavy_dependency(entry_point):
    ep = next(e for e in metadata.entry_points(group="parsel") if e.name == entry_point)
    modules = imported_after(f"import {ep.value.split(':')[0]}")
    assert not modules & set(HEAVY), modules & set(HEAVY)


def test_listing_cas_backends_imports_no_cas():
    modules = imported_after("from parsel_core.plugins import cas_backend_names\nprint(cas_backend_names())")
    assert not modules & {"sympy", "symengine"}


def test_the_sympy_backend_class_is_importable_without_sympy():
    code = ("import sys\nfrom parsel_sympy.backend import SympyBackend\nassert 'sympy' not in sys.modules\n"
            "backend = SympyBackend()\nassert 'sympy' in sys.modules\n"
            "assert str(backend.solve(backend.symbol('f') * 2 - 1, 'f')) == '[1/2]'")
    assert "sympy" in imported_after(code)


@pytest.mark.parametrize("argv", [("inspect", "chair", "--json"), ("edit", "chair", "make the chair wider"),
                                  ("edit", "chair", "make the legs longer"), ("edit", "chair", "make the back taller")])
def test_inspect_and_edit_of_the_bundled_chair_import_no_heavy_dependency(argv, tmp_path):
    if argv[0] == "edit":
        argv = (*argv, "-o", str(tmp_path / "out"))
    modules = imported_after(run_cli(*argv))
    assert not modules & {"trimesh", "scipy", "sympy", "networkx", "matplotlib"}, modules & set(HEAVY)
    if argv[0] == "edit":
        assert json.loads((tmp_path / "out" / "program.json").read_text())["ops"]


def test_the_networkx_view_is_built_on_first_use_and_agrees_with_neighbours():
    from parsel_core.graph import GROUP_KINDS
    from parsel_core.loading import load_shape

    assert "networkx" not in imported_after("from parsel_core.loading import load_shape\nload_shape('tiny_table')")
    shape = load_shape("tiny_table")
    graph = shape.graph
    assert set(graph.nodes) == set(shape.parts) | set(shape.virtual_parents)
    assert all(graph.nodes[g].get("virtual") for g in shape.virtual_parents)
    expected = sum(len(r.members) if r.kind in GROUP_KINDS else max(1, len(r.members) * (len(r.members) - 1) // 2)
                   for r in shape.relations.values())
    assert graph.number_of_edges() == expected
    for pid in shape.all_parts:
        assert shape.neighbours(pid) == sorted(n for n in graph.neighbors(pid) if n != pid)
    assert {key for _, _, key in graph.edges(keys=True)} == set(shape.relations)


def reported_at_exit(args: list[str], report: str, env: dict[str, str], cwd=None) -> str:
    """What ``report`` (Python code, run when the process exits) wrote on a line of its
    own after ``REPORT `` to stderr, in a ``parsel`` process (the console entry, run the
    way the installed script runs it) given ``args``."""
    probe = ("import atexit, sys\n"
             "def report():\n"
             + "".join(f"    {line}\n" for line in report.splitlines()) +
             "atexit.register(report)\n"
             f"sys.argv = ['parsel', *{args!r}]\n"
             "from parsel_core.cli import console\n"
             "console()\n")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, env=env,
                            cwd=cwd)
    assert result.returncode == 0, result.stderr
    return result.stderr.rsplit("REPORT ", 1)[1]


def blas_threads_of_command(args: list[str], env: dict[str, str]) -> list[int]:
    """The BLAS pool sizes numpy had in a ``parsel`` process, read when it exits."""
    report = ("import json\n"
              "from threadpoolctl import threadpool_info\n"
              "sizes = [i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas']\n"
              "print('REPORT ' + json.dumps(sizes), file=sys.stderr)")
    return json.loads(reported_at_exit(args, report, env))


def clean_environment() -> dict[str, str]:
    from parsel_core.blas import THREAD_VARIABLES

    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}


def test_the_command_runs_blas_on_one_thread():
    sizes = blas_threads_of_command(["inspect", "tiny_table", "--json"], clean_environment())
    assert sizes and all(size == 1 for size in sizes), sizes


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: every pool has one thread")
def test_a_thread_count_the_user_chose_is_kept():
    sizes = blas_threads_of_command(["inspect", "tiny_table", "--json"],
                                    {**clean_environment(), "OPENBLAS_NUM_THREADS": "2"})
    assert sizes and all(size == 2 for size in sizes), sizes


def test_main_in_process_leaves_the_environment_alone():
    from parsel_core.blas import THREAD_VARIABLES

    probe = (run_cli("inspect", "tiny_table", "--json")
             + f"\nimport os\nassert not [n for n in {THREAD_VARIABLES!r} if n in os.environ]")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300,
                            env=clean_environment())
    assert result.returncode == 0, result.stderr


def test_one_thread_unless_chosen():
    from parsel_core.blas import THREAD_VARIABLES, one_thread_unless_chosen

    environ = {"PATH": "/bin"}
    assert one_thread_unless_chosen(environ) == list(THREAD_VARIABLES)
    assert environ == {"PATH": "/bin", **{name: "1" for name in THREAD_VARIABLES}}
    chosen = {"OMP_NUM_THREADS": "4"}  # one size chosen: the user's choice, left whole
    assert one_thread_unless_chosen(chosen) == [] and chosen == {"OMP_NUM_THREADS": "4"}


def test_the_command_reads_no_package_metadata_and_no_thread_library_once_cached(tmp_path):
    """The ``parsel`` program with its BLAS started on one thread needs no threadpoolctl,
    and with the entry points cached (entrypoints.py) no importlib.metadata (nor the email
    package it parses metadata with); without a parsel.toml, no TOML parser."""
    args = ["edit", "chair", "make the chair wider", "-o", str(tmp_path / "out")]
    report = "import json\nprint('REPORT ' + json.dumps(sorted(sys.modules)), file=sys.stderr)"
    env = {**clean_environment(), "PARSEL_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("PARSEL_CONFIG", None)
    for run in ("cold", "warm"):
        modules = set(json.loads(reported_at_exit(args, report, env, cwd=tmp_path)))
        assert not modules & {"threadpoolctl", "tomllib"}, run
        assert ("importlib.metadata" in modules) == (run == "cold")
        assert "email" not in {m.split(".")[0] for m in modules} or run == "cold"
    assert list((tmp_path / "cache").glob("entry-points-*.json"))
