"""The identity program keeps every detected relation, on the whole ShapeAssembly corpus.

Each program of every category and split is loaded (executed, then relations detected
at the configured tolerance, 1% of the diagonal) and checked under the program with no
ops by the same check ``parsel check`` and AEP use (1e-4 of the diagonal, 50 samples).
Relations are anchored at rest (docs/relations.md), so the line to read is
``kept 100.00%``; anything else names the program and relation.

Usage::

    python benchmarks/bench_identity.py [--data DIR] [--jobs N] [--limit N]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "shapeassembly"
CATEGORIES = ("chair", "table", "storage")


def check_one(path: str) -> tuple[str, Counter, list[str], str | None, float]:
    """Relation counts by kind, the relations the identity breaks, an error, CPU seconds."""
    from parsel_core.loading import load_shape
    from parsel_core.program import Program
    from parsel_core.report import check_program

    clock = time.process_time()
    try:
        shape = load_shape(path)
        report = check_program(shape, Program(()))
    except Exception as exc:  # a benchmark reports failures instead of stopping
        return path, Counter(), [], f"{type(exc).__name__}: {exc}", time.process_time() - clock
    kinds = Counter(r.kind for r in report.relations)
    broken = [r.id for r in report.relations if r.state != "kept"]
    return path, kinds, broken, None, time.process_time() - clock


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--limit", type=int, default=0, help="programs per category (0: all)")
    args = parser.parse_args()
    paths = []
    for category in CATEGORIES:
        files = sorted((args.data / category).glob("*.txt"))
        paths += [str(p) for p in (files[: args.limit] if args.limit else files)]
    kinds: Counter = Counter()
    broken: list[tuple[str, str]] = []
    errors: list[tuple[str, str]] = []
    seconds = []
    started = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for path, counts, lost, error, cpu in pool.map(check_one, paths, chunksize=16):
            kinds.update(counts)
            broken += [(path, rid) for rid in lost]
            if error:
                errors.append((path, error))
            seconds.append(cpu)
    total = sum(kinds.values())
    print(f"{len(paths)} programs, {total} detected relations "
          f"({', '.join(f'{k} {v}' for k, v in kinds.most_common())}); "
          f"{time.perf_counter() - started:.0f} s wall on {args.jobs} workers, "
          f"median {statistics.median(seconds):.3f} s CPU per program")
    print(f"identity program: kept {(total - len(broken)) / max(total, 1):.2%} "
          f"({len(broken)} broken), {len(errors)} programs failed to load")
    for path, rid in broken[:20]:
        print(f"  broken: {path} {rid}")
    for path, error in errors[:20]:
        print(f"  failed: {path}: {error}")


if __name__ == "__main__":
    main()
