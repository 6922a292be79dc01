"""Edit propagation at scale: ShapeAssembly val shapes x 3 seed edits, both CAS backends.

For a fixed sample of val-split programs (default 100, spread over chair, table and
storage) the script loads each shape (executing the program and detecting relations),
makes three deterministic seed edits — widen the largest part, raise the highest part,
lengthen a random part from its bottom — and runs AEP with each backend. It prints the
median and 95th-percentile time per request, candidates screened per second, and the
fraction of relations kept; then the cost of one slider step: evaluating the compiled
AEP program versus re-solving placements with the ``online`` solver.

Run: ``python benchmarks/bench_aep.py [--shapes 100] [--data ../shared/data/shapeassembly]``
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from parsel_core.interfaces import SolveRequest
from parsel_core.loading import load_shape
from parsel_core.plugins import get_cas_backend, solvers
from parsel_core.program import Program, compile_program
from parsel_core.report import check_program

ROOT = Path(__file__).resolve().parents[1]
CATEGORIES = ("chair", "table", "storage")


def sample_programs(data: Path, count: int, seed: int = 0) -> list[Path]:
    rng = np.random.default_rng(seed)
    per = [count // 3 + (1 if i < count % 3 else 0) for i in range(3)]
    out = []
    for category, n in zip(CATEGORIES, per):
        ids = (data / "splits" / category / "val.txt").read_text().split()
        out += [data / category / f"{i}.txt" for i in rng.choice(ids, size=n, replace=False)]
    return out


def seeds_for(shape) -> list[str]:
    """Three deterministic seed edits in the program text form."""
    parts = sorted(shape.parts.values(), key=lambda p: p.id)
    rng = np.random.default_rng(len(parts) * 7919 + sum(map(ord, shape.name)))

    def quoted(pid: str) -> str:
        return repr(pid)

    largest = max(parts, key=lambda p: (float(np.prod(p.hexahedron.extents)), p.id))
    highest = max(parts, key=lambda p: (float(p.hexahedron.corners[:, 1].max()), p.id))
    other = parts[int(rng.integers(len(parts)))]
    c = [float(v) for v in largest.hexahedron.center]
    bottom = float(other.hexahedron.corners[:, 1].min())
    oc = [float(v) for v in other.hexahedron.center]
    return [
        f"scale_1d({quoted(largest.id)}, origin=({c[0]!r}, {c[1]!r}, {c[2]!r}), dir=(1, 0, 0), amount=x)",
        f"translate({quoted(highest.id)}, dir=(0, 1, 0), amount=0.2 * x)",
        f"scale_1d({quoted(other.id)}, origin=({oc[0]!r}, {bottom!r}, {oc[2]!r}), dir=(0, 1, 0), amount=0.5 * x)",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", type=int, default=100)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "shapeassembly")
    parser.add_argument("--backends", default="symengine,sympy")
    parser.add_argument("--slider-requests", type=int, default=10)
    args = parser.parse_args()
    aep = solvers()["aep"]
    paths = sample_programs(args.data, args.shapes)
    started = time.perf_counter()
    shapes = [load_shape(str(p)) for p in paths]
    load_time = time.perf_counter() - started
    requests = [(shape, seed) for shape in shapes for seed in seeds_for(shape)]
    mix = ", ".join(f"{sum(s.metadata.get('category') == c for s in shapes)} {c}" for c in CATEGORIES)
    print(f"{len(shapes)} shapes ({mix}), "
          f"{len(requests)} requests; parts per shape: median {statistics.median(len(s.parts) for s in shapes):.0f}, "
          f"max {max(len(s.parts) for s in shapes)}; relations: median "
          f"{statistics.median(len(s.relations) for s in shapes):.0f}, max {max(len(s.relations) for s in shapes)}; "
          f"loading + detection {load_time:.1f} s")
    rows = []
    programs = {}
    for backend in args.backends.split(","):
        get_cas_backend(backend)
        times, screened, kept, total, failures = [], 0, 0, 0, 0
        for i, (shape, seed) in enumerate(requests):
            request = SolveRequest(shape, Program.from_text(seed), options={"backend": backend})
            clock = time.perf_counter()
            try:
                result = aep.run(request)
            except Exception as exc:  # recorded, not fatal: a benchmark reports failures
                failures += 1
                print(f"  {backend}: {shape.name}: {type(exc).__name__}: {exc}")
                continue
            times.append(time.perf_counter() - clock)
            screened += result.stats["candidates_screened"]
            counts = check_program(shape, result.program).counts()
            kept += counts["kept"]
            total += sum(counts.values())
            programs.setdefault(i, result.program)
        times.sort()
        rows.append((backend, len(times), failures, statistics.median(times), times[int(0.95 * (len(times) - 1))],
                     screened / sum(times), kept / max(total, 1)))
    print(f"\n{'backend':<11}{'requests':>9}{'failed':>8}{'median s':>10}{'p95 s':>9}{'cand/s':>10}{'kept':>8}")
    for backend, n, failed, median, p95, rate, kept in rows:
        print(f"{backend:<11}{n:>9}{failed:>8}{median:>10.3f}{p95:>9.3f}{rate:>10.0f}{kept:>8.1%}")
    if len(rows) == 2:
        print(f"median ratio {rows[1][0]}/{rows[0][0]}: {rows[1][3] / rows[0][3]:.2f}x")

    online = solvers()["online"]
    aep_steps, online_steps = [], []
    backend = get_cas_backend(args.backends.split(",")[0])
    for i in sorted(programs)[:: max(1, len(programs) // args.slider_requests)][: args.slider_requests]:
        shape, seed = requests[i]
        program = programs[i]
        compiled = compile_program(program, shape, backend)
        hi = program.parameters[0].hi
        values = np.linspace(0, hi, 20)
        clock = time.perf_counter()
        for v in values:
            compiled({"x": float(v)})
        aep_steps.append((time.perf_counter() - clock) / len(values))
        editor = online.editor(SolveRequest(shape, Program.from_text(seed)))
        clock = time.perf_counter()
        for v in values[:5]:
            editor.corners({"x": float(v)})
        online_steps.append((time.perf_counter() - clock) / 5)
    a, o = statistics.median(aep_steps), statistics.median(online_steps)
    print(f"\none slider step over {len(aep_steps)} requests (median): AEP program {a * 1e3:.2f} ms, "
          f"online re-solve {o * 1e3:.1f} ms, ratio {o / a:.0f}x")


if __name__ == "__main__":
    main()
