"""Batch throughput: ShapeAssembly val shapes in expert mode on 1 and 2 local worker processes.

For a fixed sample of val-split programs (default 200, spread evenly over chair, table
and storage) the script writes one expert-mode case per shape, whose seed widens the
shape's largest part along x about its centre, and runs the cases with ``parsel
batch`` machinery (:func:`parsel_batch.batch.run_batch`) once per worker count into a
fresh output folder. It prints the wall time, the throughput (cases per second), the
failures and the speed-up over one worker, and checks that the outputs of all runs are
byte-identical (batch outputs are deterministic whatever the parallelism).

Both runs use worker processes (the 1-worker run too), so both pay the same start-up
and the speed-up measures parallelism alone. Loading the shapes to choose the seeds is
not timed.

Run: ``python benchmarks/bench_batch.py [--shapes 200] [--workers 1,2] [--data ../shared/data/shapeassembly]``
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CATEGORIES = ("chair", "table", "storage")


def require_shapeassembly_loader(sample: Path) -> None:
    """Exit with a clear message when no installed loader reads ShapeAssembly programs."""
    from parsel_core.plugins import shape_loaders

    if not any(loader.can_load(sample) for loader in shape_loaders()):
        sys.exit("bench_batch: no installed shape loader reads ShapeAssembly programs (.txt). Install the "
                 "ShapeAssembly plugin first: pip install -e plugins/parsel-shapeassembly")


def sample_programs(data: Path, count: int, seed: int = 0) -> list[Path]:
    """``count`` val programs, as evenly spread over the categories as their sizes allow."""
    rng = np.random.default_rng(seed)
    per = [count // len(CATEGORIES) + (1 if i < count % len(CATEGORIES) else 0) for i in range(len(CATEGORIES))]
    out = []
    for category, n in zip(CATEGORIES, per):
        split = data / "splits" / category / "val.txt"
        if not split.exists():
            sys.exit(f"bench_batch: {split} not found (use --data to point at the ShapeAssembly data)")
        ids = sorted(split.read_text().split())
        out += [data / category / f"{i}.txt" for i in rng.choice(ids, size=min(n, len(ids)), replace=False)]
    return out


def widen_largest_part(shape) -> str:
    """The deterministic seed: scale the largest part (by box volume) by x along x, about its centre."""
    part = max(shape.parts.values(), key=lambda p: (float(np.prod(p.hexahedron.extents)), p.id))
    cx, cy, cz = (float(v) for v in part.hexahedron.center)
    return f"scale_1d({part.id!r}, origin=({cx!r}, {cy!r}, {cz!r}), dir=(1, 0, 0), amount=x)"


def write_cases(paths: list[Path], target: Path) -> int:
    from parsel_core.loading import load_shape

    lines = []
    for path in paths:
        shape = load_shape(str(path))
        case_id = f"{path.parent.name}-{path.stem}"
        lines.append(json.dumps({"id": case_id, "shape": str(path), "seed": widen_largest_part(shape)}))
    target.write_text("\n".join(lines) + "\n")
    return len(lines)


def folder_contents(outdir: Path) -> dict[str, dict[str, bytes]]:
    return {d.name: {f.name: f.read_bytes() for f in d.iterdir()} for d in outdir.iterdir() if d.is_dir()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", type=int, default=200)
    parser.add_argument("--workers", default="1,2", help="worker counts to compare (the first is the baseline)")
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "shapeassembly")
    parser.add_argument("--progress", action="store_true", help="show the progress bar of each run")
    args = parser.parse_args()
    try:
        from parsel_batch.batch import run_batch
        from parsel_batch.cases import read_cases
    except ImportError:
        sys.exit("bench_batch: the parsel-batch plugin is not installed: pip install -e plugins/parsel-batch")
    paths = sample_programs(args.data, args.shapes)
    require_shapeassembly_loader(paths[0])
    counts = [int(w) for w in args.workers.split(",")]
    with tempfile.TemporaryDirectory(prefix="bench_batch.") as tmp:
        tmp_path = Path(tmp)
        started = time.perf_counter()
        n = write_cases(paths, tmp_path / "cases.jsonl")
        cases = read_cases(tmp_path / "cases.jsonl")
        mix = ", ".join(f"{sum(p.parent.name == c for p in paths)} {c}" for c in CATEGORIES)
        print(f"{n} ShapeAssembly val shapes ({mix}); seed: widen the largest part; "
              f"cases written in {time.perf_counter() - started:.1f} s")
        rows, contents = [], []
        for workers in counts:
            outdir = tmp_path / f"out-{workers}"
            clock = time.perf_counter()
            summary = run_batch(cases, outdir, workers=workers, progress=args.progress)
            wall = time.perf_counter() - clock
            times = sorted(r["elapsed_s"] for r in summary.records if r.get("elapsed_s") is not None)
            rows.append((workers, wall, n / wall, summary.failed, float(np.median(times)) if times else float("nan")))
            contents.append(folder_contents(outdir))
            failures = [r for r in summary.records if r.get("status") != "ok"]
    base = rows[0][1]
    print(f"\n{'workers':>7}{'wall s':>9}{'cases/s':>9}{'failed':>8}{'median case s':>15}{'speed-up':>10}")
    for workers, wall, rate, failed, median in rows:
        print(f"{workers:>7}{wall:>9.1f}{rate:>9.2f}{failed:>8}{median:>15.3f}{base / wall:>9.2f}x")
    for record in failures:
        error = record.get("error") or {}
        print(f"failed: {record['id']}: {error.get('type')}: {error.get('message')}")
    identical = all(c == contents[0] for c in contents[1:])
    print(f"outputs identical across runs: {'yes' if identical else 'NO'}")
    if not identical:
        sys.exit(1)


if __name__ == "__main__":
    main()
