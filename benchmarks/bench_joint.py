"""Many sliders, one valid shape: joint parameter boxes of stacked designer requests.

For ShapeAssembly val shapes (default 20, spread over chair, table and storage), three
designer seeds per shape (``designer_seeds.py``: the first, middle and last rule that
applies; the next one when a seed's layer cannot combine with the earlier ones, say a
row laid out both top-down and bottom-up) are solved one at a time on the rest shape and added as layers
(``parsel_core.joint.add_layer``), as ``parsel proxydural`` and ``parsel edit --on`` do.
Each program is then checked on its joint box (all 8 corners and 200 random points).

The figure is relative, as the issue asks: of the relations that every slider keeps when it
moves alone, the share that the joint box keeps too ("joint kept"). The same figure for the
old sequential stacking (``Program.then``: ops keep their rest origins after earlier ops
moved the parts) is printed beside it. CPU seconds (``time.process_time``) are medians per
shape: solving the three requests, adding the layers (range fitting included), the joint check.

    python benchmarks/bench_joint.py [--shapes 20] [--samples 200] [--verbose]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from designer_seeds import designer_seeds  # noqa: E402

from parsel_core.api import edit  # noqa: E402
from parsel_core.errors import ParselError  # noqa: E402
from parsel_core.joint import add_layer, box_corners, edge_skew  # noqa: E402
from parsel_core.loading import load_shape  # noqa: E402
from parsel_core.program import Program  # noqa: E402
from parsel_core.report import check_program, kept_alone  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CATEGORIES = ("chair", "table", "storage")


def val_programs(data: Path, count: int) -> list[Path]:
    """``count`` val-split programs, round-robin over the categories in split order (deterministic)."""
    ids = {c: (data / "splits" / c / "val.txt").read_text().split() for c in CATEGORIES}
    out: list[Path] = []
    i = 0
    while len(out) < count and any(i < len(v) for v in ids.values()):
        for c in CATEGORIES:
            if i < len(ids[c]) and len(out) < count:
                out.append(data / c / f"{ids[c][i]}.txt")
        i += 1
    return out


def seed_order(shape) -> list:
    """The shape's designer seeds, the first, middle and last first (the three stacked);
    the rest stand by for a request whose layer does not combine with the earlier ones."""
    seeds = designer_seeds(shape)
    picks = sorted({0, len(seeds) // 2, len(seeds) - 1}) if seeds else []
    return [seeds[i] for i in picks] + [s for i, s in enumerate(seeds) if i not in picks]


@dataclass
class Outcome:
    shape: str
    category: str
    requests: list[str] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    alone: int = 0          # relations every slider keeps alone
    joint: int = 0          # of those, kept on the joint box (layers)
    sequential: int = 0     # of those, kept on the joint box when stacked with then
    lost: list[str] = field(default_factory=list)
    on_top: int = 0         # layers that turn parts, run on top of the summed ones
    skew: float = 0.0       # shear the combination adds to a part: |cos| between its edges at a box
    summed_skew: float = 0.0  # corner beyond what any slider alone gives it; the same, every layer summed
    solve_s: float = 0.0
    compose_s: float = 0.0
    check_s: float = 0.0
    error: str | None = None


def run_shape(path: Path, samples: int) -> Outcome:
    shape = load_shape(str(path))
    outcome = Outcome(shape.name, shape.metadata.get("category", path.parent.name))
    layered: Program | None = None
    sequential: Program | None = None
    breaks: set[str] = set()
    try:
        for seed in seed_order(shape):
            if len(outcome.requests) == 3:
                break
            started = time.process_time()
            result = edit(shape, seed=seed.seed, breaks=list(seed.breaks))
            outcome.solve_s += time.process_time() - started
            program = result.program
            started = time.process_time()
            try:
                layered, name = add_layer(shape, layered, program, seed.kind, name=f"x{len(outcome.requests) + 1}")
            except ParselError as exc:
                outcome.refused.append(f"{seed.kind}: {exc}")
                continue
            finally:
                outcome.compose_s += time.process_time() - started
            breaks.update(seed.breaks)
            outcome.requests.append(seed.kind)
            renamed = program.renamed(program.parameters[0].name, name)
            renamed = Program(renamed.ops, (layered.parameter(name),), {})
            sequential = renamed if sequential is None else sequential.then(renamed)
        if layered is None:
            outcome.error = "no designer seed applies"
            return outcome
        started = time.process_time()
        must = kept_alone(shape, layered, breaks)
        report = check_program(shape, layered, sorted(breaks), samples=samples)
        outcome.check_s = time.process_time() - started
        kept = {s.id for s in report.relations if s.state == "kept"}
        seq_report = check_program(shape, sequential, sorted(breaks), samples=samples)
        seq_kept = {s.id for s in seq_report.relations if s.state == "kept"}
        outcome.alone = len(must)
        outcome.joint = len(must & kept)
        outcome.sequential = len(must & seq_kept)
        outcome.lost = sorted(must - kept)
        outcome.on_top = len(layered.outer)
        outcome.skew = added_skew(shape, layered)
        outcome.summed_skew = added_skew(shape, Program(layered.ops, layered.parameters, {}, layered.layers))
    except Exception as exc:  # noqa: BLE001 - a benchmark reports crashes, it does not stop at them
        outcome.error = f"{type(exc).__name__}: {exc}"
    return outcome


def added_skew(shape, program: Program) -> float:
    """The largest shear the combination adds to a part: its edges' |cos| at a box corner
    beyond the most any one slider gives it moving alone (the solver shears some parts itself)."""
    joint = edge_skew(shape, program, box_corners(program.parameters))
    alone = {pid: 0.0 for pid in joint}
    for moving in program.parameters:
        values = {p.name: p.hi if p is moving else p.lo for p in program.parameters}
        for pid, skew in edge_skew(shape, program, values).items():
            alone[pid] = max(alone[pid], skew)
    return max((joint[pid] - alone[pid] for pid in joint), default=0.0)


def percent(part: int, whole: int) -> str:
    return f"{100.0 * part / whole:.1f}%" if whole else "-"


def median(rows: list[Outcome], key: str) -> str:
    return f"{statistics.median(getattr(o, key) for o in rows):.2f}" if rows else "-"


def print_table(outcomes: list[Outcome]) -> None:
    print(f"\n{'category':<10}{'shapes':>7}{'alone kept':>12}{'joint kept':>12}{'all kept':>10}"
          f"{'then (old)':>12}{'on top':>8}{'skew':>7}{'summed':>8}{'solve s':>9}{'layer s':>9}{'check s':>9}")
    groups = {c: [o for o in outcomes if o.category == c] for c in CATEGORIES}
    groups["all"] = outcomes
    for name, rows in groups.items():
        ok = [o for o in rows if o.error is None]
        if not rows:
            continue
        alone = sum(o.alone for o in ok)
        joint = sum(o.joint for o in ok)
        seq = sum(o.sequential for o in ok)
        skew, summed = max((o.skew for o in ok), default=0), max((o.summed_skew for o in ok), default=0)
        every = sum(1 for o in ok if o.joint == o.alone)
        print(f"{name:<10}{len(rows):>7}{alone:>12}{percent(joint, alone):>12}{f'{every}/{len(ok)}':>10}"
              f"{percent(seq, alone):>12}{sum(o.on_top for o in ok):>8}{skew:>7.3f}{summed:>8.3f}"
              f"{median(ok, 'solve_s'):>9}{median(ok, 'compose_s'):>9}"
              f"{median(ok, 'check_s'):>9}")
    crashed = [o for o in outcomes if o.error]
    if crashed:
        print(f"\n{len(crashed)} shape(s) without a result:")
        for o in crashed:
            print(f"  {o.shape}: {o.error}")
    refused = [o for o in outcomes if o.refused]
    if refused:
        print("\nseeds whose layer did not combine (the next seed was taken):")
        for o in refused:
            for line in o.refused:
                print(f"  {o.shape}: {line}")
    lost = [o for o in outcomes if o.lost]
    if lost:
        print("\nrelations kept by every slider alone but not on the joint box:")
        for o in lost:
            print(f"  {o.shape} ({', '.join(o.requests)}): {', '.join(o.lost)}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "shapeassembly")
    parser.add_argument("--shapes", type=int, default=20, help="val shapes (default 20)")
    parser.add_argument("--samples", type=int, default=200, help="random joint samples besides the box corners")
    parser.add_argument("--verbose", action="store_true", help="a line per shape as it finishes")
    args = parser.parse_args()
    outcomes = []
    paths = val_programs(args.data, args.shapes)
    print(f"{len(paths)} val shapes x 3 designer requests, stacked as layers; joint box: corners + "
          f"{args.samples} random samples")
    for path in paths:
        outcome = run_shape(path, args.samples)
        outcomes.append(outcome)
        if args.verbose:
            print(f"  {outcome.category}/{path.stem}: {outcome.joint}/{outcome.alone} joint, "
                  f"{outcome.sequential}/{outcome.alone} with then  {outcome.error or ''}", flush=True)
    print_table(outcomes)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
