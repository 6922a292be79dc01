"""Edit propagation on large synthetic assemblies: CPU time against parts and relations.

For each assembly of :mod:`parsel_core.synthetic` (a bookcase of N boards, a stadium row
of N chairs in translation groups, a long table of N legs) and each size, the script
runs AEP on the assembly's seed edit (``parsel_core.synthetic.SEEDS``) and prints the
CPU time of the solve (``time.process_time``; the median of ``--repeat`` runs for shapes
up to 50 parts, one run above), the program's size and the relation report. Then, per
assembly and over all runs, the growth exponent ``k`` of ``CPU ~ relations^k`` (a
least-squares line through log CPU against log relations), and the goals: 100, 200 and
500 parts solved in at most 2, 5 and 15 s of CPU. ``--png FILE`` also draws CPU against
relations on log-log axes.

    python benchmarks/bench_scale.py [--parts 10 20 50 100 200 500] [--assemblies bookcase stadium long_table]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from parsel_core.interfaces import SolveRequest
from parsel_core.plugins import get_cas_backend, solvers
from parsel_core.report import check_program
from parsel_core.synthetic import GENERATORS, SEEDS, assembly
from parsel_core.textform import seed_from_text

GOALS_S = {100: 2.0, 200: 5.0, 500: 15.0}


def solve_cpu(shape, seed, backend: str | None, repeat: int):
    """(median CPU seconds of the solve, the last result)."""
    solver = solvers()["aep"]
    times, result = [], None
    for _ in range(repeat):
        started = time.process_time()
        result = solver.run(SolveRequest(shape, seed, {}, (), {"backend": backend}))
        times.append(time.process_time() - started)
    return statistics.median(times), result


def exponent(relations: list[int], cpu: list[float]) -> float:
    """Slope of log CPU against log relations (least squares)."""
    if len(set(relations)) < 2:
        return float("nan")
    return float(np.polyfit(np.log(relations), np.log(cpu), 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", type=int, nargs="+", default=[10, 20, 50, 100, 200, 500])
    parser.add_argument("--assemblies", nargs="+", default=list(GENERATORS), choices=list(GENERATORS))
    parser.add_argument("--repeat", type=int, default=3, help="runs per size up to 50 parts (median)")
    parser.add_argument("--backend", default=None, help="CAS backend (default: configured)")
    parser.add_argument("--png", metavar="FILE", help="also plot CPU against relations (log-log) to FILE")
    args = parser.parse_args()
    backend = get_cas_backend(args.backend).name
    solve_cpu(assembly("bookcase", 10), seed_from_text(SEEDS["bookcase"]), backend, 1)  # imports, caches
    print(f"AEP on synthetic assemblies, CAS backend {backend}; CPU = time.process_time of solver.run")
    print(f"\n{'assembly':<12}{'parts':>6}{'relations':>10}{'solve CPU':>11}{'check CPU':>11}{'ops':>5}"
          f"{'kept':>6}{'broken':>7}{'rejected':>9}")
    rows: list[tuple[str, int, int, float]] = []
    for name in args.assemblies:
        seed = seed_from_text(SEEDS[name])
        for parts in args.parts:
            shape = assembly(name, parts)
            cpu, result = solve_cpu(shape, seed, backend, args.repeat if len(shape.parts) <= 50 else 1)
            started = time.process_time()
            counts = check_program(shape, result.program, ()).counts()
            check = time.process_time() - started
            rows.append((name, len(shape.parts), len(shape.relations), cpu))
            print(f"{name:<12}{len(shape.parts):>6}{len(shape.relations):>10}{cpu:>10.2f}s{check:>10.2f}s"
                  f"{len(result.program.ops):>5}{counts['kept']:>6}{counts['broken']:>7}{len(result.rejected):>9}")
    print("\ngrowth: CPU ~ relations^k")
    for name in args.assemblies:
        mine = [r for r in rows if r[0] == name]
        print(f"  {name:<12} k = {exponent([r[2] for r in mine], [r[3] for r in mine]):.2f}")
    print(f"  {'all':<12} k = {exponent([r[2] for r in rows], [r[3] for r in rows]):.2f}")
    print("\ngoals (solve CPU):")
    for parts, goal in GOALS_S.items():
        for name, n, _, cpu in rows:
            if abs(n - parts) <= 2:
                print(f"  {name:<12}{n:>4} parts: {cpu:6.2f} s <= {goal:g} s  {'ok' if cpu <= goal else 'NOT MET'}")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(figsize=(6, 4))
        for name in args.assemblies:
            mine = [r for r in rows if r[0] == name]
            axes.loglog([r[2] for r in mine], [r[3] for r in mine], "o-", label=name)
        axes.set_xlabel("relations")
        axes.set_ylabel("AEP solve, CPU s")
        axes.legend()
        figure.tight_layout()
        figure.savefig(args.png, dpi=120)
        print(f"\nplot: {args.png}")


if __name__ == "__main__":
    main()
