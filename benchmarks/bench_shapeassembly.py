"""ShapeAssembly executor against the reference interpreter, over the whole corpus.

Every program of every category (train and val splits) is executed by
``parsel_shapeassembly``; for train programs the leaf cuboids are compared
with ``reference/<category>_train.json``, the output of the interpreter
published with the ShapeAssembly paper.  A program matches when both give the
same number of cuboids and they pair up one-to-one (greedy nearest, order and
names ignored) with every corner, rounded to 1e-5 like the reference, within
``--tol`` (1e-4).  Time is the median wall time of parsing plus executing one
program (relations included), measured inside the worker processes.

Usage::

    python benchmarks/bench_shapeassembly.py [--data DIR] [--jobs N] [--show N]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "shapeassembly"
CATEGORIES = ("chair", "table", "storage")

try:
    from parsel_shapeassembly.compare import reference_error
    from parsel_shapeassembly.interpreter import ShapeAssemblyError, execute_file
except ImportError:  # running from a checkout without the plugin installed
    sys.path.insert(0, str(ROOT / "plugins" / "parsel-shapeassembly"))
    from parsel_shapeassembly.compare import reference_error
    from parsel_shapeassembly.interpreter import ShapeAssemblyError, execute_file


@dataclass(frozen=True)
class Job:
    """One program to run; ``reference`` is None for val programs."""

    category: str
    program_id: str
    path: str
    reference: list[list[list[float]]] | None


@dataclass(frozen=True)
class Outcome:
    category: str
    program_id: str
    executed: bool
    matched: bool | None
    error: str
    worst: float
    seconds: float


def run_job(job: Job, tol: float) -> Outcome:
    start = time.perf_counter()
    try:
        program = execute_file(job.path)
    except ShapeAssemblyError as exc:
        return Outcome(job.category, job.program_id, False, None, str(exc), float("inf"), 0.0)
    seconds = time.perf_counter() - start
    if job.reference is None:
        return Outcome(job.category, job.program_id, True, None, "", 0.0, seconds)
    worst = reference_error(program, job.reference)
    return Outcome(job.category, job.program_id, True, worst <= tol, "", worst, seconds)


def _run_chunk(args: tuple[list[Job], float]) -> list[Outcome]:
    jobs, tol = args
    return [run_job(job, tol) for job in jobs]


def load_jobs(data: Path) -> list[Job]:
    jobs: list[Job] = []
    for category in CATEGORIES:
        reference = json.loads((data / "reference" / f"{category}_train.json").read_text(encoding="utf-8"))
        for split in ("train", "val"):
            ids = (data / "splits" / category / f"{split}.txt").read_text(encoding="utf-8").split()
            for pid in ids:
                ref = None
                if split == "train":
                    ref = [c["corners"] for c in reference[pid]]
                jobs.append(Job(category, pid, str(data / category / f"{pid}.txt"), ref))
    return jobs


def run_all(jobs: list[Job], workers: int, tol: float) -> list[Outcome]:
    chunk = 64
    chunks = [(jobs[i : i + chunk], tol) for i in range(0, len(jobs), chunk)]
    if workers <= 1:
        return [o for c in chunks for o in _run_chunk(c)]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return [o for part in pool.map(_run_chunk, chunks) for o in part]


def report(outcomes: list[Outcome], show: int) -> str:
    rows = defaultdict(list)
    for o in outcomes:
        rows[o.category].append(o)
    header = (
        f"{'category':<9} {'programs':>8} {'executed':>8} {'train':>6} {'match':>6} {'match %':>8} {'median ms':>9}"
    )
    lines = [header, "-" * len(header)]
    for category in (*CATEGORIES, "all"):
        group = outcomes if category == "all" else rows[category]
        train = [o for o in group if o.matched is not None]
        matched = sum(1 for o in train if o.matched)
        times = [o.seconds * 1000 for o in group if o.executed]
        pct = 100.0 * matched / len(train) if train else float("nan")
        median = statistics.median(times) if times else float("nan")
        executed = sum(1 for o in group if o.executed)
        lines.append(
            f"{category:<9} {len(group):>8} {executed:>8} {len(train):>6} {matched:>6} {pct:>8.2f} {median:>9.1f}"
        )
    failures = [o for o in outcomes if not o.executed]
    mismatches = sorted((o for o in outcomes if o.matched is False), key=lambda o: -o.worst)
    if failures:
        lines.append(f"\nfailed to execute ({len(failures)}):")
        lines.extend(f"  {o.error}" for o in failures[:show])
    if mismatches:
        lines.append(f"\nmismatching train programs ({len(mismatches)}), largest corner error first:")
        lines.extend(f"  {o.category}/{o.program_id}: {o.worst:.5f}" for o in mismatches[:show])
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="corpus directory (default: %(default)s)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all CPUs)")
    parser.add_argument("--tol", type=float, default=1e-4, help="corner tolerance (default: %(default)s)")
    parser.add_argument("--show", type=int, default=20, help="failures/mismatches to list (default: %(default)s)")
    args = parser.parse_args(argv)
    if not (args.data / "reference").is_dir():
        print(f"no ShapeAssembly corpus at {args.data} (use --data)", file=sys.stderr)
        return 2
    start = time.perf_counter()
    jobs = load_jobs(args.data)
    outcomes = run_all(jobs, args.jobs, args.tol)
    print(report(outcomes, args.show))
    print(f"\n{len(jobs)} programs in {time.perf_counter() - start:.1f} s with {args.jobs} worker(s)")
    return 0 if all(o.executed for o in outcomes) else 1


if __name__ == "__main__":
    raise SystemExit(main())
