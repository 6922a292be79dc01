"""Round trip of edited shapes through ShapeAssembly: export, execute, compare corners.

For a fixed sample of val-split programs (default 200, spread over chair, table and
storage) the script makes a designer seed edit (``designer_seeds.py``, alternately:
widen the seat/top about its centre, or lengthen the legs from their bottom), completes it
with AEP, evaluates the program at x = 0.5 (or the top of its range when that is
lower), writes the edited shape as a ShapeAssembly program, executes the written
program with parsel's interpreter and compares every cuboid's corners with the edited
corners. A part counts as matched when every corner comes back within 1e-6 of the
shape's diagonal; parts the edit turned into non-cuboids are written as their
best-fitting cuboid and counted apart. It prints the match rate, the non-cuboid parts,
the statements written and the export time (CPU). A shape whose seed AEP cannot solve
is reported and replaced by the next program of its category, so that the count of
exported shapes is the one asked for.

Run: ``python benchmarks/bench_sa_roundtrip.py [--shapes 200] [--data ../shared/data/shapeassembly]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from designer_seeds import designer_seeds, sample_programs, seed_of  # noqa: E402

from parsel_core.interfaces import SolveRequest  # noqa: E402
from parsel_core.loading import load_shape  # noqa: E402
from parsel_core.plugins import solvers  # noqa: E402
from parsel_core.program import Program, evaluate  # noqa: E402
from parsel_shapeassembly.exporter import _executed_corners, _set_distance, export_program  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MATCH = 1e-6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", type=int, default=200)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "shapeassembly")
    parser.add_argument("--value", type=float, default=0.5)
    args = parser.parse_args()
    aep = solvers()["aep"]
    spare = sample_programs(args.data, args.shapes + 30)
    paths = sample_programs(args.data, args.shapes)
    spares = {c: [q for q in spare if q.parent.name == c and q not in paths] for c in ("chair", "table", "storage")}
    matched = cuboid_parts = non_cuboid = 0
    failures: list[str] = []
    misses: list[str] = []
    worst = 0.0
    cpu: list[float] = []
    statements: Counter = Counter()
    categories: Counter = Counter()
    queue = list(paths)
    i = 0
    while queue:
        path = queue.pop(0)
        i += 1
        shape = load_shape(str(path))
        # alternate the two edits over the sample so both are measured (no legs: widen)
        seed = seed_of(designer_seeds(shape), *(("widen-",) if i % 2 else ("lengthen-legs", "widen-"))).seed
        try:
            program = aep.run(SolveRequest(shape, Program.from_text(seed))).program
        except Exception as exc:  # recorded, not fatal: a benchmark reports failures
            failures.append(f"{shape.name}: solve (replaced): {type(exc).__name__}: {exc}")
            if spares[path.parent.name]:
                queue.append(spares[path.parent.name].pop(0))
            continue
        x = min(args.value, program.parameters[0].hi)
        evaluation = evaluate(program, shape, {program.parameters[0].name: x})
        clock = time.process_time()
        try:
            result = export_program(shape, evaluation)
        except Exception as exc:
            failures.append(f"{shape.name}: export: {type(exc).__name__}: {exc}")
            continue
        cpu.append(time.process_time() - clock)
        categories[shape.metadata.get("category")] += 1
        statements.update(result.statements)
        got = _executed_corners(result.text)
        tol = MATCH * shape.size
        for key, expected_corners in result.expected.items():
            if key in result.non_cuboids:
                non_cuboid += 1
                continue
            cuboid_parts += 1
            name = result.names.get(key)
            error = _set_distance(got[name], expected_corners) if name in got else float("inf")
            worst = max(worst, error / shape.size)
            if error <= tol:
                matched += 1
            else:
                misses.append(f"{shape.name} {key}: {error / shape.size:.2e} of the diagonal")
        for key, deviation in result.non_cuboids.items():
            print(f"  non-cuboid: {shape.name} {key}: best-fitting cuboid {deviation / shape.size:.2e} of the "
                  f"diagonal away ({seed.split('(')[0]})")
    print(f"\n{len(cpu)} shapes exported ({', '.join(f'{n} {c}' for c, n in sorted(categories.items()))}), "
          f"{len(failures)} failed; edits at x = {args.value:g} (or the top of a shorter range)")
    for line in failures:
        print(f"  failed: {line}")
    print(f"\n{'parts that stayed cuboids':<34}{cuboid_parts:>8}")
    print(f"{'  corners back within 1e-6 diag':<34}{matched:>8}  ({matched / max(cuboid_parts, 1):.2%})")
    print(f"{'  worst corner error / diag':<34}{worst:>8.1e}")
    print(f"{'parts turned into non-cuboids':<34}{non_cuboid:>8}  (written as best-fitting cuboids)")
    print(f"statements written: {dict(statements)}")
    print(f"export CPU per shape: median {statistics.median(cpu) * 1e3:.1f} ms, "
          f"p95 {np.percentile(cpu, 95) * 1e3:.1f} ms")
    for line in misses[:20]:
        print(f"  miss: {line}")


if __name__ == "__main__":
    main()
