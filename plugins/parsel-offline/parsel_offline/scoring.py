"""Scoring the offline interpreter on a table of requests with hand-written expectations.

The tables (``tests/data/requests_dev.tsv`` and ``requests_held_out.tsv`` of this plugin)
hold one request a line: ``kind  shape  request  expected``. ``expected`` is ``refuse``
or ops separated by `` ; ``, each ``OP TARGET AXIS SIGN [=AMOUNT]``:

* ``OP``: the op's name (``scale_1d``, ``translate``, ``rotate`` ...);
* ``TARGET``: part ids or labels separated by ``|``; a label also matches a symmetry
  group whose members all carry it (an edit through the group's virtual parent);
* ``AXIS``: ``x``/``y``/``z``, the world axis of the op's direction (``dir``, ``axis`` or
  ``normal``), or ``-`` for ops without one;
* ``SIGN``: ``+`` or ``-``: the sign of the amount at ``x = 1`` times the sign of the
  direction's component on that axis (a scale's direction has no sign: its amount's sign
  says grow or shrink; a rotation's is the right-hand sense about the positive axis);
* ``=AMOUNT``: optionally the amount at ``x = 1`` (to 1e-6), for degree words.

``all`` is right when every op matches an expected op and every expected op is met: by
one op, or by the same edit on each set of symmetric parts it names (legs of a chair whose
front and back pairs differ); no op may be added, nor repeated on parts of one symmetric
set (those would compound). The ``op``, ``part``, ``axis`` and ``sign`` columns compare the
first op with the first expected op. A refusal is counted apart, with its reason.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.ops import EditOp

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
HALVES = {"development": DATA / "requests_dev.tsv", "held-out": DATA / "requests_held_out.tsv"}
SHAPE_DIR = DATA / "shapeassembly"
METRICS = ("op", "part", "axis", "sign", "all")


@dataclass(frozen=True)
class Expected:
    op: str
    targets: tuple[str, ...]
    axis: str
    sign: str
    amount: float | None = None


@dataclass(frozen=True)
class Case:
    kind: str
    shape: str
    request: str
    expected: tuple[Expected, ...]  # empty: the request should be refused
    line: int


@dataclass
class Outcome:
    case: Case
    scores: dict[str, bool] = field(default_factory=dict)
    refused: str | None = None
    crashed: str | None = None
    got: list[str] = field(default_factory=list)


def read_cases(path: Path | str) -> list[Case]:
    """The cases of one table; a malformed line is an error naming it."""
    path = Path(path)
    cases = []
    with path.open(encoding="utf-8") as handle:
        for number, row in enumerate(csv.reader(handle, delimiter="\t", quoting=csv.QUOTE_NONE), start=1):
            if not row or row[0].startswith("#"):
                continue
            if len(row) != 4:
                raise ParselError(f"{path}:{number}: expected 4 tab-separated fields, got {len(row)}")
            kind, shape, request, expected = row
            ops = () if expected.strip() == "refuse" else tuple(_expected(e, f"{path}:{number}")
                                                                 for e in expected.split(" ; "))
            cases.append(Case(kind, shape, request, ops, number))
    return cases


def _expected(text: str, where: str) -> Expected:
    words = text.split()
    if len(words) not in (4, 5) or words[2] not in ("x", "y", "z", "-") or words[3] not in ("+", "-"):
        raise ParselError(f"{where}: expected 'OP TARGET AXIS SIGN [=AMOUNT]', got {text!r}")
    amount = float(words[4][1:]) if len(words) == 5 else None
    return Expected(words[0], tuple(words[1].split("|")), words[2], words[3], amount)


def shape_path(name: str) -> str:
    """``sa:chair/39482`` names a ShapeAssembly program copied into the test data; other names are bundled shapes."""
    return str(SHAPE_DIR / f"{name[3:]}.txt") if name.startswith("sa:") else name


def _direction(op: EditOp) -> np.ndarray | None:
    for name in ("dir", "axis", "normal"):
        value = getattr(op, name, None)
        if value is not None:
            return np.asarray(value, dtype=float)
    return None


def describe_op(op: EditOp) -> str:
    """The op in the table's terms: ``scale_1d leg.000 y + =1``."""
    from parsel_core.language.amounts import amount_values

    value = amount_values(op.amount, "x", 0.0, 1.0, samples=2)[1]
    d = _direction(op)
    if d is None:
        axis, sign = "-", np.sign(value)
    else:
        k = int(np.argmax(np.abs(d)))
        axis = "xyz"[k]
        sign = np.sign(value) * (1.0 if op.name.startswith("scale") else np.sign(d[k]))
    return f"{op.name} {op.operand} {axis} {'+' if sign >= 0 else '-'} ={value:.6g}"


def _target_ok(op: EditOp, want: Expected, shape) -> bool:
    operand = op.operand
    if operand in want.targets:
        return True
    if operand in shape.parts:
        return shape.parts[operand].label in want.targets
    members = shape.relations[operand].members if operand in shape.relations else ()
    if members:
        return all(m in want.targets or shape.parts[m].label in want.targets for m in members)
    return False


def _matches(op: EditOp, want: Expected, shape) -> dict[str, bool]:
    words = describe_op(op).split()
    value = float(words[4][1:])
    return {
        "op": op.name == want.op,
        "part": _target_ok(op, want, shape),
        "axis": words[2] == want.axis,
        "sign": words[3] == want.sign,
        "amount": want.amount is None or abs(value - want.amount) < 1e-6,
    }


def score(case: Case, ops: list[EditOp], shape) -> dict[str, bool]:
    """Per-metric right/wrong of a request's ops against the case."""
    if not case.expected:
        return dict.fromkeys(METRICS, False)
    first = _matches(ops[0], case.expected[0], shape)
    out = {k: first[k] for k in ("op", "part", "axis", "sign")}
    # Each expected op is met by one op, or by the same edit on each set of symmetric parts it
    # names (a chair whose front and back legs differ gets one scale per pair); two ops on parts
    # of one symmetric set are the same edit twice, and wrong.
    component = _components(shape)
    matched: dict[Expected, list[str]] = {w: [] for w in case.expected}
    for op in ops:
        hits = [w for w in case.expected if all(_matches(op, w, shape).values())]
        if not hits:
            out["all"] = False
            return out
        want = hits[0]
        key = component.get(op.operand, op.operand)
        if key in matched[want]:
            out["all"] = False
            return out
        matched[want].append(key)
    out["all"] = all(matched.values())
    return out


def _components(shape) -> dict[str, str]:
    """Part or group id -> a name for its set of symmetric parts (reflections, translations, rotations)."""
    import networkx as nx

    graph = nx.Graph()
    graph.add_nodes_from(shape.parts)
    for relation in shape.relations.values():
        if relation.kind in ("reflection", "translation", "rotation"):
            graph.add_edges_from((relation.members[0], m) for m in relation.members[1:])
            graph.add_edge(relation.id, relation.members[0])
    out = {}
    for nodes in nx.connected_components(graph):
        name = min(nodes)
        out.update(dict.fromkeys(nodes, name))
    return out


def run_cases(cases: Iterable[Case], load: Callable[[str], Any] | None = None) -> list[Outcome]:
    """Ask the offline provider (through the whole language layer, seed-only, one sample) for each case."""
    from parsel_core.language import InferenceError, infer
    from parsel_core.loading import load_shape

    load = load or load_shape
    shapes: dict[str, Any] = {}
    outcomes = []
    for case in cases:
        outcome = Outcome(case)
        try:
            if case.shape not in shapes:
                shapes[case.shape] = load(shape_path(case.shape))
            shape = shapes[case.shape]
            result = infer(shape, case.request, provider="offline", mode="seed-only", samples=1)
        except InferenceError as exc:
            outcome.refused = str(exc)
            outcome.scores = dict.fromkeys(METRICS, not case.expected)
        except Exception as exc:  # a crash is what this table exists to catch
            outcome.crashed = f"{type(exc).__name__}: {exc}"
            outcome.scores = dict.fromkeys(METRICS, False)
        else:
            ops = list(result.seed.ops)
            outcome.got = [describe_op(op) for op in ops]
            outcome.scores = score(case, ops, shape)
        outcomes.append(outcome)
    return outcomes


def accuracy(outcomes: list[Outcome], metric: str) -> float:
    return sum(o.scores[metric] for o in outcomes) / max(len(outcomes), 1)
