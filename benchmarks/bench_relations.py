"""Relation detection against the relations ShapeAssembly programs declare.

Each program of the val split (chair, table, storage) is executed by the parsel
ShapeAssembly interpreter; its leaf cuboids become a ShapeGraph (one part per leaf; the
label is the leaf's path with copy suffixes ``_ref``, ``_tN`` and ``_N`` stripped from
every element, so ``Program_2_ref/cube1_t3`` is labelled ``Program_2/cube1``, which
plays the role of PartNet's semantic label; ``--labels leaf`` keeps only the last
element, ``cube1``, a coarser labelling). The parsel-relations detectors run on it with
the default tolerance (0.01 x the shape's diagonal) and their relations are compared
with the program's declarations, per relation kind:

reflection
    A declared ``reflect`` of a leaf gives one expected pair (leaf, copy). A reflected
    sub-program (``Program_N``) gives one pair per leaf: the leaf of the source and the
    copy's leaf at the same relative path. A declared ``translate`` with a single copy
    (2 parts) is expected as a reflection pair too, since the paper only makes groups of
    more than 2 parts and two translated copies of a box are mirror images about the
    plane halfway between them. A detected reflection is a true positive when its
    member pair is an expected pair.
translation
    A declared ``translate`` with 2 or more copies gives one expected group per leaf of
    the translated cuboid (for a sub-program, the leaves at the same relative path in
    the source and every copy). A detected group matches when its member set is equal.
attachment
    Each executed ``attach`` (also those ``squeeze`` expands into and those
    ``reflect``/``translate`` replay for copies) joins a moved side and a target side.
    Attachments to a block's ``bbox`` are not between parts and are left out. A side
    that is a leaf is that leaf. A side that is a sub-program cuboid was resolved by the
    interpreter to the sub-program's leaves within 2% of the attachment point; when
    none is that close it stays the sub-program's path and stands for all of its leaves.
    An expected attachment (moved side S, target side T, duplicates merged) is recalled
    when some detected attachment joins a leaf of S with a leaf of T.

    Precision is given at three levels, because ShapeAssembly declares the attachments
    that position parts, not every contact:

    ``precision``  a detected attachment is explained when some declared attachment has
                   one member among the leaves of its moved cuboid and the other among
                   the leaves of its target cuboid (a sub-program attached to another
                   explains any contact between their leaves);
    ``p(+sym)``    also when it is the image of such a pair under the declared
                   reflections and translations (orbits of leaves joined by declared
                   symmetries: shelves attached to the left side also touch its
                   reflected copy, the right side);
    ``p(+bbox)``   also when both leaves were placed against the same block bounding
                   box (``attach``/``squeeze`` to ``bbox``), e.g. a table top and the
                   legs squeezed under the same bbox top;
    ``p(+contact)`` also when the two executed cuboids really touch or overlap: their
                   separation along the best separating axis (exact, by the
                   separating-axis theorem; an independent test from the detector's
                   clipping) is at most 0.1% of the diagonal. These are contacts the
                   program does not declare, e.g. arms that overlap the seat while the
                   program attaches them to the legs only.

    What ``p(+contact)`` still counts as false is a detection across a real gap
    (below the tolerance, above 0.1% of the diagonal) that no declaration explains.

Time is the wall time of ``parsel_relations.detect_all`` on one shape (all families).
Run: ``python benchmarks/bench_relations.py [--categories chair table] [--limit N]
[--labels path|leaf] [--misses FILE] [--data ../shared/data/shapeassembly]``.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import networkx as nx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "shapeassembly"
CATEGORIES = ("chair", "table", "storage")
KINDS = ("reflection", "translation", "attachment")
COPY_SUFFIX = re.compile(r"(_ref|_t\d+)(_\d+)?$")

try:
    from parsel_shapeassembly.interpreter import execute_file
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "plugins" / "parsel-shapeassembly"))
    from parsel_shapeassembly.interpreter import execute_file

from parsel_core import Hexahedron, Part, ShapeGraph  # noqa: E402
from parsel_relations import DEFAULT_RELATIVE_TOLERANCE, detect_all  # noqa: E402
from parsel_relations.geometry import boxes_of, separations  # noqa: E402


def strip_copies(element: str) -> str:
    """``cube1_t3`` -> ``cube1``, ``Program_2_ref`` -> ``Program_2``, ``cube0_ref_2`` -> ``cube0``."""
    while (stripped := COPY_SUFFIX.sub("", element)) != element:
        element = stripped
    return element


def label_of(name: str, mode: str) -> str:
    elements = [strip_copies(e) for e in name.split("/")]
    return "/".join(elements) if mode == "path" else elements[-1]


def shape_of(program, name: str, mode: str) -> ShapeGraph:
    parts = [Part(c.name, label_of(c.name, mode), Hexahedron.from_box(c.center, c.dims, c.axes))
             for c in program.cuboids]
    return ShapeGraph(parts, name=name)


# -- expected relations from the declarations -----------------------------------------------


def _under(path: str, leaves: set[str]) -> list[str]:
    if path in leaves:
        return [path]
    return sorted(leaf for leaf in leaves if leaf.startswith(path + "/"))


def _relative(path: str, leaf: str) -> str:
    return "" if leaf == path else leaf[len(path) + 1:]


def _corresponding(paths: list[str], leaves: set[str]) -> list[list[str]]:
    """For each leaf of the first path, the leaves at the same relative path in all paths."""
    rows = []
    for leaf in _under(paths[0], leaves):
        rel = _relative(paths[0], leaf)
        row = [p if not rel else f"{p}/{rel}" for p in paths]
        if all(r in leaves for r in row):
            rows.append(row)
    return rows


def _side(path: str, members: tuple[str, ...], leaves: set[str]) -> frozenset[str]:
    """The leaves standing for one side of an attachment."""
    mine = [m for m in members if m == path or m.startswith(path + "/")]
    out: set[str] = set()
    for m in mine:
        out.update(_under(m, leaves))
    return frozenset(out)


@dataclass
class Expected:
    reflection: set[frozenset[str]] = field(default_factory=set)
    translation: set[frozenset[str]] = field(default_factory=set)
    #: (moved side, target side) as the interpreter resolved them: what recall asks for
    attachment: set[tuple[frozenset[str], frozenset[str]]] = field(default_factory=set)
    #: (all leaves of the moved cuboid, all leaves of the target cuboid): what precision allows
    licence: set[tuple[frozenset[str], frozenset[str]]] = field(default_factory=set)
    #: leaf -> representative of its orbit under the declared reflections and translations
    orbit: dict[str, str] = field(default_factory=dict)
    #: per block bbox, the leaves placed against it (themselves or through a sub-program)
    against_bbox: dict[str, set[str]] = field(default_factory=dict)


def _orbits(rows: list[list[str]], leaves: set[str]) -> dict[str, str]:
    """Leaves joined by declared symmetries: each leaf -> its orbit's smallest name."""
    graph = nx.Graph()
    graph.add_nodes_from(leaves)
    for row in rows:
        graph.add_edges_from((row[0], other) for other in row[1:])
    return {leaf: min(orbit) for orbit in nx.connected_components(graph) for leaf in orbit}


def expected_relations(program) -> Expected:
    leaves = {c.name for c in program.cuboids}
    out = Expected()
    symmetric_rows: list[list[str]] = []
    for rel in program.relations:
        p = rel.params
        if rel.kind == "reflection":
            for a, b in _corresponding([p["source"], p["copy"]], leaves):
                symmetric_rows.append([a, b])
                if a != b:
                    out.reflection.add(frozenset((a, b)))
        elif rel.kind == "translation":
            for row in _corresponding([p["source"], *p["copies"]], leaves):
                symmetric_rows.append(row)
                if len(row) == 2:
                    out.reflection.add(frozenset(row))
                elif len(set(row)) > 2:
                    out.translation.add(frozenset(row))
        elif rel.kind == "attachment":
            if p["target"].endswith("bbox"):
                out.against_bbox.setdefault(p["target"], set()).update(_under(p["source"], leaves))
                continue
            s, t = _side(p["source"], rel.members, leaves), _side(p["target"], rel.members, leaves)
            if s and t and s != t:
                out.attachment.add(tuple(sorted((s, t), key=sorted)))
                whole = frozenset(_under(p["source"], leaves)), frozenset(_under(p["target"], leaves))
                out.licence.add(tuple(sorted(whole, key=sorted)))
    out.orbit = _orbits(symmetric_rows, leaves)
    return out


# -- scoring ---------------------------------------------------------------------------------

PRECISION_LEVELS = ("declared", "+symmetry", "+bbox", "+contact")
#: Cuboids this close (fraction of the diagonal) or overlapping are in contact.
CONTACT = 1e-3


@dataclass
class Score:
    """Counts for one kind; ``explained[level]`` counts detected relations explained at that level."""

    detected: int = 0
    tp_expected: int = 0
    expected: int = 0
    explained: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PRECISION_LEVELS, 0))

    def add(self, other: Score) -> None:
        self.detected += other.detected
        self.tp_expected += other.tp_expected
        self.expected += other.expected
        for level in PRECISION_LEVELS:
            self.explained[level] += other.explained[level]

    def precision(self, level: str = "declared") -> float:
        return self.explained[level] / self.detected if self.detected else 1.0

    @property
    def recall(self) -> float:
        return self.tp_expected / self.expected if self.expected else 1.0


def _covers(pair: tuple[str, str], item: tuple[frozenset[str], frozenset[str]]) -> bool:
    (a, b), (s, t) = pair, item
    return (a in s and b in t) or (a in t and b in s)


def attachment_levels(pair: tuple[str, str], expected: Expected, touching: bool) -> str | None:
    """The first precision level at which a detected attachment is explained (None: not at all).

    ``touching``: whether the pair's executed cuboids touch or overlap."""
    if any(_covers(pair, e) for e in expected.attachment | expected.licence):
        return "declared"
    orbit = expected.orbit
    images = (orbit[pair[0]], orbit[pair[1]])
    for s, t in expected.attachment | expected.licence:
        if _covers(images, (frozenset(orbit[x] for x in s), frozenset(orbit[y] for y in t))):
            return "+symmetry"
    if any(pair[0] in placed and pair[1] in placed for placed in expected.against_bbox.values()):
        return "+bbox"
    return "+contact" if touching else None


def score_shape(relations, expected: Expected, shape: ShapeGraph) -> tuple[dict[str, Score], dict[str, dict]]:
    """Scores per kind and the misses (false positives and false negatives) for analysis."""
    found = defaultdict(list)
    for r in relations:
        found[r.kind].append(r.members)
    scores, misses = {}, {}
    for kind in ("reflection", "translation"):
        want = getattr(expected, kind)
        got = {frozenset(m) for m in found[kind]}
        hits = len(got & want)
        scores[kind] = Score(len(got), hits, len(want), dict.fromkeys(PRECISION_LEVELS, hits))
        misses[kind] = {"fp": [sorted(g) for g in got - want], "fn": [sorted(w) for w in want - got]}
    pairs = [tuple(m) for m in found["attachment"]]
    ids = {pid: i for i, pid in enumerate(shape.parts)}
    boxes = boxes_of(np.stack([part.hexahedron.corners for part in shape.parts.values()]))
    gaps = separations(boxes, np.array([ids[a] for a, _ in pairs], int), np.array([ids[b] for _, b in pairs], int)) \
        if pairs else np.zeros(0)
    levels = [attachment_levels(p, expected, gap <= CONTACT * shape.size) for p, gap in zip(pairs, gaps)]
    explained = {level: sum(lv is not None and PRECISION_LEVELS.index(lv) <= k for lv in levels)
                 for k, level in enumerate(PRECISION_LEVELS)}
    recalled = [e for e in expected.attachment if any(_covers(p, e) for p in pairs)]
    scores["attachment"] = Score(len(pairs), len(recalled), len(expected.attachment), explained)
    misses["attachment"] = {
        "fp": {level or "unexplained": [list(p) for p, lv in zip(pairs, levels) if lv == level]
               for level in (*PRECISION_LEVELS[1:], None)},
        "fn": [[sorted(s), sorted(t)] for s, t in expected.attachment if (s, t) not in recalled],
    }
    return scores, misses


def run(data: Path, categories, limit: int | None, mode: str, misses_path: Path | None, relative: float) -> None:
    all_misses = {}
    print(f"labels: {mode}; tolerance: {relative} x shape diagonal")
    print(f"{'category':<9} {'shapes':>6} {'kind':<12} {'precision':>9} {'p(+sym)':>8} {'p(+bbox)':>8} "
          f"{'p(+contact)':>11} {'recall':>7} {'detected':>8} {'expected':>8} {'median s':>9}")
    for category in categories:
        ids = (data / "splits" / category / "val.txt").read_text().split()[:limit]
        totals = {k: Score() for k in KINDS}
        times = []
        for pid in ids:
            program = execute_file(data / category / f"{pid}.txt")
            shape = shape_of(program, f"{category}/{pid}", mode)
            start = time.perf_counter()
            relations = detect_all(shape, relative * shape.size)
            times.append(time.perf_counter() - start)
            scores, misses = score_shape(relations, expected_relations(program), shape)
            for kind in KINDS:
                totals[kind].add(scores[kind])
            if any(m["fn"] or (m["fp"] if kind != "attachment" else m["fp"]["unexplained"])
                   for kind, m in misses.items()):
                all_misses[f"{category}/{pid}"] = misses
        median = statistics.median(times)
        for kind in KINDS:
            s = totals[kind]
            print(f"{category:<9} {len(ids):>6} {kind:<12} {s.precision():>9.3f} {s.precision('+symmetry'):>8.3f} "
                  f"{s.precision('+bbox'):>8.3f} {s.precision('+contact'):>11.3f} {s.recall:>7.3f} {s.detected:>8} "
                  f"{s.expected:>8} {median:>9.3f}")
    if misses_path:
        misses_path.write_text(json.dumps(all_misses, indent=1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--categories", nargs="+", default=list(CATEGORIES), choices=CATEGORIES)
    parser.add_argument("--limit", type=int, default=None, help="first N programs of each val split")
    parser.add_argument("--labels", choices=("path", "leaf"), default="path")
    parser.add_argument("--tolerance", type=float, default=DEFAULT_RELATIVE_TOLERANCE,
                        help="relative tolerance (fraction of the shape's diagonal)")
    parser.add_argument("--misses", type=Path, default=None, help="write false positives / negatives as JSON")
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the ShapeAssembly corpus")
    args = parser.parse_args(argv)
    run(args.data, args.categories, args.limit, args.labels, args.misses, args.tolerance)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
