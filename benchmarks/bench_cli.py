"""Whole-command cost: ``parsel --help``, ``inspect chair --json`` and two ``edit chair`` requests.

Each command runs as a fresh process, as a user runs it (the side's own ``parsel``
script entry, ``[project.scripts]``), for this checkout and for a base commit,
alternately in the same run (so machine load hits both alike). CPU time is the child's
user + system time (``os.wait4``), wall time its elapsed time; the table prints medians
and the ratios base / this checkout, then checks the goal: ``parsel edit chair "make the
chair wider"`` at most 1 s of CPU. The second request, ``"make the legs longer"``, names
a set of symmetric parts, as most requests do, and is read along other paths. The base
commit's sources are extracted with ``git archive`` into a temporary folder and put
first on ``PYTHONPATH``, so both sides run in this checkout's virtual environment (same
interpreter, numpy, trimesh ...); bytecode is cached in a temporary
``PYTHONPYCACHEPREFIX`` and each side runs every command once before timing, as an
installed parsel would. Each request's ``edit`` programs of both sides are compared
byte for byte. A floor process (the interpreter and numpy, started as ``parsel`` starts
them) is timed between the runs of the goal's edit: its median shows how fast the
machine was, so runs on different days compare by what the edit costs above it.

CPU times of whole processes move by a fifth between two runs a minute apart on a busy
machine. Where Linux ``perf`` can count a process's user-space instructions, each
command and side is also run under ``perf stat -e instructions:u`` (three runs, after
the timed ones): a count that barely moves with the load, printed with its ratio, so a
change of a few percent can be told from noise.

    python benchmarks/bench_cli.py [--base REV] [--runs 7]

``--base`` defaults to the commit where this branch left ``main``; once merged, name the
commit to compare with (82a1e13 is the last one before lazy start-up). The base runs with
its own plugins only: one added since (installed here, its entry point found by the base's
core) is left out through ``PARSEL_PLUGINS``, as the base ran without it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GOAL_EDIT_CPU_S = 1.0
#: The floor under every command: the interpreter and numpy, started as ``parsel`` starts
#: them (BLAS on one thread). Timed between the edit runs; its median says how fast the
#: machine was during the run, so figures from different days can be compared.
FLOOR = "import os\nfrom parsel_core.blas import one_thread_unless_chosen\none_thread_unless_chosen(os.environ)\n" \
        "import numpy"
#: The command the goal is about; the floor is timed between its runs.
EDIT = 'parsel edit chair "make the chair wider"'
COMMANDS = {
    "parsel --help": ["--help"],
    "parsel inspect chair --json": ["inspect", "chair", "--json"],
    EDIT: ["edit", "chair", "make the chair wider", "-o", "{out}"],
    'parsel edit chair "make the legs longer"': ["edit", "chair", "make the legs longer", "-o", "{out}"],
}


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def extract(rev: str, target: Path) -> None:
    """The tree of ``rev`` under ``target`` (no checkout, no worktree metadata)."""
    archive = subprocess.run(["git", "archive", rev], cwd=ROOT, capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(target)], input=archive, check=True)


def source_path(tree: Path) -> str:
    """``PYTHONPATH`` that makes ``tree``'s core and plugins shadow the installed ones."""
    return os.pathsep.join([str(tree), *(str(p.parent) for p in sorted(tree.glob("plugins/*/pyproject.toml")))])


def tree_plugins(tree: Path) -> set[str]:
    """The ``parsel`` entry-point names that ``tree``'s own plugin folders declare."""
    names: set[str] = set()
    for pyproject in tree.glob("plugins/*/pyproject.toml"):
        project = tomllib.loads(pyproject.read_text()).get("project", {})
        names.update(project.get("entry-points", {}).get("parsel", {}))
    return names


def installed_plugins() -> set[str]:
    """The ``parsel`` entry-point names installed in this environment (both sides load from it)."""
    return {ep.name for ep in metadata.entry_points(group="parsel")}


def side_env(tree: Path, pycache: Path, plugins: set[str] | None = None) -> dict[str, str]:
    """The side's environment: ``tree`` first on ``PYTHONPATH``, the caller's ``PARSEL_*``
    settings left out and, with ``plugins``, only those entry points loaded
    (``PARSEL_PLUGINS``)."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("PARSEL_") and k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONPATH")}
    env.update({"PYTHONPATH": source_path(tree), "PYTHONPYCACHEPREFIX": str(pycache)})
    if plugins is not None:
        env["PARSEL_PLUGINS"] = ",".join(sorted(plugins))
    return env


def base_plugins(tree: Path, installed: set[str]) -> set[str] | None:
    """What the base side may load: ``None`` (every installed plugin) when ``tree`` has them
    all, else the installed ones it has. A plugin added since the base is installed in this
    environment and found through its entry point, but its code needs the newer core: the
    base ran without it."""
    own = tree_plugins(tree)
    return None if installed <= own else installed & own


def check_sources(env: dict[str, str], tree: Path, cwd: Path) -> None:
    """Fail loudly unless the side imports its own core and plugin code (run outside any
    checkout: ``python -c`` puts the working directory first on ``sys.path``)."""
    code = "import parsel_core, parsel_aep, parsel_mesh; print(parsel_core.__file__, parsel_aep.__file__, " \
           "parsel_mesh.__file__)"
    files = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True,
                           check=True)
    for file in files.stdout.split():
        if not Path(file).resolve().is_relative_to(tree.resolve()):
            raise SystemExit(f"bench_cli: {file} is not from {tree}; PYTHONPATH did not take precedence")


def entry_point(tree: Path) -> list[str]:
    """The interpreter command that runs ``tree``'s own ``parsel`` script: what the console
    script pip writes does (import the ``[project.scripts]`` function and exit with it)."""
    module, function = tomllib.loads((tree / "pyproject.toml").read_text())["project"]["scripts"]["parsel"].split(":")
    return [sys.executable, "-c", f"import sys\nfrom {module} import {function}\nsys.argv[0] = 'parsel'\n"
                                  f"sys.exit({function}())"]


def run_once(parsel: list[str], argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """(CPU seconds, wall seconds) of one ``parsel`` process."""
    started = time.perf_counter()
    process = subprocess.Popen([*parsel, *argv], env=env, cwd=cwd, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    process.returncode = os.waitstatus_to_exitcode(status)
    error = process.stderr.read().decode() if process.stderr else ""
    process.stderr.close()
    if process.returncode != 0:
        raise SystemExit(f"bench_cli: parsel {' '.join(argv)} failed ({process.returncode}): {error.strip()}")
    return usage.ru_utime + usage.ru_stime, wall


#: ``perf stat`` counting the user-space instructions of the process it starts, in CSV.
PERF = ["perf", "stat", "-x,", "-e", "instructions:u"]
#: Runs under ``perf`` per command and side (the counts move by well under 1%).
COUNTED_RUNS = 3


def perf_count(text: str) -> float | None:
    """The instruction count in ``perf stat -x,`` output (``None``: not counted, e.g.
    ``<not supported>`` where ``perf_event_paranoid`` forbids it)."""
    for line in text.splitlines():
        fields = line.split(",")
        if len(fields) > 2 and fields[2].startswith("instructions"):
            try:
                return float(fields[0])
            except ValueError:
                return None
    return None


def count_once(parsel: list[str], argv: list[str], env: dict[str, str], cwd: Path) -> float | None:
    """User-space instructions of one ``parsel`` process, or ``None`` where perf cannot count."""
    with tempfile.NamedTemporaryFile("r", suffix=".perf") as out:
        try:
            done = subprocess.run([*PERF, "-o", out.name, "--", *parsel, *argv], env=env, cwd=cwd,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        except OSError:  # no perf
            return None
        return perf_count(out.read()) if done.returncode == 0 else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", help="commit to compare with (default: merge-base of HEAD and main)")
    parser.add_argument("--runs", type=int, default=7, help="timed runs per command and side (default 7)")
    args = parser.parse_args()
    head = git("rev-parse", "--short", "HEAD")
    try:
        base = git("rev-parse", "--short", args.base or git("merge-base", "HEAD", "main"))
    except subprocess.CalledProcessError as exc:
        raise SystemExit(f"bench_cli: no base commit ({exc.stderr.strip() or 'git failed'}); pass --base REV") from None
    if base == head and not args.base:
        raise SystemExit("bench_cli: HEAD is on main; name the commit to compare with: --base REV")
    with tempfile.TemporaryDirectory(prefix="bench-cli-") as tmp:
        tmp_path = Path(tmp)
        (tmp_path / "base").mkdir()
        extract(base, tmp_path / "base")
        sides = {"base": tmp_path / "base", "this": ROOT}
        installed = installed_plugins()
        plugins = {"base": base_plugins(sides["base"], installed), "this": None}
        envs = {name: side_env(tree, tmp_path / f"pycache-{name}", plugins[name]) for name, tree in sides.items()}
        entries = {name: entry_point(tree) for name, tree in sides.items()}
        work = tmp_path / "work"
        work.mkdir()
        for name, tree in sides.items():
            check_sources(envs[name], tree, work)
        dirty = " (with uncommitted changes)" if git("status", "--porcelain", "--untracked-files=no") else ""
        print(f"base {base} vs this checkout {head}{dirty}; {args.runs} runs per command and side, alternating; "
              f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load average "
              f"{os.getloadavg()[0]:.1f}")
        if plugins["base"] is not None:
            print(f"base {base} runs without the plugins added since: {', '.join(sorted(installed - plugins['base']))}")
        results: dict[tuple[str, str], list[tuple[float, float]]] = {}
        floor: list[tuple[float, float]] = []
        for number, (label, template) in enumerate(COMMANDS.items()):
            for name in sides:  # warm-up: bytecode caches, page cache
                run_once(entries[name], [a.format(out=work / f"warm-{name}") for a in template], envs[name], work)
            for i in range(args.runs):
                for name in (sides if i % 2 == 0 else reversed(list(sides))):
                    argv = [a.format(out=work / f"out-{name}-{number}") for a in template]
                    results.setdefault((label, name), []).append(run_once(entries[name], argv, envs[name], work))
                if label == EDIT:
                    floor.append(run_once([sys.executable, "-c", FLOOR], [], envs["this"], work))
        print(f"\n{'command':<44}{'CPU base':>10}{'CPU this':>10}{'ratio':>8}{'wall base':>11}{'wall this':>11}"
              f"{'ratio':>8}")
        for label in COMMANDS:
            cpu = {n: statistics.median(c for c, _ in results[(label, n)]) for n in sides}
            wall = {n: statistics.median(w for _, w in results[(label, n)]) for n in sides}
            print(f"{label:<44}{cpu['base']:>9.3f}s{cpu['this']:>9.3f}s{cpu['base'] / cpu['this']:>7.1f}x"
                  f"{wall['base']:>10.3f}s{wall['this']:>10.3f}s{wall['base'] / wall['this']:>7.1f}x")
        counted = count_instructions(entries, envs, sides, work)
        if counted:
            print(f"\n{'command':<44}{'instr base':>12}{'instr this':>12}{'ratio':>8}")
            for label in COMMANDS:
                base_count, this_count = counted[(label, "base")], counted[(label, "this")]
                print(f"{label:<44}{base_count / 1e6:>11.1f}M{this_count / 1e6:>11.1f}M"
                      f"{base_count / this_count:>7.3f}x")
        else:
            print("\ninstructions: not counted (Linux perf missing or not permitted)")
        edits = [number for number, template in enumerate(COMMANDS.values()) if "{out}" in template]
        same = all((work / f"out-base-{n}" / "program.json").read_bytes()
                   == (work / f"out-this-{n}" / "program.json").read_bytes() for n in edits)
        edit = statistics.median(c for c, _ in results[(EDIT, "this")])
        print(f"\nedit programs of base and this checkout: {'identical' if same else 'DIFFERENT'}")
        print(f"goal: parsel edit chair ... <= {GOAL_EDIT_CPU_S:g} s CPU: {edit:.3f} s "
              f"{'ok' if edit <= GOAL_EDIT_CPU_S else 'NOT MET'}")
        lowest = statistics.median(c for c, _ in floor)
        print(f"floor: python and numpy as parsel starts them, timed between the edit runs: {lowest:.3f} s CPU; "
              f"parsel edit chair ... above it: {edit - lowest:.3f} s ({edit / lowest:.1f}x the floor)")
        print("CPU: user + system time of the process (os.wait4); medians; ratio = base / this")
        if counted:
            print(f"instr: user-space instructions (perf stat -e instructions:u), median of {COUNTED_RUNS} runs")


def count_instructions(entries: dict[str, list[str]], envs: dict[str, dict[str, str]], sides: dict[str, Path],
                       work: Path) -> dict[tuple[str, str], float] | None:
    """Median instructions per command and side, or ``None`` where perf cannot count."""
    counted: dict[tuple[str, str], float] = {}
    for number, (label, template) in enumerate(COMMANDS.items()):
        for name in sides:
            argv = [a.format(out=work / f"counted-{name}-{number}") for a in template]
            counts = [count_once(entries[name], argv, envs[name], work) for _ in range(COUNTED_RUNS)]
            if any(c is None for c in counts):
                return None
            counted[(label, name)] = statistics.median(counts)
    return counted


if __name__ == "__main__":
    main()
