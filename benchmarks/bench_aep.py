"""Edit propagation at scale: ShapeAssembly val shapes x 3 seed edits, both CAS backends.

For a fixed sample of val-split programs (default 100, spread over chair, table and
storage) the script loads each shape (executing the program and detecting relations),
makes three deterministic seed edits — widen the largest part, raise the highest part,
lengthen a random part from its bottom — and runs AEP with each backend. It prints the
median and 95th-percentile time per request, candidates screened per second, and the
fraction of relations kept; then the cost of one slider step: evaluating the compiled
AEP program versus re-solving placements with the ``online`` solver.

With ``--baseline REV`` the random-seed requests are also solved side by side by REV's
``plugins/parsel-aep`` and the working tree (``bench_aep_speed.py``'s alternating worker
processes): both sides' CPU median and p95 from the same run, and whether every program
is the same (exit status 1 if not); ``--baseline-core`` takes REV's ``parsel_core`` too,
``--baseline-tree`` its whole tree (core and every plugin: for a revision whose core the
working tree's other plugins no longer run on).

Run: ``python benchmarks/bench_aep.py [--shapes 100] [--data ../shared/data/shapeassembly] [--baseline REV]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from parsel_core.interfaces import SolveRequest
from parsel_core.loading import load_shape, parse_options
from parsel_core.plugins import get_cas_backend, solvers
from parsel_core.program import Program, compile_program
from parsel_core.report import check_program

sys.path.insert(0, str(Path(__file__).resolve().parent))
from designer_seeds import designer_seeds, sample_programs  # noqa: E402

from parsel_aep.candidates import candidate_family  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CATEGORIES = ("chair", "table", "storage")


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


RELATION_KINDS = ("attachment-point", "attachment-line", "attachment-face", "attachment-volume", "ground",
                  "reflection", "translation", "rotation")


def relation_kind(relation) -> str:
    """The loss table's kind: attachments by contact, other relations by their kind."""
    return f"attachment-{relation.contact}" if relation.kind == "attachment" else relation.kind


@dataclass
class Case:
    shape: object
    kind: str
    seed: str
    breaks: tuple[str, ...] = ()


@dataclass
class Outcome:
    case: Case
    kept: int = 0
    total: int = 0
    seconds: float = 0.0
    crashed: str | None = None
    losses: list[tuple[str, str, str]] = field(default_factory=list)  # (relation kind, op family, reason)
    program: Program | None = None


def run_case(case: Case, options: dict) -> Outcome:
    """Solve one case and check it: kept relations over those that hold at rest."""
    aep = solvers()["aep"]
    outcome = Outcome(case)
    try:
        request = SolveRequest(case.shape, Program.from_text(case.seed), breaks=case.breaks, options=options)
        clock = time.process_time()
        result = aep.run(request)
        outcome.seconds = time.process_time() - clock
        report = check_program(case.shape, result.program, breaks=case.breaks)
    except Exception as exc:  # a benchmark reports crashes instead of stopping
        outcome.crashed = f"{type(exc).__name__}: {exc}"
        return outcome
    outcome.program = result.program
    losses = result.stats.get("losses", {})
    for state in report.relations:
        if state.state == "broken_on_purpose":
            continue
        outcome.total += 1
        if state.state == "kept":
            outcome.kept += 1
            continue
        relation = case.shape.relations[state.id]
        reason, part = losses.get(state.id, ("final-check", None))
        outcome.losses.append((relation_kind(relation), op_family(case.shape, result.program, part, relation), reason))
    return outcome


def op_family(shape, program: Program, part: str | None, relation) -> str:
    """The op family of the part that broke a relation: the one the solver names, else the
    last member the program edits (directly or through its group's virtual parent)."""
    members = [part] if part else list(relation.members)
    for member in reversed(members):
        operands = {member, *shape.groups_of(member)} if member in shape.parts else {member}
        ops = [op for op in program.ops if op.operand in operands]
        if ops:
            return "+".join(sorted({candidate_family(op) if op.acts_on == "part" else op.name for op in ops}))
    return "unedited"


def summarise(outcomes: list[Outcome]) -> tuple[float, float, int, int]:
    """Kept share, share of cases keeping everything, crashes, cases."""
    done = [o for o in outcomes if o.crashed is None]
    kept = sum(o.kept for o in done) / max(1, sum(o.total for o in done))
    whole = sum(o.kept == o.total for o in done) / max(1, len(done))
    return kept, whole, len(outcomes) - len(done), len(outcomes)


def print_groups(title: str, outcomes: list[Outcome], key) -> None:
    groups: dict[str, list[Outcome]] = {}
    for o in outcomes:
        groups.setdefault(key(o), []).append(o)
    print(f"\n{title:<22}{'cases':>7}{'kept':>9}{'all kept':>10}{'crashes':>9}{'median s':>10}")
    for name in sorted(groups) + ["all"]:
        chosen = outcomes if name == "all" else groups[name]
        kept, whole, crashes, n = summarise(chosen)
        times = [o.seconds for o in chosen if o.crashed is None] or [0.0]
        print(f"{name:<22}{n:>7}{kept:>9.2%}{whole:>10.1%}{crashes:>9}{statistics.median(times):>10.3f}")


def print_losses(outcomes: list[Outcome]) -> None:
    """Every relation not kept: its kind, the op family that broke it and why."""
    rows = Counter(loss for o in outcomes for loss in o.losses)
    total = sum(rows.values())
    print(f"\n{total} relations not kept")
    if not rows:
        return
    print(f"{'relation kind':<20}{'op family':<26}{'reason':<22}{'count':>7}")
    for (kind, family, reason), n in rows.most_common():
        print(f"{kind:<20}{family[:25]:<26}{reason:<22}{n:>7}")
    for label, index in (("by reason", 2), ("by relation kind", 0)):
        counts = Counter()
        for row, n in rows.items():
            counts[row[index]] += n
        print(f"{label}: " + ", ".join(f"{k} {v}" for k, v in counts.most_common()))
    crashes = [o for o in outcomes if o.crashed]
    for o in crashes[:10]:
        print(f"  crash {o.case.shape.name} {o.case.kind}: {o.crashed[:200]}")


def side_by_side(args: argparse.Namespace, backend: str, extra: dict) -> bool:
    """The random-seed requests solved by ``args.baseline`` and the working tree, alternating
    in two worker processes: both sides' CPU figures from this one run, and whether every
    program, rejection and solver count is the same."""
    import bench_aep_speed

    todo = bench_aep_speed.cases(3 * args.shapes, 0, False, args.data, shapes=args.shapes)
    for case in todo:
        case["options"] = {**extra, "backend": backend}
    print(f"\nside by side with {args.baseline} ({backend}, {len(todo)} requests, alternating workers):", flush=True)
    found = bench_aep_speed.compare(todo, args.baseline, echo=lambda line: None, scope=args.baseline_scope)
    print(f"{'solver':<22}{'median s':>10}{'p95 s':>9}{'max s':>9}{'total s':>9}")
    for name, label in (("old", args.baseline), ("new", "working tree")):
        median, p95, most, total = found.figures(name)
        print(f"{label[:21]:<22}{median:>10.3f}{p95:>9.3f}{most:>9.3f}{total:>9.1f}")
    print(f"identical programs, rejections and counts: {found.requests - len(found.mismatches)}/{found.requests}")
    for label, why in found.mismatches:
        print(f"  {label}: {why}")
    return not found.mismatches


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", type=int, default=100, help="val shapes for the random seeds")
    parser.add_argument("--designer-shapes", type=int, default=60,
                        help="val shapes for the designer seeds (0: every val shape)")
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "shapeassembly")
    parser.add_argument("--backends", default="symengine,sympy")
    parser.add_argument("--slider-requests", type=int, default=10)
    parser.add_argument("--skip", default="", help="comma-separated parts to skip: random,designer,ablation,slider")
    parser.add_argument("--verbose", action="store_true", help="print every case that loses a relation")
    parser.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                        help="an AEP option for every run (e.g. repair=0), repeatable")
    parser.add_argument("--baseline", metavar="REV",
                        help="also solve the random-seed requests with REV's plugins/parsel-aep, side by side "
                             "with the working tree in two worker processes (bench_aep_speed.py), and compare")
    taken = parser.add_mutually_exclusive_group()
    taken.add_argument("--baseline-core", dest="baseline_scope", action="store_const", const="core", default="aep",
                       help="with --baseline, take parsel_core from REV too (relations and ops as they were)")
    taken.add_argument("--baseline-tree", dest="baseline_scope", action="store_const", const="tree",
                       help="with --baseline, take REV's whole tree: its core and every plugin")
    args = parser.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    extra = parse_options(args.option, "--option")
    backends = args.backends.split(",")
    programs: dict[int, Program] = {}
    requests: list[tuple[object, str]] = []

    if "designer" not in skip:
        count = args.designer_shapes or 10 ** 6
        paths = sample_programs(args.data, count, seed=1)
        shapes = [load_shape(str(p)) for p in paths]
        cases = [Case(shape, d.kind, d.seed, d.breaks) for shape in shapes for d in designer_seeds(shape)]
        print(f"designer seeds: {len(shapes)} val shapes, {len(cases)} cases")
        variants = [("full", {})]
        if "ablation" not in skip:
            variants += [("--no-nhbd", {"nhbd": False}), ("--no-breaking", {"breaking": False})]
        ablation = []
        for name, options in variants:
            outcomes = [run_case(c, {**extra, **options, "backend": backends[0]}) for c in cases]
            ablation.append((name, *summarise(outcomes)))
            if name != "full":
                continue
            print_groups("category", outcomes, lambda o: o.case.shape.metadata.get("category", "?"))
            print_groups("seed kind", outcomes, lambda o: o.case.kind)
            print_losses(outcomes)
            if args.verbose:
                for o in outcomes:
                    if o.losses or o.crashed:
                        print(f"  {o.case.shape.name} {o.case.kind}: {o.kept}/{o.total} {o.losses[:4]} "
                              f"{o.crashed or ''}")
        print(f"\n{'designer seeds':<16}{'kept':>9}{'all kept':>10}{'crashes':>9}")
        for name, kept, whole, crashes, _ in ablation:
            print(f"{name:<16}{kept:>9.2%}{whole:>10.1%}{crashes:>9}")

    if "random" not in skip:
        paths = sample_programs(args.data, args.shapes)
        clock = time.perf_counter()
        shapes = [load_shape(str(p)) for p in paths]
        load_time = time.perf_counter() - clock
        requests = [(shape, seed) for shape in shapes for seed in seeds_for(shape)]
        mix = ", ".join(f"{sum(s.metadata.get('category') == c for s in shapes)} {c}" for c in CATEGORIES)
        print(f"\nrandom seeds: {len(shapes)} shapes ({mix}), {len(requests)} requests; parts per shape: median "
              f"{statistics.median(len(s.parts) for s in shapes):.0f}, max {max(len(s.parts) for s in shapes)}; "
              f"relations: median {statistics.median(len(s.relations) for s in shapes):.0f}, "
              f"max {max(len(s.relations) for s in shapes)}; loading + detection {load_time:.1f} s")
        rows = []
        for backend in backends:
            get_cas_backend(backend)
            outcomes = [run_case(Case(shape, "random", seed), {**extra, "backend": backend})
                        for shape, seed in requests]
            for i, o in enumerate(outcomes):
                if o.program is not None:
                    programs.setdefault(i, o.program)
            times = sorted(o.seconds for o in outcomes if o.crashed is None)
            kept, whole, crashes, n = summarise(outcomes)
            rows.append((backend, n, crashes, statistics.median(times), times[int(0.95 * (len(times) - 1))],
                         kept, whole))
            if backend == backends[0]:
                print_losses(outcomes)
        print(f"\n{'backend':<11}{'requests':>9}{'crashes':>8}{'median s':>10}{'p95 s':>9}{'kept':>8}{'all kept':>10}")
        for backend, n, failed, median, p95, kept, whole in rows:
            print(f"{backend:<11}{n:>9}{failed:>8}{median:>10.3f}{p95:>9.3f}{kept:>8.1%}{whole:>10.1%}")
        if len(rows) == 2:
            print(f"median CPU ratio {rows[1][0]}/{rows[0][0]}: {rows[1][3] / rows[0][3]:.2f}x")
        if args.baseline and not side_by_side(args, backends[0], extra):
            sys.exit(1)
    if "slider" in skip or not programs:
        return

    online = solvers()["online"]
    aep_steps, online_steps = [], []
    backend = get_cas_backend(backends[0])
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
