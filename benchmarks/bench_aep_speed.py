"""AEP solver speed, old against new, and proof that the programs did not change.

A fixed list of requests (the first random-seed requests of ``bench_aep.py``, designer
seeds spread over ``bench_aep.py``'s designer shapes, and the seeds of the property
tests in ``plugins/parsel-aep/tests/test_properties.py``) is solved by two worker
processes, one importing ``parsel_aep`` from the working tree and one from a baseline
revision (``git archive`` of ``plugins/parsel-aep``, with ``--core`` of ``parsel_core`` too,
with ``--tree`` of the whole tree, core and every plugin, into a temporary folder, put
first on ``PYTHONPATH``). The requests alternate between the
two workers, so a busy machine slows both alike; each request's CPU time is
``time.process_time`` inside its worker.

For every request the program's JSON text, the rejected relations and the solver's
counts (its stats without times) must be byte-for-byte the same in both; any difference
is listed (with, for programs of the same ops, the largest difference of the amounts at
the samples) and the exit status is 1. A request a side crashes on (any exception but
the solver's own refusals) is recorded as its result and listed per side at the end; a
crash of the working tree's side also exits with status 1. Counts of work done
(``WORK_COUNTS``: candidates screened, searches proved hopeless without screening) may
differ; their totals are printed at the end.

    python benchmarks/bench_aep_speed.py [--baseline REV [--core | --tree]] [--random 40] [--designer 40]
        [--no-properties] [--save DIR] [--only LABEL-SUBSTRING] [--split [--goal 0.5]]
        [--sample SEED] [--shapes 100]

``--sample`` draws the random-seed requests' shapes afresh (another seed than
``bench_aep.py``'s 0), so a change is also checked on shapes it was not measured on;
``--shapes`` how many are drawn.

Without ``--baseline`` only the working tree runs (CPU times and, with ``--save``, the
outputs, one JSON file per request).

``--split`` also times, in each worker, the CPU spent inside ``numpy.linalg``'s
factorisations and solves (LAPACK) and inside the joint pass, request by request, and
prints where the time goes: the median and p95 as measured, without the joint pass,
without LAPACK and of LAPACK alone, and how many times faster the work outside LAPACK
would have to be for a p95 of ``--goal`` seconds (with the same LAPACK calls, as the same
programs need).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "shapeassembly"
PROPERTIES = ROOT / "plugins" / "parsel-aep" / "tests" / "test_properties.py"


# -- the requests ----------------------------------------------------------------------

def _properties_module():
    spec = importlib.util.spec_from_file_location("_aep_properties", PROPERTIES)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cases(random: int, designer: int, properties: bool, data: Path, shapes: int = 100,
          sample: int = 0) -> list[dict]:
    """``{label, spec, seed, breaks, options}`` for every request, in a fixed order; the
    random-seed requests are those of ``bench_aep.py --shapes SHAPES``, on shapes drawn
    with the seed ``sample`` (0: ``bench_aep.py``'s; others label theirs ``random<sample>``)."""
    import numpy as np

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_aep import seeds_for
    from designer_seeds import designer_seeds, sample_programs

    from parsel_core.loading import load_shape

    out: list[dict] = []
    if random:
        requests = []
        for path in sample_programs(data, shapes, seed=sample):
            shape = load_shape(str(path))
            requests += [(str(path), shape.name, seed) for seed in seeds_for(shape)]
            if len(requests) >= random:
                break
        kind = "random" if sample == 0 else f"random{sample}"
        for i, (path, name, seed) in enumerate(requests[:random]):
            out.append({"label": f"{kind}-{i:03d}-{name}", "spec": path, "seed": seed, "breaks": [],
                        "options": {"backend": "symengine"}})
    if designer:
        found = []
        for path in sample_programs(data, 60, seed=1):
            shape = load_shape(str(path))
            found += [(str(path), shape.name, d) for d in designer_seeds(shape)]
        step = max(1, len(found) // designer)
        for i, (path, name, d) in enumerate(found[::step][:designer]):
            out.append({"label": f"designer-{i:03d}-{name}-{d.kind}", "spec": path, "seed": d.seed,
                        "breaks": list(d.breaks), "options": {"backend": "symengine"}})
    if properties:
        module = _properties_module()
        for spec in module.SHAPES:
            shape = load_shape(spec)
            rng = np.random.default_rng(sum(map(ord, Path(spec).stem)))
            for k in range(2):
                out.append({"label": f"property-{Path(spec).stem}-{k}", "spec": spec,
                            "seed": module.random_seed(shape, rng), "breaks": [], "options": {}})
                rng.uniform(0.0, 1.0, 50)  # the test's fresh parameter values (same draws whatever the range)
        for backend in ("symengine", "sympy"):
            for spec in ["tiny_table", "shelf", str(module.FIXTURES / "chair" / "1277.txt")]:
                shape = load_shape(spec)
                rng = np.random.default_rng(sum(map(ord, Path(spec).stem + backend)))
                for k in range(6):
                    out.append({"label": f"family-{Path(spec).stem}-{backend}-{k}", "spec": spec,
                                "seed": module.any_seed(shape, rng), "breaks": [], "options": {"backend": backend}})
    return out


# -- a worker: solves the requests it is sent ------------------------------------------

def worker(split: bool = False) -> None:
    """Read one request (JSON) a line on stdin, answer one result (JSON) a line on stdout;
    ``split``: with its :class:`SplitClock` figures."""
    answer = sys.stdout
    sys.stdout = sys.stderr  # nothing the solver prints may reach the answers
    import parsel_aep
    from parsel_core.plugins import solvers

    shapes: dict[str, object] = {}
    aep = solvers()["aep"]
    print(f"worker {os.getpid()}: parsel_aep from {Path(parsel_aep.__file__).parent}", file=sys.stderr)
    split_clock = SplitClock() if split else None
    if split_clock:
        split_clock.install()
    for line in sys.stdin:
        case = json.loads(line)
        if split_clock:
            split_clock.reset()
        seconds, out = solve_case(aep, shapes, case)
        found = {"label": case["label"], "seconds": seconds, "result": out}
        if split_clock:
            found["split"] = dict(split_clock.totals)
        answer.write(json.dumps(found) + "\n")
        answer.flush()


def solve_case(aep, shapes: dict, case: dict) -> tuple[float, dict]:
    """CPU seconds and the result of one request: its program, rejections and counts; the
    error of a request the solver refuses (``ParselError``); or, when the solver fails
    (any other exception), ``crashed``, so that a crash on one side is a difference to
    list rather than the end of the run. ``shapes`` keeps the loaded shapes by spec."""
    from parsel_core.errors import ParselError
    from parsel_core.interfaces import SolveRequest
    from parsel_core.loading import load_shape
    from parsel_core.program import Program

    shape = shapes.get(case["spec"])
    if shape is None:
        shape = shapes[case["spec"]] = load_shape(case["spec"])
    clock = time.process_time()
    try:
        request = SolveRequest(shape, Program.from_text(case["seed"]), breaks=tuple(case["breaks"]),
                               options=case["options"])
        result = aep.run(request)
    except ParselError as exc:
        return time.process_time() - clock, {"error": f"{type(exc).__name__}: {exc}"}
    except Exception as exc:  # a benchmark reports crashes instead of stopping
        return time.process_time() - clock, {"crashed": f"{type(exc).__name__}: {exc}"}
    seconds = time.process_time() - clock
    stats = {k: v for k, v in result.stats.items() if k != "time_s"}
    return seconds, {"program": result.program.to_json(), "rejected": list(result.rejected),
                     "stats": json.loads(json.dumps(stats, sort_keys=True, default=str))}


# -- where the time goes (--split) -----------------------------------------------------

#: The ``numpy.linalg`` functions that run LAPACK, timed by ``--split``.
LAPACK_CALLS = ("lstsq", "svd", "solve", "cholesky", "qr", "pinv", "det", "slogdet", "inv", "eig", "eigh",
                "eigvalsh", "matrix_rank")


class SplitClock:
    """CPU seconds inside ``numpy.linalg``'s LAPACK calls (``lapack``; ``lapack_joint`` of
    them inside the joint pass) and inside the joint pass (``joint``), by wrapping those
    functions in this worker process. A call inside a timed one (pinv's SVD) counts once;
    the wrappers' own time (two clock reads a call) counts as work outside LAPACK."""

    def __init__(self) -> None:
        self.totals = dict.fromkeys(("lapack", "lapack_joint", "joint"), 0.0)
        self.depth = 0
        self.in_joint = False

    def reset(self) -> None:
        self.totals = dict.fromkeys(self.totals, 0.0)

    def install(self) -> None:
        import numpy as np

        from parsel_aep import propagate

        for name in LAPACK_CALLS:
            if hasattr(np.linalg, name):
                setattr(np.linalg, name, self.lapack(getattr(np.linalg, name)))
        joint_repair = getattr(propagate.Propagation, "joint_repair", None)  # (an old baseline may lack it)
        if joint_repair is not None:
            propagate.Propagation.joint_repair = self.joint(joint_repair)

    def lapack(self, function):
        def timed(*args, **kwargs):
            if self.depth:
                return function(*args, **kwargs)
            self.depth += 1
            clock = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                seconds = time.process_time() - clock
                self.depth -= 1
                self.totals["lapack"] += seconds
                if self.in_joint:
                    self.totals["lapack_joint"] += seconds
        return timed

    def joint(self, function):
        def timed(*args, **kwargs):
            self.in_joint = True
            clock = time.process_time()
            try:
                return function(*args, **kwargs)
            finally:
                self.in_joint = False
                self.totals["joint"] += time.process_time() - clock
        return timed


def what_if(seconds: list[float], splits: list[dict[str, float]], goal: float) -> tuple[list, dict]:
    """Where the time goes: ``(rows, factors)``. ``rows`` are ``(case, median, p95)`` of the
    requests' CPU as measured and with parts of the work taken away; ``factors`` how many
    times faster the work outside LAPACK (all of it, or the joint pass's only) would have
    to be for a p95 of at most ``goal`` (``inf``: not even if it took no time)."""
    cpu = [float(t) for t in seconds]
    lapack = [s["lapack"] for s in splits]
    joint = [s["joint"] for s in splits]
    joint_rest = [s["joint"] - s["lapack_joint"] for s in splits]
    outside = [c - a for c, a in zip(cpu, lapack)]  # all the work outside LAPACK

    def figures(times: list[float]) -> tuple[float, float]:
        return statistics.median(times), percentile(times, 0.95)

    rows = [("as measured", *figures(cpu)),
            ("without the joint pass", *figures([c - j for c, j in zip(cpu, joint)])),
            ("joint pass: its LAPACK only", *figures([c - j for c, j in zip(cpu, joint_rest)])),
            ("without LAPACK", *figures(outside)),
            ("LAPACK alone", *figures(lapack))]

    def factor(rest: list[float]) -> float:
        """The least ``k`` with ``p95(cpu - rest + rest / k) <= goal``, by bisection."""
        def p95(k: float) -> float:
            return percentile([c - r + r / k for c, r in zip(cpu, rest)], 0.95)
        if p95(1.0) <= goal:
            return 1.0
        if p95(float("inf")) > goal:
            return float("inf")
        lo, hi = 1.0, 2.0
        while p95(hi) > goal:
            lo, hi = hi, 2 * hi
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (lo, mid) if p95(mid) <= goal else (mid, hi)
        return hi

    return rows, {"all work outside LAPACK": factor(outside), "the joint pass outside LAPACK": factor(joint_rest)}


def print_split(name: str, seconds: list[float], splits: list[dict[str, float]], goal: float) -> None:
    """``--split``'s table for side ``name``."""
    total = max(sum(seconds), 1e-9)
    lapack, joint = sum(s["lapack"] for s in splits), sum(s["joint"] for s in splits)
    lapack_joint = sum(s["lapack_joint"] for s in splits)
    print(f"\n{name}: where the CPU goes ({len(seconds)} requests, {total:.1f} s): LAPACK {lapack:.1f} s "
          f"({lapack / total:.0%}), the joint pass {joint:.1f} s ({joint / total:.0%}; "
          f"{lapack_joint:.1f} s of it LAPACK)")
    rows, factors = what_if(seconds, splits, goal)
    print(f"{'CPU per request':<32}{'median s':>10}{'p95 s':>9}")
    for case, median, p95 in rows:
        print(f"{case:<32}{median:>10.3f}{p95:>9.3f}")
    for work, k in factors.items():
        needed = "not even if it took no time" if k == float("inf") else f"{k:.2f}x faster"
        print(f"for a p95 of {goal:g} s, {work}: {needed}")


class Worker:
    def __init__(self, name: str, pythonpath: str | None, extra: dict[str, str] | None = None,
                 split: bool = False) -> None:
        env = {**os.environ, **(extra or {})}
        if pythonpath:
            env["PYTHONPATH"] = pythonpath + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        self.name = name
        self.process = subprocess.Popen([sys.executable, __file__, "--worker", *(["--split"] if split else [])],
                                        stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env, text=True, cwd=ROOT)

    def solve(self, case: dict) -> dict:
        self.process.stdin.write(json.dumps(case) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f"worker {self.name} ended")
        return json.loads(line)

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait()


#: What a baseline takes from its revision, by scope (:func:`baseline_tree`): the paths
#: extracted (none: the whole tree).
TAKEN = {"aep": ["plugins/parsel-aep"], "core": ["plugins/parsel-aep", "parsel_core"], "tree": []}


def baseline_tree(revision: str, into: Path, scope: str = "aep") -> str:
    """What ``revision`` solves with, extracted into ``into``; the ``PYTHONPATH`` to import it from.

    ``scope``: ``aep``, only ``plugins/parsel-aep``; ``core``, ``parsel_core`` too; ``tree``,
    the whole tree, core and every plugin folder. The installed entry points still name the
    plugins (a plugin ``revision`` lacks loads from the working tree), so ``tree`` compares
    with a revision whose core the working tree's other plugins no longer run on."""
    if scope not in TAKEN:
        raise ValueError(f"baseline scope {scope!r}: expected one of {', '.join(TAKEN)}")
    paths = TAKEN[scope]
    archive = subprocess.run(["git", "archive", revision, *paths], cwd=ROOT, check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    if scope == "tree":
        plugins = sorted(p for p in (into / "plugins").iterdir() if (p / "pyproject.toml").is_file())
    else:
        plugins = [into / "plugins" / "parsel-aep"]
    return os.pathsep.join([*map(str, plugins), *([str(into)] if scope != "aep" else [])])


# -- comparing ---------------------------------------------------------------------------

def amount_difference(old: str, new: str) -> str:
    """For two programs with the same ops and parameters: the largest difference of their
    amounts at 101 samples of the range (else why they differ)."""
    import numpy as np

    from parsel_aep.derive import evaluate_amount
    from parsel_core.program import Program

    a, b = Program.from_json(old), Program.from_json(new)
    if [(op.name, op.operand, op.feature) for op in a.ops] != [(op.name, op.operand, op.feature) for op in b.ops]:
        return "different ops"
    if a.parameters != b.parameters:
        return "different parameters"
    p = a.parameters[0]
    xs = np.linspace(p.lo, p.hi, 101)
    worst = 0.0
    for x, y in zip(a.ops, b.ops):
        pa = {k: v for k, v in x.params().items()}
        pb = {k: v for k, v in y.params().items()}
        for k in pa:
            worst = max(worst, float(np.max(np.abs(np.asarray(pa[k], dtype=float) - np.asarray(pb[k], dtype=float))))
                        if isinstance(pa[k], tuple) else 0.0)
        worst = max(worst, float(np.max(np.abs(evaluate_amount(x.amount, p.name, xs)
                                                - evaluate_amount(y.amount, p.name, xs)))))
    return f"same ops, largest parameter/amount difference {worst:.3g}"


#: Solver counts of work done, not of what was decided: compared as totals only.
WORK_COUNTS = ("candidates_screened", "hopeless_searches")


def decided(result: dict) -> dict:
    """The result without its counts of work done."""
    if "stats" not in result:
        return result
    return {**result, "stats": {k: v for k, v in result["stats"].items() if k not in WORK_COUNTS}}


def digest(result: dict) -> str:
    return hashlib.sha256(json.dumps(result, sort_keys=True).encode()).hexdigest()[:16]


def percentile(times: list[float], q: float) -> float:
    ordered = sorted(times)
    return ordered[int(q * (len(ordered) - 1))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--baseline", help="git revision to compare with (its plugins/parsel-aep)")
    taken = parser.add_mutually_exclusive_group()
    taken.add_argument("--core", dest="scope", action="store_const", const="core", default="aep",
                       help="take parsel_core from the baseline too (for changes to relations or ops)")
    taken.add_argument("--tree", dest="scope", action="store_const", const="tree",
                       help="take the baseline's whole tree, core and every plugin (for an older revision)")
    parser.add_argument("--random", type=int, default=40, help="first random-seed requests of bench_aep")
    parser.add_argument("--sample", type=int, default=0,
                        help="draw the random-seed requests' shapes with this seed (0: bench_aep's shapes)")
    parser.add_argument("--shapes", type=int, default=100, help="shapes drawn for the random-seed requests")
    parser.add_argument("--designer", type=int, default=40, help="designer seeds, spread over the shapes")
    parser.add_argument("--no-properties", action="store_true", help="leave out the property-test seeds")
    parser.add_argument("--only", default="", help="only requests whose label contains this")
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--env", action="append", default=[], metavar="NAME=VALUE",
                        help="an environment variable for the working tree's worker only (repeatable)")
    parser.add_argument("--reference", type=Path,
                        help="a --save folder of an earlier run: compare with its results, not a baseline's")
    parser.add_argument("--save", type=Path, help="folder for every result (one JSON per request and side)")
    parser.add_argument("--split", action="store_true",
                        help="also time LAPACK and the joint pass in each request, and print where the time goes")
    parser.add_argument("--goal", type=float, default=0.5, help="with --split: the p95 goal in seconds (0.5)")
    args = parser.parse_args()
    if args.worker:
        worker(args.split)
        return
    todo = [c for c in cases(args.random, args.designer, not args.no_properties, args.data, args.shapes, args.sample)
            if args.only in c["label"]]
    print(f"{len(todo)} requests", flush=True)
    found = compare(todo, args.baseline, dict(item.split("=", 1) for item in args.env), args.save, args.reference,
                    scope=args.scope, split=args.split)
    print()
    found.print_summary()
    for name, splits in found.splits.items():
        print_split(name, found.times[name], splits, args.goal)
    if found.mismatches or found.crashed.get("new"):
        sys.exit(1)


@dataclass
class Comparison:
    """CPU seconds per request of each side, the requests whose results differ, work counts."""

    times: dict[str, list[float]]
    mismatches: list[tuple[str, str]]
    work: dict[str, dict[str, int]]
    requests: int
    compared: bool
    #: ``--split``: each request's :class:`SplitClock` figures, by side.
    splits: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    #: The requests each side crashed on (whether or not the other side did too).
    crashed: dict[str, list[str]] = field(default_factory=dict)

    def figures(self, name: str) -> tuple[float, float, float, float]:
        """Median, p95, max and total CPU seconds of side ``name``."""
        t = self.times[name]
        return statistics.median(t), percentile(t, 0.95), max(t), sum(t)

    def print_summary(self) -> None:
        for name, t in self.times.items():
            median, p95, most, total = self.figures(name)
            print(f"{name}: {len(t)} requests, CPU median {median:.3f} s, "
                  f"p95 {p95:.3f} s, max {most:.3f} s, total {total:.1f} s")
        for name, counts in self.work.items():
            print(f"{name}: work " + ", ".join(f"{k} {v}" for k, v in counts.items()))
        for name, labels in self.crashed.items():
            if labels:
                print(f"{name}: crashed on {len(labels)}: {', '.join(labels)}")
        if self.compared:
            print(f"identical: {self.requests - len(self.mismatches)}/{self.requests}")
            for label, why in self.mismatches:
                print(f"  {label}: {why}")


def compare(todo: list[dict], baseline: str | None = None, env: dict[str, str] | None = None,
            save: Path | None = None, reference: Path | None = None, echo=None, scope: str = "aep",
            split: bool = False) -> Comparison:
    """Solve ``todo`` (:func:`cases`) in a worker on the working tree and, with ``baseline``,
    in one on what that revision solves with (:func:`baseline_tree`'s ``scope``),
    alternating; ``echo`` gets a line per request (printed by default); ``split``: each
    worker times LAPACK and the joint pass too (:class:`SplitClock`)."""
    echo = echo or (lambda line: print(line, flush=True))
    with tempfile.TemporaryDirectory() as tmp:
        sides = [Worker("new", None, env, split)]
        if baseline:
            sides.insert(0, Worker("old", baseline_tree(baseline, Path(tmp), scope), split=split))
        times: dict[str, list[float]] = {w.name: [] for w in sides}
        splits: dict[str, list[dict[str, float]]] = {w.name: [] for w in sides} if split else {}
        mismatches = []
        crashed: dict[str, list[str]] = {w.name: [] for w in sides}
        work: dict[str, dict[str, int]] = {}
        if save:
            save.mkdir(parents=True, exist_ok=True)
        for i, case in enumerate(todo):
            # alternate which side goes first, so neither always runs on a warmer machine
            order = sides if i % 2 == 0 else sides[::-1]
            answers = {w.name: w.solve(case) for w in order}
            for name, answer in answers.items():
                if name not in times:
                    continue
                times[name].append(answer["seconds"])
                if "crashed" in answer["result"]:
                    crashed[name].append(case["label"])
                if split:
                    splits[name].append(answer["split"])
                if save:
                    path = save / f"{case['label'].replace('/', '_')}.{name}.json"
                    path.write_text(json.dumps(answer["result"], indent=1, sort_keys=True))
            if reference:
                stem = reference / case["label"].replace("/", "_")
                saved = next((p for p in (Path(f"{stem}.new.json"), Path(f"{stem}.old.json")) if p.exists()), None)
                if saved is not None:
                    answers["old"] = {"seconds": float("nan"), "result": json.loads(saved.read_text())}
            line = "  ".join(f"{name} {answers[name]['seconds']:7.3f}s" for name in answers)
            same = ""
            for name, answer in answers.items():
                for count in WORK_COUNTS:
                    work.setdefault(name, dict.fromkeys(WORK_COUNTS, 0))[count] += \
                        answer["result"].get("stats", {}).get(count, 0)
            if len(answers) == 2:
                old, new = decided(answers["old"]["result"]), decided(answers["new"]["result"])
                if old == new:
                    same = "same"
                else:
                    why = [k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
                    detail = ""
                    if "program" in old and "program" in new and old["program"] != new["program"]:
                        detail = amount_difference(old["program"], new["program"])
                    same = f"DIFFERENT ({', '.join(why)}) {detail}"
                    mismatches.append((case["label"], same))
            echo(f"{i:3d} {case['label']:<52} {line}  {digest(decided(answers['new']['result']))}  {same}")
        for w in sides:
            w.close()
    return Comparison(times, mismatches, work, len(todo), bool(baseline or reference), splits, crashed)


if __name__ == "__main__":
    main()
