"""Evaluation metrics of ParSEL (reference section 7; supplement 5.3 and 5.4).

Program quality, comparing an inferred program with a ground-truth (GT) one:

* ``J(prog)`` (:func:`program_jaccard`): Jaccard similarity of the sets of op
  signatures ``type(operand)``.
* ``D(geo)`` (:func:`geometric_distance`): the control parameter set to 0.35 in both
  programs, the L2 distances between corresponding hexahedron corners, summed over
  corners and parts.
* ``%Rel`` (:func:`relation_agreement`): among relations touching at least one edited
  part, the fraction whose state (kept or broken) is the same under both programs.

Language-model accuracy, comparing what the model inferred with what an expert entered
(the human-solver inputs):

* ``Acc(SE)`` (:func:`seed_accuracy`): the seed edit's signature is in the GT program's
  signature set.
* ``Acc(R)`` (:func:`validity_accuracy`): per-relation agreement on validity (which
  symmetry relations the edit may break).
* ``J(T)`` (:func:`hint_jaccard`): Jaccard similarity of the type hints.
* ``Match`` (:func:`all_match`): all three right.

The functions on plain values (signature sets, corner arrays, relation states) are pure
and cheap; the ones taking a shape and programs evaluate them and call those. Where the
reference leaves a case open, the choice is stated in the function's docstring and in
docs/evaluation.md.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.ops import EditOp, GroupOp
from parsel_core.program import Program, evaluate, laid_out_groups
from parsel_core.report import check_program

#: The control-parameter value at which D(geo) compares programs (supplement 5.3.2).
DGEO_VALUE = 0.35
#: Relation kinds the relation-validity prompts ask about (reference section 6): Acc(R)'s universe.
SYMMETRY_KINDS = ("reflection", "translation", "rotation")


# -- J(prog) ------------------------------------------------------------------------------


def signature(op: EditOp) -> str:
    """An op's signature ``type(operand)``: its operator name and operand, nothing else.

    Supplement 5.3.1 keeps "only the type of edit operation and its operand", so two
    programs that edit the same part with the same operator agree whatever the op's
    origin, direction, feature or amount.
    """
    return f"{op.name}({op.operand})"


def signatures(ops: Program | Iterable[EditOp]) -> frozenset[str]:
    """The set of op signatures of a program (or of any ops); repeated ops count once."""
    items = ops.ops if isinstance(ops, Program) else ops
    return frozenset(signature(op) for op in items)


def jaccard(a: Collection[Any], b: Collection[Any]) -> float:
    """``|a & b| / |a | b|``; two empty sets are identical, so their similarity is 1."""
    a, b = set(a), set(b)
    union = a | b
    return 1.0 if not union else len(a & b) / len(union)


def program_jaccard(inferred: Program | Iterable[EditOp], ground_truth: Program | Iterable[EditOp]) -> float:
    """J(prog): Jaccard similarity of the two programs' signature sets (reference section 7)."""
    return jaccard(signatures(inferred), signatures(ground_truth))


# -- D(geo) -------------------------------------------------------------------------------


def control_values(program: Program, value: float = DGEO_VALUE) -> dict[str, float]:
    """Every parameter of ``program`` set to ``value``, clamped into its own range ``[lo, hi]``.

    D(geo) sets "the user-controlled parameter" to 0.35 (supplement 5.3.2). A program
    whose range ends below 0.35 (AEP chooses ``[0, tau]``, and tau can be smaller) cannot
    be evaluated there, so it is evaluated at the end of its range instead: the closest
    shape the program can make. Programs with several parameters (composed, proxydural)
    get every parameter set the same way.
    """
    return {p.name: min(max(float(value), p.lo), p.hi) for p in program.parameters}


def corner_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Sum over corresponding corners of the Euclidean (L2) distance: ``sum_k ||a_k - b_k||``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.linalg.norm(a - b, axis=-1).sum())


def instance_distance(a: Sequence[np.ndarray], b: Sequence[np.ndarray]) -> float:
    """Distance between two layouts of one symmetry group (lists of instance corners).

    Instances are matched by index. When a count changed differently in the two
    programs, the instances past the shorter list have no partner by index; each is
    charged its distance to the nearest instance of the other layout, so a layout
    with one board more costs about one board's offset rather than nothing (or an
    arbitrary constant). An empty layout against a non-empty one charges the other's
    instances against nothing: they are skipped, as there is no geometry to compare.
    """
    a = [np.asarray(x, dtype=float) for x in a]
    b = [np.asarray(x, dtype=float) for x in b]
    shared = min(len(a), len(b))
    total = sum(corner_distance(a[j], b[j]) for j in range(shared))
    longer, shorter = (a, b) if len(a) > len(b) else (b, a)
    if shorter:
        for extra in longer[shared:]:
            total += min(corner_distance(extra, other) for other in shorter)
    return float(total)


def corner_set_distance(parts_a: Mapping[str, np.ndarray], parts_b: Mapping[str, np.ndarray],
                        groups_a: Mapping[str, Sequence[np.ndarray]] | None = None,
                        groups_b: Mapping[str, Sequence[np.ndarray]] | None = None) -> float:
    """D(geo) on evaluated corners: per part :func:`corner_distance`, summed over parts,
    plus :func:`instance_distance` for each re-laid-out group.

    ``parts_*`` map part ids to (8, 3) corners and must name the same parts; ``groups_*``
    map a group id to its instances' corners (both or neither mention a group).
    """
    if set(parts_a) != set(parts_b):
        missing = sorted(set(parts_a) ^ set(parts_b))
        raise ValueError(f"the two shapes differ in parts: {', '.join(missing)}")
    groups_a, groups_b = dict(groups_a or {}), dict(groups_b or {})
    if set(groups_a) != set(groups_b):
        raise ValueError("the two shapes differ in laid-out groups")
    total = sum(corner_distance(parts_a[pid], parts_b[pid]) for pid in sorted(parts_a))
    total += sum(instance_distance(groups_a[g], groups_b[g]) for g in sorted(groups_a))
    return float(total)


def _layout_corners(shape: ShapeGraph, program: Program, values: Mapping[str, float],
                    groups: Collection[str]) -> tuple[dict[str, np.ndarray], dict[str, list[np.ndarray]]]:
    """Corners of the real parts outside ``groups`` and the instance list of each group."""
    evaluation = evaluate(program, shape, values)
    members = {m for g in groups for m in shape.relations[g].members}
    parts = {pid: np.asarray(evaluation.parts[pid]) for pid in shape.parts if pid not in members}
    layouts: dict[str, list[np.ndarray]] = {}
    for g in groups:
        if g in evaluation.instances:
            layouts[g] = list(evaluation.instances[g])
        else:
            layouts[g] = [np.asarray(evaluation.parts[m]) for m in shape.relations[g].members]
    return parts, layouts


def geometric_distance(shape: ShapeGraph, inferred: Program, ground_truth: Program,
                       value: float = DGEO_VALUE) -> float:
    """D(geo) (reference section 7): both programs at x = ``value`` (clamped, see
    :func:`control_values`), summed corner distances over the shape's real parts.

    Virtual parents are not parts of the asset and are left out (their members count).
    A translation or rotation group whose count or spacing either program changes is
    compared as a layout of instances (:func:`instance_distance`) instead of member by
    member, since members past a smaller count no longer exist.
    """
    groups = sorted(laid_out_groups(inferred) | laid_out_groups(ground_truth))
    parts_a, layout_a = _layout_corners(shape, inferred, control_values(inferred, value), groups)
    parts_b, layout_b = _layout_corners(shape, ground_truth, control_values(ground_truth, value), groups)
    return corner_set_distance(parts_a, parts_b, layout_a, layout_b)


# -- %Rel ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class RelationAgreement:
    """%Rel with its counts: ``agreeing`` of ``considered`` relations (``fraction`` in [0, 1])."""

    fraction: float
    agreeing: int
    considered: int
    disagreeing: tuple[str, ...] = ()

    @property
    def percent(self) -> float:
        return 100.0 * self.fraction


def edited_parts(shape: ShapeGraph, program: Program) -> set[str]:
    """Real parts a program moves: operands of part ops (``keep_fixed`` excluded), with a
    virtual parent standing for all its members, and the members of groups it re-lays out."""
    out: set[str] = set()
    for op in program.ops:
        if op.name == "keep_fixed":
            continue
        if isinstance(op, GroupOp) or op.operand in shape.virtual_parents:
            relation = shape.relations.get(op.operand)
            if relation is not None:
                out.update(relation.members)
        elif op.operand in shape.parts:
            out.add(op.operand)
    return out


def relation_agreement(states_inferred: Mapping[str, str], states_ground_truth: Mapping[str, str],
                       members: Mapping[str, Iterable[str]], edited: Collection[str]) -> RelationAgreement:
    """%Rel on relation states (reference section 7; supplement 5.3.3).

    ``states_*`` map relation ids to ``kept``, ``broken`` or ``broken_on_purpose`` (the
    last two are both *broken*: %Rel compares kept vs broken); ``members`` gives each
    relation's parts; ``edited`` the parts edited by either program. Only relations with
    at least one edited member count. With none, nothing can disagree: 100%.
    """
    edited = set(edited)
    considered = sorted(rid for rid, ms in members.items() if set(ms) & edited)
    disagreeing = tuple(rid for rid in considered
                        if (states_inferred[rid] == "kept") != (states_ground_truth[rid] == "kept"))
    agreeing = len(considered) - len(disagreeing)
    fraction = 1.0 if not considered else agreeing / len(considered)
    return RelationAgreement(fraction, agreeing, len(considered), disagreeing)


def structural_agreement(shape: ShapeGraph, inferred: Program, ground_truth: Program,
                         states_inferred: Mapping[str, str] | None = None,
                         states_ground_truth: Mapping[str, str] | None = None) -> RelationAgreement:
    """%Rel of two programs on a shape; relation states come from
    :func:`parsel_core.report.check_program` (each program over its own range) unless given.

    "Edited" means edited by either program: a relation the GT program breaks by editing
    a part the inferred program left alone is a disagreement too.
    """
    if states_inferred is None:
        states_inferred = check_program(shape, inferred).states()
    if states_ground_truth is None:
        states_ground_truth = check_program(shape, ground_truth).states()
    edited = edited_parts(shape, inferred) | edited_parts(shape, ground_truth)
    members = {rid: r.members for rid, r in shape.relations.items()}
    return relation_agreement(states_inferred, states_ground_truth, members, edited)


# -- language-model accuracy --------------------------------------------------------------


def seed_accuracy(seed: Program | Iterable[EditOp], reference: Program | Iterable[EditOp]) -> bool:
    """Acc(SE) (supplement 5.4.1): the seed edit's signature is in the reference's signature set.

    ``reference`` is the GT program (or, lacking one, the expert's seed). A seed of
    several ops is right when every op's signature is in the set; an empty seed is wrong.
    """
    seed_signatures = signatures(seed)
    return bool(seed_signatures) and seed_signatures <= signatures(reference)


def validity_universe(shape: ShapeGraph) -> list[str]:
    """The relations the validity prompts ask about: the shape's symmetry relations."""
    return sorted(rid for rid, r in shape.relations.items() if r.kind in SYMMETRY_KINDS)


def validity_accuracy(inferred_breaks: Iterable[str], expected_breaks: Iterable[str],
                      relations: Iterable[str]) -> float:
    """Acc(R) (supplement 5.4.2): the fraction of relations whose validity (may break or
    not) the model set as the expert did.

    ``relations`` are the relations asked about (:func:`validity_universe`); any relation
    either side marks breakable is asked about too. With no relation to ask about, the
    model cannot be wrong: 1.
    """
    inferred, expected = set(inferred_breaks), set(expected_breaks)
    universe = set(relations) | inferred | expected
    if not universe:
        return 1.0
    return sum((rid in inferred) == (rid in expected) for rid in universe) / len(universe)


def hint_jaccard(inferred_hints: Mapping[str, str], expected_hints: Mapping[str, str]) -> float:
    """J(T) (supplement 5.4.3): Jaccard similarity of the type hints as ``(part, type)`` pairs.

    A hint with the right part and the wrong type counts as a miss on both sides; no
    hints on either side is a perfect match (the expert often sets none).
    """
    return jaccard(set(inferred_hints.items()), set(expected_hints.items()))


def all_match(acc_se: bool, acc_r: float, j_t: float) -> bool:
    """Match: the seed edit, every relation validity and the type hints are all right."""
    return bool(acc_se) and math.isclose(acc_r, 1.0) and math.isclose(j_t, 1.0)


# -- bundles and summaries ----------------------------------------------------------------


@dataclass(frozen=True)
class ProgramMetrics:
    """J(prog), D(geo) and %Rel of one inferred program against its GT program."""

    j_prog: float
    d_geo: float
    rel: RelationAgreement

    def to_dict(self) -> dict[str, Any]:
        return {"J_prog": self.j_prog, "D_geo": self.d_geo, "rel": self.rel.fraction,
                "rel_considered": self.rel.considered, "rel_disagreeing": list(self.rel.disagreeing)}


def program_metrics(shape: ShapeGraph, inferred: Program, ground_truth: Program,
                    states_inferred: Mapping[str, str] | None = None, value: float = DGEO_VALUE) -> ProgramMetrics:
    """The three program-quality metrics of reference section 7."""
    return ProgramMetrics(program_jaccard(inferred, ground_truth),
                          geometric_distance(shape, inferred, ground_truth, value),
                          structural_agreement(shape, inferred, ground_truth, states_inferred))


@dataclass(frozen=True)
class LanguageMetrics:
    """Acc(SE), Acc(R), J(T) and Match of one set of language-model outputs."""

    acc_se: bool
    acc_r: float
    j_t: float

    @property
    def match(self) -> bool:
        return all_match(self.acc_se, self.acc_r, self.j_t)

    def to_dict(self) -> dict[str, Any]:
        return {"acc_se": self.acc_se, "acc_r": self.acc_r, "J_T": self.j_t, "match": self.match}


def language_metrics(shape: ShapeGraph, seed: Program | Iterable[EditOp], hints: Mapping[str, str],
                     breaks: Iterable[str], reference: Program | Iterable[EditOp],
                     expected_hints: Mapping[str, str], expected_breaks: Iterable[str]) -> LanguageMetrics:
    """The four language-model metrics of reference section 7 for one request."""
    return LanguageMetrics(seed_accuracy(seed, reference),
                           validity_accuracy(breaks, expected_breaks, validity_universe(shape)),
                           hint_jaccard(hints, expected_hints))


#: Metric keys of a case record, in table order, with how to average them.
METRIC_KEYS = ("J_prog", "D_geo", "rel", "acc_se", "acc_r", "J_T", "match")


def summarise(metrics: Iterable[Mapping[str, Any] | None]) -> dict[str, Any]:
    """Means over the cases where each metric is defined (booleans as fractions), with counts.

    This is how the paper's tables report them: J, D and %Rel averaged over requests,
    Acc(SE) and Match as the fraction of requests that got them right.
    """
    columns: dict[str, list[float]] = {key: [] for key in METRIC_KEYS}
    for item in metrics:
        for key in METRIC_KEYS:
            value = (item or {}).get(key)
            if value is not None:
                columns[key].append(float(value))
    out: dict[str, Any] = {}
    for key, values in columns.items():
        out[key] = {"mean": (sum(values) / len(values)) if values else None, "cases": len(values)}
    return out
