"""The offline interpreter on requests phrased the way people write them.

Reads the two halves of the request table of the offline plugin
(plugins/parsel-offline/tests/data/requests_dev.tsv and requests_held_out.tsv: the
bundled chair, table, cabinet and shelf, and three ShapeAssembly programs with their
geometric labels), asks the offline provider for each request's seed edit through the
whole language layer, and prints accuracy per kind on each half: op, part, axis, sign,
all together (every op right, none repeated or added), refusals and crashes; then every
refusal with its reason and every miss. The held-out half is never used to tune the
interpreter; the development half is.

    python benchmarks/bench_language.py [--misses]
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

from parsel_offline.scoring import HALVES, METRICS, accuracy, read_cases, run_cases


def table(name: str, outcomes) -> None:
    by_kind = defaultdict(list)
    for outcome in outcomes:
        by_kind[outcome.case.kind].append(outcome)
    header = f"{'kind':<12} {'n':>4} " + " ".join(f"{m:>6}" for m in METRICS) + f" {'refused':>8} {'crashed':>8}"
    print(f"\n{name} half ({len(outcomes)} requests)")
    print(header)
    print("-" * len(header))
    for kind, rows in [*sorted(by_kind.items()), ("ALL", outcomes)]:
        cells = " ".join(f"{100 * accuracy(rows, m):5.1f}%" for m in METRICS)
        refused = sum(1 for o in rows if o.refused is not None)
        crashed = sum(1 for o in rows if o.crashed is not None)
        print(f"{kind:<12} {len(rows):>4} {cells} {refused:>8} {crashed:>8}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--misses", action="store_true", help="also list every miss and refusal")
    args = parser.parse_args()
    results = {}
    for name, path in HALVES.items():
        started = time.process_time()
        results[name] = run_cases(read_cases(path))
        print(f"{name}: {len(results[name])} requests in {time.process_time() - started:.1f} s CPU")
    for name, outcomes in results.items():
        table(name, outcomes)
    print("\nall together: " + ", ".join(f"{name} {100 * accuracy(o, 'all'):.1f}%" for name, o in results.items()))
    for name, outcomes in results.items():
        refusals = [o for o in outcomes if o.refused is not None]
        print(f"\n{name}: refusals ({len(refusals)}), each with its reason")
        for o in refusals:
            expected = "expected" if not o.case.expected else "WRONG"
            print(f"  [{o.case.kind}, {expected}] {o.case.shape}: {o.case.request!r} -> {o.refused}")
        crashes = [o for o in outcomes if o.crashed is not None]
        for o in crashes:
            print(f"  CRASH {o.case.shape}: {o.case.request!r} -> {o.crashed}")
        if args.misses:
            print(f"{name}: misses")
            for o in outcomes:
                if not o.scores["all"] and o.refused is None:
                    print(f"  [{o.case.kind}] {o.case.shape}: {o.case.request!r} -> {o.got} "
                          f"(line {o.case.line})")


if __name__ == "__main__":
    main()
