"""Analytical Edit Propagation (paper section 5, supplement algorithms 1-3).

From a seed edit, edits are added one part at a time until no relation is broken
anywhere in [0, tau]:

1. relations the user allows to break are dropped; hinted ``keep`` parts are fixed;
2. the program so far is evaluated at samples of [0, tau] and broken relations gathered;
3. a broken symmetry with an edited member is restored analytically (transfer.py);
4. otherwise the undecided part with the most relations among those touching broken
   relations is edited next (the minimum-entropy heuristic); a member of an intact
   translation or rotation group is edited through the group's virtual parent;
5. its candidates (candidates.py) are screened numerically against every relation
   linking it to decided parts (screening.py); survivors are ranked (selection.py)
   and the winner's amount is derived in closed form with the CAS (derive.py);
6. failing that, nhbd-edits and then breaking-edits are tried; what cannot be kept is
   rejected and reported.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import itertools
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_aep import breaking as breaking_module
from parsel_aep import cluster as cluster_module
from parsel_aep import factor as factor_module
from parsel_aep import feasibility
from parsel_aep.breaking import BreakingTable, breaking_table
from parsel_aep.candidates import (
    HINT_TYPES,
    SIMPLICITY,
    candidate_family,
    directions,
    neighbour_candidates,
    own_candidates,
)
from parsel_aep.compound import Compound, compound_candidates, simplify
from parsel_aep.derive import (
    affine_amount,
    amount_text,
    evaluate_amount,
    linear_combination,
    rotation_amount,
    simpler_equivalent,
    symbolic_residual,
)
from parsel_aep.options import AEPOptions
from parsel_aep.screening import (
    Screened,
    apply_each,
    compound_solver,
    residual_slices,
    screen,
    screen_table,
)
from parsel_aep.selection import HIGH_DISTORTION, arap_energies, symmetry_plane_counts
from parsel_aep.tau import automatic_tau
from parsel_aep.transfer import transfer
from parsel_core import opmath
from parsel_core.blas import one_blas_thread, started_on_one_thread
from parsel_core.collector import fewer_collections
from parsel_core.errors import ParselError, UnknownPartError
from parsel_core.graph import GROUP_KINDS, ShapeGraph
from parsel_core.interfaces import SolveRequest, SolveResult
from parsel_core.ops import ChangeCount, EditOp, KeepFixed, Scale1D, Translate
from parsel_core.plugins import get_cas_backend
from parsel_core.program import (
    NUMPY_MATH,
    Parameter,
    Program,
    evaluate,
    laid_out_groups,
    op_amount,
    op_targets,
    symbolic_corners,
)
from parsel_core.relations import Attachment, ReflectionSymmetry, Relation, TranslationSymmetry
from parsel_core.report import batch_relation_errors, check_program, relation_error, sliding_members, tolerance_for

HINTS = (*HINT_TYPES, "keep")
#: How many parts' corners (8, 3) at one sample of recent programs, and how many relation
#: errors, a run keeps: about 13 MB and 10 MB at most, on shapes of any size.
_REMEMBERED_CORNERS = 70_000
_REMEMBERED_ERRORS = 100_000
_REMEMBERED_DIGESTS = 10_000
#: Ops the joint pass can redo with scalings and translations (cluster.py).
BOX_OPS = frozenset({"translate", "scale_1d", "scale_2d", "scale_3d"})


@dataclass
class _State:
    ops: list[EditOp]
    decided: set[str]
    rejected: set[str] = field(default_factory=set)
    #: Why each rejected relation was given up, and the part being edited then (for the
    #: loss analysis of benchmarks/bench_aep.py and the report).
    losses: dict[str, tuple[str, str | None]] = field(default_factory=dict)
    transferred: set[str] = field(default_factory=set)
    seeded: set[str] = field(default_factory=set)
    stats: dict[str, Any] = field(default_factory=lambda: {
        "candidates_screened": 0, "candidates_valid": 0, "symmetry_transfers": 0, "searches": 0,
        "nhbd_edits": 0, "breaking_edits": 0, "unfixed_parts": 0,
        "time_s": {"tau": 0.0, "evaluate": 0.0, "screen": 0.0, "derive": 0.0, "verify": 0.0}})

    def edited(self) -> set[str]:
        return {op.operand for op in self.ops if op.acts_on == "part" and not isinstance(op, KeepFixed)}

    def reject(self, relations, reason: str, part: str | None = None) -> None:
        for relation in relations:
            rid = relation if isinstance(relation, str) else relation.id
            self.rejected.add(rid)
            self.losses.setdefault(rid, (reason, part))


@dataclass
class _Cluster:
    """A joint edit of the joint pass, solved numerically (closed forms still to derive)."""

    parts: list[str]
    members: set[str]
    plan: cluster_module.Plan
    others_ops: list[EditOp]
    constraints: list[Relation]
    #: The constraints given up (indices), and the variant (shears, world frame).
    dropped: tuple[int, ...] = ()
    shears: bool = False
    world: bool = False

    @property
    def system(self) -> cluster_module.ClusterSystem:
        return self.plan.system

    @property
    def kept(self) -> list[int]:
        return self.plan.kept

    @functools.cached_property
    def solution(self) -> tuple[np.ndarray, np.ndarray]:
        """The sparse amounts (S, B) and their solver (B, K'), solved when first read."""
        f, matrix, _ = self.plan.solve()
        return f, matrix

    @functools.cached_property
    def score(self) -> tuple:
        """``(constraints dropped, their error, shears, world frame)``, least first. The error
        is measured on the sparse amounts (solved here when first read, raising as they
        do); a cluster keeping every constraint scores 0 whatever its amounts."""
        if not self.dropped:
            return (0, 0.0, self.shears, self.world)
        errors = cluster_module.relation_errors(self.system, self.solution[0])
        return (len(self.dropped), float(sum(errors[i] for i in self.dropped)), self.shears, self.world)


def _least_scored(state: _State, solved: list[tuple[int, _Cluster]]) -> tuple[tuple, int, _Cluster] | None:
    """``(score, index, cluster)`` of the least of the ``solved`` (by score, then index),
    scoring only the clusters that drop the fewest constraints; those whose sparse
    amounts cannot be solved are removed from ``solved`` on the way."""
    while solved:
        fewest = min(len(found.dropped) for _, found in solved)
        scored = []
        clock = time.perf_counter()
        try:
            for index, found in [t for t in solved if len(t[1].dropped) == fewest]:
                try:
                    scored.append((found.score, index, found))
                except (np.linalg.LinAlgError, FloatingPointError):  # an ill-posed cluster is not taken
                    solved[:] = [t for t in solved if t[1] is not found]
        finally:
            state.stats["time_s"]["screen"] += time.perf_counter() - clock
        if scored:
            return min(scored, key=lambda t: (t[0], t[1]))
    return None


def _part_by_part(program: Program) -> bool:
    """Whether ``program`` is part ops in one layer: each part's corners are then its rest
    corners under the ops that move it (:meth:`Propagation.parts_of`)."""
    return all(op.acts_on == "part" for op in program.ops) and len(program.layer_slices) == 1


def _moved_part(known: dict, pid: str, rest: np.ndarray, ops: Sequence[EditOp], start: Callable[[np.ndarray], Any],
                amount: Callable[[EditOp], Any], math_ns: Any) -> Any:
    """Part ``pid``'s corners under ``ops`` (those moving it, in order), from ``start`` of
    its ``rest`` corners, each op at ``amount(op)``; remembered in ``known`` by the ops'
    identities (the entry holds the ops, so the ids stay theirs) and read-only."""
    key = (pid, tuple(map(id, ops)))
    found = known.get(key)
    if found is None:
        corners = start(rest)
        for op in ops:
            corners = op.apply(corners, amount(op), math_ns)
        corners.flags.writeable = False
        found = known[key] = (tuple(ops), corners)
    return found[1]


def _digest(array: np.ndarray) -> bytes:
    """A 128-bit digest of an array's shape, type and values."""
    digest = hashlib.blake2b(repr((array.shape, array.dtype.str)).encode(), digest_size=16)
    digest.update(array.tobytes())
    return digest.digest()


def _frozen(array: np.ndarray) -> bool:
    """Whether neither the array nor any array it views can be written."""
    while isinstance(array, np.ndarray):
        if array.flags.writeable:
            return False
        array = array.base
    return array is None


def validate_request(request: SolveRequest) -> None:
    """Unknown parts, relations or hint types are one-line errors naming them."""
    shape = request.shape
    request.seed.validate(shape)
    for part, hint in request.hints.items():
        if part not in shape.parts and part not in shape.virtual_parents:
            raise UnknownPartError(f"--hint {part}={hint}: shape {shape.name!r} has no part {part!r}")
        if hint not in HINTS:
            raise ParselError(f"--hint {part}={hint}: unknown hint type {hint!r} (known: {', '.join(HINTS)})")
    for rid in request.breaks:
        if rid not in shape.relations:
            raise UnknownPartError(f"--break {rid}: shape {shape.name!r} has no relation {rid!r}")
    if len(request.seed.parameters) != 1:
        raise ParselError("edit propagation takes a seed with exactly one parameter")
    check_amounts(request.seed)


#: Seed amounts beyond this magnitude are refused: no part is meant to grow a million-fold.
MAX_AMOUNT = 1e6


def check_amounts(seed: Program, samples: int = 201) -> None:
    """Every seed amount is finite and bounded over the whole range (``x/0``, ``log(0) + x``
    and ``1e300*x`` are one-line errors here, not NaN corners later)."""
    parameter = seed.parameters[0]
    lo, hi = parameter.lo, max(parameter.hi, 1.0)
    values = np.linspace(lo, hi, samples)
    for op in seed.ops:
        try:
            with np.errstate(all="ignore"):
                amounts = evaluate_amount(op.amount, parameter.name, values)
        except (ArithmeticError, ValueError, TypeError) as exc:
            raise ParselError(f"seed {op.name} on {op.operand!r}: amount {op.amount!r} cannot be evaluated: "
                              f"{exc}") from None
        bad = ~np.isfinite(amounts) | (np.abs(amounts) > MAX_AMOUNT)
        if bad.any():
            at = float(values[int(np.argmax(bad))])
            what = "is not finite" if not np.isfinite(amounts[bad][0]) else f"exceeds {MAX_AMOUNT:g}"
            raise ParselError(f"seed {op.name} on {op.operand!r}: amount {op.amount!r} {what} at "
                              f"{parameter.name} = {at:g}")


class Propagation:
    """One run of AEP on a request; ``run()`` returns the program and what was learned."""

    def __init__(self, request: SolveRequest) -> None:
        validate_request(request)
        self.request = request
        self.shape: ShapeGraph = request.shape
        self.options = AEPOptions.from_mapping(request.options)
        self.backend = get_cas_backend(self.options.backend)
        self.parameter = request.seed.parameters[0]
        self.breaks = set(request.breaks)
        self.relations = [r for r in self.shape.relations.values() if r.id not in self.breaks]
        self.tolerance = tolerance_for(self.shape, self.options.relative_tolerance)
        self.rest = self.shape.rest_corners()
        self.hints = dict(request.hints)
        self.copy_sources: dict[int, str] = {}
        #: Recent programs' corners (:meth:`corners`) and relation errors by what they read
        #: (:meth:`error`): the loop, the repair and the joint pass check the same states again.
        self._corners: dict[tuple, dict[str, np.ndarray]] = {}
        #: Each part's corners by the ops that move it (:meth:`parts_of`).
        self._part_corners: dict[tuple, tuple[tuple[EditOp, ...], np.ndarray]] = {}
        self._errors: dict[tuple, float] = {}
        self._digests: dict[int, tuple[np.ndarray, bytes]] = {}
        #: The joint pass's box bases moved at rest and their slopes (cluster.build_system).
        self._bases: dict = {}
        #: Each part's symbolic corners by the ops that move it, and each op's amount as an
        #: expression (:meth:`symbolic_parts`).
        self._symbolic: dict[tuple, tuple[tuple[EditOp, ...], np.ndarray]] = {}
        self._expressions: dict[int, tuple[EditOp, Any]] = {}

    # -- program bookkeeping -------------------------------------------------------

    def program(self, ops: Sequence[EditOp]) -> Program:
        return Program(tuple(ops), (self.params,), {"solver": "aep"})

    def corners(self, ops: Sequence[EditOp]) -> dict[str, np.ndarray]:
        """Every part's corners (S, 8, 3) at the samples under ``ops`` (read-only arrays).

        Remembered by the ops' identities (the entry holds the ops, so those stay unique):
        equal ops may differ in the sign of a zero, which the corners could keep."""
        key = tuple(map(id, ops))
        known = self._corners.get(key)
        if known is None:
            if (len(self._corners) * len(self.rest) + len(self._part_corners)) * len(self.xs) >= _REMEMBERED_CORNERS:
                self._corners.clear()
                self._part_corners.clear()
            program = self.program(ops)
            if _part_by_part(program):
                parts = self.parts_of(program)
            else:  # group layouts, layers: the whole evaluation
                parts = evaluate(program, self.shape, {self.parameter.name: self.xs}).parts
                for array in parts.values():
                    array.flags.writeable = False
            known = self._corners[key] = (tuple(ops), parts)
        return dict(known[1])

    def parts_of(self, program: Program) -> dict[str, np.ndarray]:
        """``evaluate(program).parts`` for a program of part ops in one layer, part by part.

        There a part's corners are its rest corners under the ops that move it (its own and
        its group's), applied in order, each at its amounts at the samples: a part whose
        ops are the same objects as in an earlier program gets that program's array (the
        same ops on the same arrays: the same bits). The loop, the repair pass and the
        joint pass mostly try programs that differ from the last in a part or two."""
        program.validate(self.shape)
        moving = self.moving_ops(program.ops, self.rest)
        values = {self.parameter.name: self.xs}
        amounts: dict[int, np.ndarray] = {}  # (an op on a group's parent moves every member)

        def amount(op: EditOp) -> np.ndarray:
            known = amounts.get(id(op))
            if known is None:
                known = amounts[id(op)] = op_amount(op, values)[..., None, None]
            return known

        def sampled(rest: np.ndarray) -> np.ndarray:
            return np.broadcast_to(rest, (len(self.xs), 8, 3)).copy()

        return {pid: _moved_part(self._part_corners, pid, self.rest[pid], ops, sampled, amount, NUMPY_MATH)
                for pid, ops in moving.items()}

    def moving_ops(self, ops: Sequence[EditOp], parts: Iterable[str]) -> dict[str, list[EditOp]]:
        """The ops that move each of ``parts`` (its own and its group's), in program order."""
        moving: dict[str, list[EditOp]] = {pid: [] for pid in parts}
        for op in ops:
            for target in op_targets(op, self.shape):
                if target in moving:
                    moving[target].append(op)
        return moving

    def symbolic_parts(self, ops: Sequence[EditOp], only: Sequence[str]) -> dict[str, np.ndarray]:
        """``symbolic_corners(self.program(ops), ..., only=only)``, part by part for a program
        of part ops in one layer (as :meth:`parts_of`): a part's expressions are its rest
        corners under the ops that move it, so a part whose ops are the same objects as
        before keeps its expressions (the searches derive against the same decided
        neighbours again and again). Other programs are derived whole."""
        program = self.program(ops)
        if not _part_by_part(program):
            return symbolic_corners(program, self.shape, self.backend, only=only)
        program.validate(self.shape)
        moving = self.moving_ops(ops, [pid for pid in only if pid in self.rest])
        # (a part no op moves keeps its float corners)
        return {pid: _moved_part(self._symbolic, pid, self.rest[pid], part_ops, self.backend.corners,
                                 self.expression, opmath) if part_ops else self.rest[pid]
                for pid, part_ops in moving.items()}

    def expression(self, op: EditOp) -> Any:
        """``op``'s amount parsed by the backend, once per op (the entry holds the op)."""
        known = self._expressions.get(id(op))
        if known is None or known[0] is not op:
            known = self._expressions[id(op)] = (op, self.backend.parse(op.amount))
        return known[1]

    def error(self, relation: Relation, corners: Mapping[str, np.ndarray], sliding=()) -> float:
        """:func:`relation_error`, remembered by what it reads: the members' corners (by a
        128-bit digest) and which of them slide. Between two checks of the whole shape only
        the relations of the parts edited since are evaluated again. Errors are compared
        with the relations' allowances, and broken ones summed: a face contact within its
        allowance is not checked again as a sliding one (``below``)."""
        key = (relation.id, *((m in sliding, self.digest(np.asarray(corners[m]))) for m in relation.members))
        error = self._errors.get(key)
        if error is None:
            if len(self._errors) >= _REMEMBERED_ERRORS:
                self._errors.clear()
            error = self._errors[key] = relation_error(relation, corners, sliding,
                                                        below=relation.allowance(self.tolerance))
        return error

    def digest(self, array: np.ndarray) -> bytes:
        """:func:`_digest`, made once for an array nothing can write (the remembered
        corners and views of them), which is kept with it so its identity stays its own."""
        if not _frozen(array):
            return _digest(array)
        known = self._digests.get(id(array))
        if known is None or known[0] is not array:
            if len(self._digests) >= _REMEMBERED_DIGESTS:
                self._digests.clear()
            known = self._digests[id(array)] = (array, _digest(array))
        return known[1]

    def broken(self, state: _State, corners: Mapping[str, np.ndarray]) -> list[Relation]:
        sliding = sliding_members(self.shape, self.program(state.ops))
        return [r for r in self.relations
                if r.id not in state.rejected and not self.holds(r, corners, sliding)]

    # -- the loop ------------------------------------------------------------------

    def run(self) -> SolveResult:
        started = time.perf_counter()
        seed = self.request.seed
        state = _State(list(seed.ops), set())
        clock = time.perf_counter()
        tau = self.options.tau if self.options.tau is not None else automatic_tau(
            self.shape, seed, self.options.tau_max)
        if not tau > 0:
            raise ParselError(f"tau must be positive, got {tau}")
        state.stats["time_s"]["tau"] = time.perf_counter() - clock
        default = self.parameter.default if self.parameter.default else tau / 2
        self.params = Parameter(self.parameter.name, 0.0, float(tau), min(default, tau))
        self.xs = np.linspace(0.0, tau, self.options.samples)
        for op in seed.ops:
            state.decided.add(op.operand)
            if op.operand in self.shape.virtual_parents:
                state.decided.update(self.shape.relations[op.operand].members)
        state.seeded = set(state.decided)
        for part, hint in sorted(self.hints.items()):
            if hint == "keep" and part not in state.decided:
                state.ops.append(KeepFixed(part))
                state.decided.add(part)
        for _ in range(4 * (len(self.shape.parts) + len(self.shape.virtual_parents)) + 4):
            clock = time.perf_counter()
            corners = self.corners(state.ops)
            broken = self.broken(state, corners)
            state.stats["time_s"]["evaluate"] += time.perf_counter() - clock
            if not broken:
                break
            if self.restore_symmetries(state, broken):
                continue
            undecided = sorted({m for r in broken for m in r.members if m not in state.decided
                                and m in self.shape.parts})
            if not undecided:
                for r in broken:
                    state.reject([r], self.late_reason(state, r, sliding_members(self.shape, self.program(state.ops))))
                break
            # Minimum entropy: the most constrained part goes first (most exact relations with
            # decided parts or the ground, then most relations overall). An intact repeated
            # group counts as one part with all its members' relations.
            sliding = sliding_members(self.shape, self.program(state.ops))
            target = min(undecided, key=lambda m: (-self.decided_count(m, state, sliding), -self.relation_count(m), m))
            self.edit_part(state, target, corners)
        else:
            raise RuntimeError("edit propagation did not terminate")
        if self.options.repair:
            self.repair(state)
        if self.options.joint and self.options.nhbd:  # the joint pass extends the nhbd-edits
            self.joint_repair(state)
        program = self.program(state.ops)
        clock = time.perf_counter()
        # The final word is a check at random samples of the whole range (paper eq. 1).
        report = check_program(self.shape.with_relations(self.relations), program, samples=50,
                               tolerance=self.tolerance)
        final = {r.id for r in report.relations if r.state != "kept"}
        state.rejected = set()
        state.reject(sorted(final), "final-check")
        state.stats["time_s"]["verify"] = time.perf_counter() - clock
        state.stats["losses"] = {rid: state.losses[rid] for rid in sorted(state.rejected) if rid in state.losses}
        state.stats["time_s"]["total"] = time.perf_counter() - started
        state.stats["tau"] = float(tau)
        return SolveResult(program, sorted(state.rejected), state.stats)

    def holds(self, relation: Relation, corners: Mapping[str, np.ndarray], sliding=()) -> bool:
        """Whether ``relation`` holds at every sample (within its allowance)."""
        return self.error(relation, corners, sliding) < relation.allowance(self.tolerance)

    def damage(self, ops: Sequence[EditOp]) -> tuple[float, int]:
        """How badly ``ops`` break the relations that must hold: total error, then count."""
        corners = self.corners(ops)
        sliding = sliding_members(self.shape, self.program(ops))
        errors = [self.error(r, corners, sliding) for r in self.relations]
        broken = [e for e, r in zip(errors, self.relations) if not e < r.allowance(self.tolerance)]
        return (float(sum(e for e in broken if np.isfinite(e))) + (np.inf if any(not np.isfinite(e) for e in broken)
                                                                   else 0.0), len(broken))

    def repair(self, state: _State) -> None:
        """A second pass over parts decided too early (an extension of the paper's loop).

        The loop edits each part once, against the parts decided before it; an edit that
        was one of many keeping those (a face moved where the whole part should stretch)
        can leave a later neighbour with no edit that keeps everything. Here every edited
        or unedited part touching a broken relation is searched again against all its
        relations, the others' edits fixed, and the new edit is kept when it lowers the
        total error of the whole shape. Seed parts, fixed parts and group members are left
        alone.
        """
        fixed = state.seeded | {p for p, hint in self.hints.items() if hint == "keep"}
        for _ in range(self.options.repair):
            damage = self.damage(state.ops)
            if damage[1] == 0:
                return
            corners = self.corners(state.ops)
            sliding = sliding_members(self.shape, self.program(state.ops))
            broken = [r for r in self.relations if not self.holds(r, corners, sliding)]
            parts = sorted({m for r in broken for m in r.members if m in self.shape.parts and m not in fixed
                            and m not in sliding and not self.shape.groups_of(m)},
                           key=lambda m: (-self.relation_count(m), m))
            improved = False
            for part in parts:
                others_ops = [op for op in state.ops if op.operand != part]
                constraints = [r for r in self.relations if part in r.members]
                trial_state = dataclasses.replace(state, ops=others_ops, stats=state.stats)
                choice = self.search(trial_state, part, (part,), constraints, self.corners(others_ops),
                                     breaking=self.options.repair_breaking)
                if choice is None:
                    continue
                op = choice[0]
                new_ops = others_ops + (op if isinstance(op, list) else [op] if op is not None else [])
                new_damage = self.damage(new_ops)
                if new_damage[0] < damage[0] - self.tolerance:
                    state.ops, damage, improved = new_ops, new_damage, True
                    state.stats["repairs"] = state.stats.get("repairs", 0) + 1
            if not improved:
                return

    def hopeless(self, part: str, constraints: Sequence[Relation], corners: Mapping[str, np.ndarray],
                 sliding: set[str]) -> bool:
        """Whether no edit of ``part`` can keep the ``constraints`` that every stage of a
        search for a valid edit screens exactly (feasibility.py): those with no member of a
        re-laid-out group (``sliding``) and no face contact (faces may slide)."""
        firm = [r for r in constraints if not set(r.members) & sliding
                and not (isinstance(r, Attachment) and r.contact == "face")]
        others = {m: corners[m] for r in firm for m in r.members if m != part}
        allowances = np.array([max(self.tolerance, r.allowance(0.0)) for r in firm])
        return feasibility.no_edit_keeps(part, self.rest[part], others, firm, allowances)

    def joint_repair(self, state: _State) -> None:
        """Re-solve the parts around the relations still broken together (cluster.py).

        The cluster starts with the editable members of the broken relations (an intact
        repeated group counts as one, edited through its virtual parent, and is also tried
        member by member) and grows by a ring of neighbours at a time. Every variant of a
        ring (own or world axes, with or without shears, turned parts kept) is solved
        numerically; the most promising are derived in closed form and checked on the
        whole shape. The first cluster whose joint edit keeps every relation is taken, else
        the one with the least total error, and only when it beats the edits found part by
        part.
        """
        damage = self.damage(state.ops)
        if damage[1] == 0:
            return
        fixed = state.seeded | {p for p, hint in self.hints.items() if hint == "keep"}
        corners = self.corners(state.ops)
        sliding = sliding_members(self.shape, self.program(state.ops))
        allowed = (None, "translate", "scale")

        def unit(m: str) -> str | None:
            """The part or intact group that the joint pass edits for part ``m``."""
            if m not in self.shape.parts or m in fixed or m in sliding:
                return None
            groups = self.shape.groups_of(m)
            if not groups:
                return m if self.hints.get(m) in allowed else None
            for group in groups:
                members = set(self.shape.relations[group].members)
                if (group not in self.breaks and group not in fixed and not members & fixed
                        and not members & sliding and self.hints.get(group) in allowed):
                    return group
            return None

        units = {u for r in self.relations if not self.holds(r, corners, sliding) for m in r.members
                 if (u := unit(m)) is not None}
        best = (damage, None)
        for ring in range(self.options.joint):
            if ring:
                grown = units | {u for v in units for m in self.unit_members(v) for n in self.shape.neighbours(m)
                                 if (u := unit(n)) is not None}
                if grown == units:
                    break
                units = grown
            if not units:
                break
            # Parts turned with a rotated neighbour cannot be redone by scalings and
            # translations: the cluster is also tried with their edits kept.
            turned = {u for u in units if any(op.operand == u and op.name not in BOX_OPS for op in state.ops)}
            groups = {u for u in units if u in self.shape.virtual_parents}
            part_sets = [units]
            if turned and units - turned:
                part_sets.append(units - turned)
            if groups and all(self.hints.get(m) in allowed for g in groups for m in self.unit_members(g)):
                part_sets.append((units - groups) | {m for g in groups for m in self.unit_members(g)})
            variants = [(sorted(parts), frame, shears) for shears in (False, True) for parts in part_sets
                        for frame in ["local"] + (["world"] if not all(
                            cluster_module.aligned(self.shape.part(p).hexahedron) for p in parts) else [])]
            # The numerically most promising variants are derived and checked in full.
            for found in itertools.islice(self.best_clusters(state, variants), 3):
                ops = self.cluster_ops(state, found)
                if ops is None:
                    continue
                trial = self.damage(ops)
                if trial[0] < best[0][0] - self.tolerance:
                    best = (trial, ops)
                if best[0][1] == 0:
                    break
            if best[0][1] == 0:
                break
        if best[1] is not None:
            state.ops = best[1]
            state.stats["joint_repairs"] = state.stats.get("joint_repairs", 0) + 1

    def best_clusters(self, state: _State, variants: Sequence[tuple[list[str], str, bool]]) -> Iterator[_Cluster]:
        """The solved ``(parts, frame, shears)`` variants, least score first (ties in the
        order given), each solved only when it may come next.

        A score is ``(dropped, their error, shears, world frame)``, so an unsolved variant
        scores at least ``(0, 0.0, shears, world frame)``: a solved one that beats every
        unsolved variant's bound comes next whatever they give, and the joint pass, which
        stops at the first cluster keeping everything, mostly solves few variants. The
        error of the dropped constraints needs the sparse amounts; it is measured only for
        the clusters that drop the fewest (only those can come next). A cluster whose
        sparse amounts cannot be solved is left out, as an unsolvable variant is.
        """
        pending = [((0, 0.0, shears, frame != "local"), i) for i, (_, frame, shears) in enumerate(variants)]
        solved: list[tuple[int, _Cluster]] = []
        while pending or solved:
            fewest = min((len(found.dropped) for _, found in solved), default=None)
            best = None if pending and fewest != 0 else _least_scored(state, solved)
            if best is None and not pending:
                return
            if best is not None and (not pending or (best[0], best[1]) < min(pending)):
                solved[:] = [t for t in solved if t[1] is not best[2]]
                clock = time.perf_counter()
                try:
                    _ = best[2].solution  # (its sparse amounts, if its score did not need them)
                except (np.linalg.LinAlgError, FloatingPointError):  # an ill-posed cluster is not taken
                    continue
                finally:
                    state.stats["time_s"]["screen"] += time.perf_counter() - clock
                yield best[2]
                continue
            bound = min(pending)
            pending.remove(bound)
            parts, frame, shears = variants[bound[1]]
            found = self.cluster_solve(state, parts, frame, shears)
            if found is not None:
                solved.append((bound[1], found))

    def unit_members(self, unit: str) -> tuple[str, ...]:
        """The parts an op on ``unit`` moves: the part itself, or a group's members."""
        if unit in self.shape.virtual_parents:
            return tuple(self.shape.relations[unit].members)
        return (unit,)

    def cluster_solve(self, state: _State, parts: list[str], frame: str = "local",
                      shears: bool = False) -> _Cluster | None:
        """The joint least-squares edit of ``parts`` (parts or intact groups), numerically."""
        clock = time.perf_counter()
        units = set(parts)
        targets = {u: self.unit_members(u) for u in parts}
        members = {m for ms in targets.values() for m in ms}
        others_ops = [op for op in state.ops if op.operand not in units]
        corners = self.corners(others_ops)
        sliding = sliding_members(self.shape, self.program(others_ops))
        constraints = [r for r in self.relations if set(r.members) & members and not set(r.members) & sliding
                       and r.id not in units]
        if not constraints:
            return None
        hexahedra = {p: self.shape.part(p).hexahedron for p in parts}
        system = cluster_module.build_system(parts, hexahedra, self.rest, corners, constraints, self.tolerance,
                                             frame, shears,
                                             frozenset(p for p in parts if self.hints.get(p) == "translate"),
                                             targets, memo=self._bases)
        try:
            plan = cluster_module.plan(system)
            kept = set(plan.kept)
            dropped = [i for i in range(len(constraints)) if i not in kept]
            if dropped and not self.options.breaking:
                return None  # giving up relations is a breaking-edit
        except (np.linalg.LinAlgError, FloatingPointError):  # an ill-posed cluster is not taken
            return None
        finally:
            state.stats["time_s"]["screen"] += time.perf_counter() - clock
        # (its score, and the sparse amounts it needs when constraints are dropped, are
        # worked out when it may come next: best_clusters)
        return _Cluster(parts, members, plan, others_ops, constraints, tuple(dropped), shears, frame != "local")

    def cluster_ops(self, state: _State, found: _Cluster) -> list[EditOp] | None:
        """The program with the cluster's edits replaced by its joint edit, amounts in closed form.

        The closed forms are derived unit by unit (a part or a group's virtual parent), the
        unit whose numeric amounts distort a member most first: when the closed forms of a
        unit distort one of its members beyond the threshold at the end of the range, or one
        of them disagrees with its numbers, the joint edit is given up without deriving the
        rest, as it would be after deriving them. Which units are derived first changes
        nothing else: each unit's closed forms are derived on their own.
        """
        clock = time.perf_counter()
        residual = self.cluster_residual(found)
        units = self.cluster_units(found)
        if units is None:
            return None
        # Each unit's members checked on their own, as the whole program checks them below,
        # only where a member's corners are those of the ops moving it (part ops in one layer)
        # and no other unit's ops move it.
        moved = [{m for pairs, _ in unit for op, _ in pairs for m in op_targets(op, self.shape)} for unit in units]
        alone = _part_by_part(self.program(found.others_ops)) and sum(map(len, moved)) == len(set().union(*moved))
        order = sorted(range(len(units)), key=lambda i: -self.numeric_distortion(units[i])) if alone else \
            range(len(units))
        derived: list[list[EditOp]] = [[] for _ in units]
        for i in order:
            for _, terms in units[i]:
                for op, expr, expected in terms(residual):
                    text = self.closed_amount(op, expr, expected)
                    if text is None:
                        return None
                    if text != "0":
                        derived[i].append(dataclasses.replace(op, amount=text))
            if alone and self.distorted(found.others_ops + derived[i], moved[i] & found.members):
                return None
        new_ops = [op for ops in derived for op in ops]
        state.stats["time_s"]["derive"] += time.perf_counter() - clock
        ops = found.others_ops + new_ops
        # As in ranking (selection.py): no part may be distorted beyond the threshold at the
        # end of the range (a leg widened 18-fold to reach a rail that was kept fixed).
        edited = evaluate(self.program(ops), self.shape, {self.parameter.name: self.xs[-1:]}).parts
        if any(arap_energies(self.rest[m], edited[m][-1:])[0] > HIGH_DISTORTION for m in found.members):
            return None
        return ops

    def cluster_residual(self, found: _Cluster) -> list:
        """The kept constraints' residual terms with the cluster's members at rest and the
        parts outside it under their decided ops (the closed forms are combinations of them)."""
        kept_constraints = [found.constraints[i] for i in found.kept]
        outside = sorted({m for r in kept_constraints for m in r.members if m not in found.members})
        symbolic = self.symbolic_parts(found.others_ops, outside)
        return symbolic_residual(kept_constraints, {**symbolic, **{m: self.rest[m] for m in found.members}})

    def cluster_units(self, found: _Cluster) -> list[list[tuple[list[tuple[EditOp, np.ndarray]], Callable]]] | None:
        """Each part's ops in the cluster's joint edit, unit by unit: ``(pairs, terms)``, the
        ops with their amounts at the samples, and ``terms(residual)`` giving ``(op, amount
        expression, amount at the samples)`` for each of them. A part with shears has its
        linear part factored exactly (factor.py); the others' ops are the simplified basis
        (compound.simplify). ``None`` when a sheared part has no exact factors (a pivot near
        zero in every axis order). What is numeric (which ops, their amounts at the samples)
        is worked out here, the expressions only when ``terms`` is called."""
        system, (f, matrix) = found.system, found.solution
        total = len(system.weights)
        units = []
        for compound, block in zip(system.compounds, system.blocks):
            fb = f[:, block]
            sheared = factor_module.has_shears(compound, fb)
            order = factor_module.choose_order(compound, fb) if sheared else None
            if sheared and order is None:
                return None
            parts = []
            if sheared:
                live = factor_module.live(fb)
                numeric = factor_module.factor(compound, list(fb.T), live, order, np.ones(len(fb)))
                parts.append((numeric, functools.partial(self._factored_terms, compound, block, live, order,
                                                         numeric, matrix)))
                fb = np.where(np.arange(fb.shape[1]) >= compound.size - 3, fb, 0.0)  # translations left
            simple = []
            for term in simplify(compound, fb, self.shape.size):
                weights = np.zeros(total)
                weights[block] = term.weights
                simple.append((term.op, weights, f @ weights))
            parts.append(([(op, values) for op, _, values in simple],
                          functools.partial(self._simple_terms, simple, matrix)))
            units.append(parts)
        return units

    def _factored_terms(self, compound: Compound, block: slice, live: list[bool], order, numeric, matrix: np.ndarray,
                        residual: Sequence) -> list[tuple[EditOp, object, np.ndarray]]:
        exprs = [linear_combination(self.backend, -matrix[block.start + i], residual) if on else None
                 for i, on in enumerate(live)]
        symbolic = factor_module.factor(compound, exprs, live, order, self.backend.number(1.0))
        return [(op, expr, values) for (op, expr), (_, values) in zip(symbolic, numeric)]

    def _simple_terms(self, simple, matrix: np.ndarray, residual: Sequence) -> list[tuple[EditOp, object, np.ndarray]]:
        return [(op, linear_combination(self.backend, -(weights @ matrix), residual), values)
                for op, weights, values in simple]

    def numeric_distortion(self, unit) -> float:
        """The largest distortion of a unit's members at the end of the range with its ops
        at their numeric amounts (the order :meth:`cluster_ops` derives units in)."""
        pairs = [pair for unit_pairs, _ in unit for pair in unit_pairs]
        members = sorted({m for op, _ in pairs for m in op_targets(op, self.shape)} & set(self.rest))
        worst = 0.0
        for m in members:
            corners = self.rest[m][None]
            for op, values in pairs:
                if m in op_targets(op, self.shape):
                    corners = op.apply(corners, float(values[-1]), NUMPY_MATH)
            worst = max(worst, float(arap_energies(self.rest[m], corners)[0]))
        return worst

    def distorted(self, ops: Sequence[EditOp], members: Iterable[str]) -> bool:
        """Whether ``ops`` distort one of ``members`` beyond the threshold at the end of the
        range, each member's corners made as the whole evaluation makes them (part ops in
        one layer: its rest corners under the ops moving it, in order)."""
        values = {self.parameter.name: self.xs[-1:]}

        def start(rest: np.ndarray) -> np.ndarray:
            return np.broadcast_to(rest, (1, 8, 3)).copy()

        def amount(op: EditOp) -> np.ndarray:
            return op_amount(op, values)[..., None, None]

        for m, part_ops in self.moving_ops(ops, sorted(members)).items():
            corners = _moved_part({}, m, self.rest[m], part_ops, start, amount, NUMPY_MATH)
            if arap_energies(self.rest[m], corners[-1:])[0] > HIGH_DISTORTION:
                return True
        return False

    def closed_amount(self, op: EditOp, expr, expected: np.ndarray) -> str | None:
        """``expr`` printed, checked against its values at the samples (``None`` when they
        disagree or it does not print); ``"0"`` for an amount that moves nothing."""
        scale = float(np.abs(expected).max())
        if scale < 1e-7 * (self.shape.size if op.name == "translate" else 1.0):
            return "0"
        x = self.parameter.name
        expr = self.backend.expand(expr)
        try:
            # round-off at rest (1e-9 where the amount should be 0) is not part of the edit
            at_rest = self.backend.to_float(self.backend.subs(expr, {x: self.backend.number(0.0)}))
            if 0 < abs(at_rest) < 1e-7 * max(1.0, scale):
                expr = self.backend.expand(expr - self.backend.number(at_rest))
            text = amount_text(self.backend, expr)
            values = evaluate_amount(text, x, self.xs)
        except (ParselError, ValueError, TypeError, ZeroDivisionError):
            return None
        if not np.allclose(values, expected, atol=1e-6 * max(1.0, scale)):
            return None
        return text

    def late_reason(self, state: _State, relation: Relation, sliding: set[str]) -> str:
        """Why a relation between decided parts is broken: which decision broke it."""
        members = set(relation.members)
        if members & sliding:
            return "group-layout"
        if members & state.transferred:
            return "symmetry-transfer"
        if members <= state.seeded:
            return "seed"
        return "decided-early"

    def decided_count(self, part: str, state: _State, sliding: set[str]) -> int:
        members = {part}
        for group in self.shape.groups_of(part):
            if group not in self.breaks and not set(self.shape.relations[group].members) & state.decided:
                members = set(self.shape.relations[group].members)
        return sum(bool(set(r.members) & members) and set(r.members) - members <= state.decided
                   and not set(r.members) & sliding for r in self.relations)

    def relation_count(self, part: str) -> int:
        return sum(part in r.members for r in self.relations)

    def restore_symmetries(self, state: _State, broken: Sequence[Relation]) -> bool:
        """E* = T(E) for symmetries with an edited and an undecided member.

        Broken symmetries are restored first; a mirror pair whose plane merely moved (an
        intact reflection) still hands the edit over, so moving one armrest out moves the
        other. A transfer is only taken when it keeps the target's relations with decided
        parts: otherwise (a seat widened about a point off the legs' mirror plane) the
        target is searched like any part, with the symmetry among its constraints.
        """
        progress = False
        edited = state.edited()
        broken_ids = {r.id for r in broken}
        intact = [r for r in self.relations if isinstance(r, ReflectionSymmetry) and r.id not in broken_ids
                  and r.id not in state.rejected]
        for relation in [r for r in broken if r.family == "symmetry"] + intact:
            sources = [m for m in relation.members if m in edited]
            targets = [m for m in relation.members if m not in state.decided]
            if not sources or not targets:
                continue
            source = sources[0]
            source_ops = [op for op in state.ops if op.operand == source and op.acts_on == "part"]
            for target in targets:
                try:
                    new_ops = transfer(source_ops, relation, source, target)
                except ValueError:
                    continue
                if not self.transfer_keeps(state, target, new_ops):
                    continue
                state.ops.extend(new_ops)
                state.decided.add(target)
                state.transferred.add(target)
                state.stats["symmetry_transfers"] += 1
                progress = True
        return progress

    def transfer_keeps(self, state: _State, target: str, new_ops: Sequence[EditOp]) -> bool:
        """Whether a transferred edit keeps the target's relations with decided parts."""
        constraints = [r for r in self.relations if target in r.members and r.id not in state.rejected
                       and set(r.members) - {target} <= state.decided]
        if not constraints:
            return True
        ops = state.ops + list(new_ops)
        corners = self.corners(ops)
        sliding = sliding_members(self.shape, self.program(ops))
        return all(self.holds(r, corners, sliding) for r in constraints)

    # -- searching one part's edit -------------------------------------------------

    def edit_part(self, state: _State, target: str, corners: Mapping[str, np.ndarray]) -> None:
        operand, moving = target, (target,)
        for group in self.shape.groups_of(target):
            members = self.shape.relations[group].members
            if group not in self.breaks and not (set(members) & state.decided):
                operand, moving = group, tuple(members)
                break
        constraints = [r for r in self.relations
                       if r.id not in state.rejected and r.id != operand and set(r.members) & set(moving)
                       and set(r.members) <= set(moving) | state.decided]
        state.stats["searches"] += 1
        choice = self.search(state, operand, moving, constraints, corners) if constraints else None
        if choice is not None:
            op, broken = choice
            if isinstance(op, list):  # a group layout: parent scaling plus change_count
                state.ops.extend(op)
            elif op is not None:  # a breaking-edit may be to leave the part where it is
                state.ops.append(op)
            state.reject(broken, "breaking-edit", operand)
        else:
            state.stats["unfixed_parts"] += 1
            state.reject([r for r in constraints if not self.holds(r, corners)],
                         "no-candidate", operand)
        state.decided.update(moving)
        state.decided.add(operand)

    def search(self, state: _State, operand: str, moving: tuple[str, ...], constraints: list[Relation],
               corners: Mapping[str, np.ndarray], breaking: bool = True
               ) -> tuple[EditOp | list[EditOp] | None, tuple[str, ...]] | None:
        """The chosen edit and the constraints it leaves broken; ``None`` when nothing helps."""
        hint = self.hints.get(operand) or self.hints.get(moving[0])
        hexahedron = self.shape.part(operand).hexahedron
        rest = {m: self.rest[m] for m in moving}
        # Contacts with laid-out group members may slide, so they cannot be screened as exact
        # equations: the exact ones are screened, the sliding ones checked on the survivors.
        sliding = sliding_members(self.shape, self.program(state.ops)) - set(moving)
        exact = [r for r in constraints if not set(r.members) & sliding] or constraints
        soft = [r for r in constraints if r not in exact]
        others = {m: corners[m] for r in exact for m in r.members if m not in rest}
        # When no edit of the part can keep the constraints every stage screens exactly
        # (feasibility.py), no stage finds a valid edit: only a breaking-edit may follow.
        hopeless = moving == (operand,) and self.hopeless(operand, constraints, corners, sliding)
        if hopeless:
            state.stats["hopeless_searches"] = state.stats.get("hopeless_searches", 0) + 1
            if not (self.options.breaking and breaking):
                return None
        check = self.sliding_check(corners, rest, soft, sliding)
        memo: dict = {}  # candidates' residual rows, screened again by the fallbacks below
        own = own_candidates(operand, hexahedron, hint)
        if operand in self.shape.virtual_parents:  # a group is edited as a whole, never by a feature
            own = [op for op in own if op.feature is None]
        copies = self.copied_edits(state, operand, moving, hint) if self.options.nhbd else []
        if not soft and self.options.nhbd and all(set(r.members) & sliding for r in constraints):
            outright = self.row_edit(state, operand, moving, constraints, hint, sliding)
            if outright is not None:
                state.stats["nhbd_edits"] += 1
                return outright, ()
        found = None
        if not hopeless:
            spanning = {id(op) for op in copies if self.spans(op, self.copy_sources[id(op)])}
            found = self.screen_and_pick(state, own + copies, rest, others, exact, check=check, memo=memo,
                                         preferred={id(op) for op in copies}, spanning=spanning)
        if found is not None and any(found[0].op is op for op in copies):
            state.stats["nhbd_edits"] += 1
        extra: list = []
        if found is None and self.options.nhbd:
            extra = self.neighbour_candidates(state, operand, moving, hexahedron, hint)
            if not hopeless:
                found = self.screen_and_pick(state, extra, rest, others, exact, check=check, memo=memo)
            if found is None:
                # Parameters read off the constraints themselves: a scaling about the origin
                # that keeps both ends of a spanning part, a translation in any direction.
                compounds = compound_candidates(operand, hexahedron, directions(hexahedron), hint)
                if not hopeless:
                    found = self.screen_and_pick(state, compounds, rest, others, exact, check=check, memo=memo)
                extra = extra + compounds
            if found is not None:
                state.stats["nhbd_edits"] += 1
        faces = [r for r in exact if isinstance(r, Attachment) and r.contact == "face"]
        if found is None and faces and len(faces) < len(exact) and not hopeless:
            # Faces in contact may slide along each other (report.relation_error): keep the
            # other constraints exactly and check the faces as sliding contacts.
            firm = [r for r in exact if r not in faces]
            loose = self.sliding_check(corners, rest, soft + faces, sliding)
            firm_others = {m: corners[m] for r in firm for m in r.members if m not in rest}
            found = self.screen_and_pick(state, own + copies + extra, rest, firm_others, firm, check=loose, memo=memo,
                                         preferred={id(op) for op in copies})
            if found is not None:
                exact, others = firm, firm_others
        if found is None and self.options.breaking and breaking:
            found = self.screen_and_pick(state, own + extra, rest, others, exact, breaking=True, memo=memo)
            if found is not None:
                state.stats["breaking_edits"] += 1
        rigid = found is not None and not found[1] and found[0].op.name in ("translate", "rotate") \
            and found[0].op.feature is None
        if operand in self.shape.virtual_parents and not rigid:
            layout = self.layout_edit(state, operand, constraints, corners)
            if layout is not None:
                state.stats["layout_edits"] = state.stats.get("layout_edits", 0) + 1
                return layout, ()
        if found is None:
            return None
        screened, broken = found
        if np.abs(screened.f).max() < 1e-12:
            return None, broken
        if screened.kind == "compound":
            ops = self.compound_form(state, screened, rest, exact, broken)
            return (ops or None, broken) if ops is not None else None
        op = self.closed_form(state, screened, rest, exact, broken)
        if op is not None and op.amount == "0":  # round-off of a breaking-edit that stays put
            return None, broken
        return (op, broken) if op is not None else None

    def layout_edit(self, state: _State, group: str, constraints: list[Relation],
                    corners: Mapping[str, np.ndarray]) -> list[EditOp] | None:
        """Re-lay out a translation group instead of deforming it (reference section 3, top-down).

        The group's virtual parent is scaled along the step so that the first and last
        instances follow what they are attached to, and ``change_count`` keeps the
        spacing near its rest value: stretching a shelf adds boards rather than
        thickening them. Accepted only if every member's relations then hold, the
        inner instances sliding along the parts they rest on.
        """
        relation = self.shape.relations[group]
        if not isinstance(relation, TranslationSymmetry) or len(relation.members) < 2:
            return None
        members = relation.members
        anchors = (members[0], members[-1])
        inner = set(members) - set(anchors)
        anchor_constraints = [r for r in constraints if set(r.members) & set(anchors) and not set(r.members) & inner]
        step = np.asarray(relation.step, dtype=float)
        if not anchor_constraints or np.linalg.norm(step) < 1e-12:
            return None
        direction = step / np.linalg.norm(step)
        origins = list(self.shape.part(group).hexahedron.feature_points)
        origins += [np.asarray(op.origin) for op in state.ops if hasattr(op, "origin") and op.acts_on == "part"]
        unique: dict[float, np.ndarray] = {}
        for origin in origins:
            unique.setdefault(round(float(origin @ direction), 7), origin)
        candidates = [AnchorScale(group, tuple(map(float, o)), tuple(map(float, direction))) for o in unique.values()]
        rest = {m: self.rest[m] for m in anchors}
        others = {m: corners[m] for r in anchor_constraints for m in r.members if m not in rest}
        results = screen(candidates, rest, others, anchor_constraints, self.tolerance)
        sliding = set(members)
        proposals = []
        for screened in results:
            if not screened.broken and np.abs(screened.f).max() > 1e-12:
                try:
                    proposals.append((screened.op.origin, self.amount_text(state, screened, rest, anchor_constraints,
                                                                           ())))
                except ValueError:
                    continue
        # A row framed by a scaled neighbour can also take that neighbour's scaling outright.
        proposals += [(op.origin, op.amount) for op in state.ops if isinstance(op, Scale1D) and op.feature is None
                      and abs(float(np.dot(op.dir, direction))) > 0.999]
        for origin, text in proposals:
            scale = Scale1D(group, text, origin=origin, dir=tuple(map(float, direction)))
            count = ChangeCount(group, f"{len(members) - 1}*({text})", mode="top_down")
            trial = self.corners(state.ops + [scale, count])
            if all(self.holds(r, trial, sliding) for r in constraints):
                return [scale, count]
        return None

    def neighbour_candidates(self, state: _State, operand: str, moving: tuple[str, ...], hexahedron,
                             hint: str | None) -> list[EditOp]:
        ops = self.neighbour_ops(state, moving)
        neighbours = sorted({op.operand for op in ops})
        boxes = [self.shape.part(n).hexahedron for n in neighbours]
        return neighbour_candidates(operand, hexahedron, ops, boxes, hint)

    def neighbour_ops(self, state: _State, moving: Sequence[str]) -> list[EditOp]:
        """The part ops of edited neighbours, a neighbour's group's virtual parent included."""
        neighbours = {n for m in moving for n in self.shape.neighbours(m)} - set(moving)
        operands = set(neighbours)
        for n in neighbours:
            if n in self.shape.parts:
                operands.update(self.shape.groups_of(n))
        operands -= set(moving)
        return [op for op in state.ops if op.operand in operands and op.acts_on == "part"
                and not isinstance(op, KeepFixed)]

    def copied_edits(self, state: _State, operand: str, moving: Sequence[str], hint: str | None) -> list[EditOp]:
        """Edited neighbours' own ops (same origin and direction, amount to solve) for this part.

        When no rigid edit keeps a part's contacts, the edit of the part it sits on usually
        does: a back cushion between two arms stretches about the seat's centre like the
        seat, rather than moving one face by whatever keeps its two nearest contacts.
        """
        out: dict[tuple, EditOp] = {}
        for op in self.neighbour_ops(state, moving):
            copy = _copied(op, operand, "f", hint)
            if copy is None:
                continue
            key = (copy.name, tuple(sorted(copy.params().items())))
            if key not in out:
                out[key] = copy
                self.copy_sources[id(copy)] = op.operand
        return list(out.values())

    def row_edit(self, state: _State, operand: str, moving: Sequence[str], constraints: list[Relation],
                 hint: str | None, sliding: set[str]) -> EditOp | None:
        """A re-laid-out row's own op, amount and all, for a part that only touches the row.

        The instances of a row laid out again keep their size and slide along what they
        touch, so no equation in one amount holds for them exactly and the CAS has no closed
        form to derive (the layout is discrete in the count). The rail on top of a row of
        spindles that widens with the seat simply takes the row's scaling: accepted when
        every contact then holds as a sliding contact.
        """
        groups = {g for m in sliding for g in self.shape.groups_of(m)} & laid_out_groups(self.program(state.ops))
        for op in state.ops:
            copy = _copied(op, operand, op.amount, hint) if op.operand in groups and op.acts_on == "part" else None
            if copy is None:
                continue
            trial = self.corners(state.ops + [copy])
            if all(self.holds(r, trial, sliding) for r in constraints):
                return copy
        return None

    def spans(self, copy: EditOp, source: str) -> bool:
        """Whether the part spans its neighbour along the directions a copied scaling stretches
        (at least half its extent): a side panel deepened with the top, not a leg."""
        directions = [np.asarray(copy.dir)] if hasattr(copy, "dir") and copy.name == "scale_1d" else (
            [v for v in np.eye(3) if abs(float(v @ np.asarray(copy.normal))) < 0.9]
            if copy.name == "scale_2d" else list(np.eye(3)) if copy.name == "scale_3d" else [])
        if not directions:
            return False
        mine = self.shape.part(copy.operand).hexahedron.corners
        theirs = self.shape.part(source).hexahedron.corners
        return all(np.ptp(mine @ d) >= 0.5 * np.ptp(theirs @ d) for d in directions)

    def sliding_check(self, corners, rest, soft: list[Relation], sliding: set[str]):
        """A function giving the first of some ranked screened candidates that also keeps the
        sliding contacts ``soft`` (``None`` if none does), or ``None`` without such contacts.

        Candidates are checked in batches of growing size (1, 4, 16, ...), one evaluation of
        every contact per batch; an error within a relative 1e-9 of its allowance is
        checked again for that candidate alone, so the choice is that of checking one
        candidate after another."""
        if not soft:
            return None

        def trial(chunk: Sequence[Screened]) -> dict[str, np.ndarray]:
            out = dict(corners)
            for pid, c in rest.items():
                out[pid] = np.stack([s.op.apply(c, s.f if s.kind == "compound" else s.f[:, None, None], np)
                                     for s in chunk])
            return out

        def keeps(chunk: Sequence[Screened]) -> np.ndarray:
            moved = trial(chunk)
            kept = np.ones(len(chunk), dtype=bool)
            for r in soft:
                alive = np.flatnonzero(kept)
                if not alive.size:
                    break
                rows = {m: moved[m][alive] if m in rest else moved[m] for m in r.members}
                errors = batch_relation_errors(r, rows, sliding)
                allowed = r.allowance(self.tolerance)
                holds = errors < allowed
                for i in np.flatnonzero(np.abs(errors - allowed) <= 1e-9 * allowed):
                    one = {m: c[i] if m in rest else c for m, c in rows.items()}
                    holds[i] = self.holds(r, one, sliding)
                kept[alive] = holds
            return kept

        def first_keeping(ranked: Sequence[Screened]) -> Screened | None:
            start, size = 0, 1
            while start < len(ranked):
                chunk = ranked[start:start + size]
                hit = np.flatnonzero(keeps(chunk))
                if hit.size:
                    return chunk[int(hit[0])]
                start, size = start + size, size * 4
            return None

        return first_keeping

    def screen_and_pick(self, state: _State, candidates: list[EditOp], rest, others, constraints,
                        breaking: bool = False, check=None, preferred: set[int] = frozenset(),
                        spanning: set[int] = frozenset(), memo: dict | None = None
                        ) -> tuple[Screened, tuple[str, ...]] | None:
        clock = time.perf_counter()
        state.stats["candidates_screened"] += len(candidates)
        if breaking:
            # The edit that breaks the constraints least, by the size of the errors it
            # leaves, not their number: a stretch that misses six contacts by 0.001 beats a
            # slide that tears three off by 0.9.
            lazy = breaking_table(candidates, rest, others, constraints, self.tolerance, memo=memo)
            state.stats["time_s"]["screen"] += time.perf_counter() - clock
            best = self.least_breaking(lazy, len(constraints), rest)
            return (best, best.broken) if best is not None else None
        table = screen_table(candidates, rest, others, constraints, self.tolerance, memo=memo, valid_only=True)
        state.stats["time_s"]["screen"] += time.perf_counter() - clock
        pool = [table.screened(i) for i in table.order[table.nbroken[table.order] == 0]]
        state.stats["candidates_valid"] += len(pool)
        if not pool:
            return None
        ranked = self.rank(pool, rest, preferred, spanning)
        best = check(ranked) if check is not None else ranked[0] if ranked else None
        return (best, best.broken) if best is not None else None

    def least_breaking(self, table: BreakingTable, constraints: int, rest: Mapping[str, np.ndarray]
                       ) -> Screened | None:
        """The breaking-edit to take (breaking.least_breaking): the best ranked (:meth:`rank`)
        of those whose total error is within 1% of the least among the edits that are not
        too distorting."""
        return breaking_module.least_breaking(
            table, constraints, lambda chunk: self._distortion(chunk, rest, planes=False)[0],
            lambda rows: self.best_row(table, rows, rest), self.tolerance, HIGH_DISTORTION)

    def best_row(self, table: BreakingTable, rows: np.ndarray, rest: Mapping[str, np.ndarray]) -> int | None:
        """The row (a position in ``table``) of ``rank([table.screened(i) for i in rows], rest)[0]``,
        ``None`` when that ranking is empty: the breaking-edits within 1% of the least error
        are hundreds, and only the best is taken, so only it is made a :class:`Screened`."""
        rows = np.asarray(rows, dtype=int)
        rows = rows[table.finite[rows]]
        if not rows.size:
            return None
        ops, kinds, last = table.ops_at_end(rows)
        energy, planes = self._distortion_at(ops, kinds, last, rest)
        order = self._ranked(ops, table.index[rows].tolist(), energy, planes)
        return int(rows[order[0]]) if order else None

    @staticmethod
    def _distortion(pool: list[Screened], rest: Mapping[str, np.ndarray], planes: bool = True
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Mean ARAP energy over the moving parts and symmetry planes kept, per screened edit,
        at the end of the range."""
        return Propagation._distortion_at([s.op for s in pool], [s.kind for s in pool], [s.f[-1] for s in pool],
                                          rest, planes)

    @staticmethod
    def _distortion_at(ops: list, kinds: list[str], last: list, rest: Mapping[str, np.ndarray],
                       planes: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_distortion` of edits given by their ops, kinds and amounts at the last sample."""
        energy = np.zeros(len(ops))
        counts = np.zeros(len(ops))
        plain = [i for i, kind in enumerate(kinds) if kind != "compound"]
        compound = [i for i, kind in enumerate(kinds) if kind == "compound"]
        plain_ops, amounts = [ops[i] for i in plain], [float(last[i]) for i in plain]
        for corners in rest.values():
            edited = np.empty((len(ops), 8, 3))
            edited[plain] = apply_each(plain_ops, corners, amounts)
            for i in compound:
                edited[i] = ops[i].apply(corners, last[i], np)
            energy += arap_energies(corners, edited)
            if planes:
                counts += symmetry_plane_counts(edited)
        energy /= len(rest)
        return energy, counts

    def rank(self, pool: list[Screened], rest: Mapping[str, np.ndarray], preferred: set[int] = frozenset(),
             spanning: set[int] = frozenset()) -> list[Screened]:
        """Best first: high-distortion edits dropped, then copies of a neighbour's scaling that
        the part spans (``spanning``), rigid edits, other copies of an edited neighbour's edit
        (``preferred``), then most symmetry planes, least ARAP energy, simplest op, candidate
        order."""
        pool = [s for s in pool if np.isfinite(s.f).all()]
        if not pool:
            return []
        energy, planes = self._distortion(pool, rest)
        order = self._ranked([s.op for s in pool], [s.index for s in pool], energy, planes, preferred, spanning)
        return [pool[i] for i in order]

    @staticmethod
    def _ranked(ops: Sequence, index: Sequence[int], energy: np.ndarray, planes: np.ndarray,
                preferred: set[int] = frozenset(), spanning: set[int] = frozenset()) -> list[int]:
        """:meth:`rank`'s order of edits given by their ops, candidate indices and distortion
        (:meth:`_distortion_at`): their positions, best first, the high-distortion ones left out."""
        scored = []
        for i, (op, e, p) in enumerate(zip(ops, energy, planes)):
            if e > HIGH_DISTORTION:
                continue
            family = candidate_family(op)
            simplicity = SIMPLICITY.index(family) if family in SIMPLICITY else len(SIMPLICITY)
            rigid = e < 1e-9
            tier = 0 if id(op) in spanning else 1 if rigid else 2 if id(op) in preferred else 3
            scored.append((tier, -p, round(float(e), 9), simplicity, index[i], i))
        scored.sort(key=lambda t: t[:5])
        return [t[-1] for t in scored]

    def _kept_residual(self, state: _State, rest, constraints, broken):
        """The symbolic residual of the kept constraints, and its columns in the screened rows."""
        kept = [r for r in constraints if r.id not in broken]
        others = sorted({m for r in kept for m in r.members if m not in rest})
        symbolic = self.symbolic_parts(state.ops, others)
        residual = symbolic_residual(kept, {**symbolic, **rest})
        columns = np.concatenate([np.arange(s.start, s.stop) for s, r in zip(residual_slices(constraints, self.rest),
                                                                            constraints) if r.id not in broken])
        return residual, columns

    def amount_text(self, state: _State, screened: Screened, rest, constraints, broken) -> str:
        """The screened amount's closed form, derived with the CAS (affine candidates)."""
        residual, columns = self._kept_residual(state, rest, constraints, broken)
        return amount_text(self.backend, affine_amount(self.backend, screened.a[columns], residual))

    def closed_form(self, state: _State, screened: Screened, rest, constraints, broken) -> EditOp | None:
        """Derive the winner's amount with the CAS and check it against the screened values."""
        clock = time.perf_counter()
        residual, columns = self._kept_residual(state, rest, constraints, broken)
        op = screened.op
        if screened.kind == "affine":
            try:
                expr = affine_amount(self.backend, screened.a[columns], residual)
            except ValueError:
                return None
            if isinstance(op, Translate) and op.feature is None and screened.f[-1] < 0:
                # a move to the left reads better as dir=(-1, 0, 0), amount=+...
                op = dataclasses.replace(op, dir=tuple(-c + 0.0 for c in op.dir))
                expr = self.backend.expand(-expr)
        else:
            expr = rotation_amount(self.backend, screened.a[columns], self._offset(screened, columns), residual)
        try:
            text = amount_text(self.backend, expr)
            finite = np.all(np.isfinite(evaluate_amount(text, self.parameter.name, self.xs)))
        except (ParselError, ValueError):  # a residual term that is not finite
            return None
        if not finite:
            return None
        if screened.kind == "rotation":
            known = sorted({op.amount for op in state.ops if op.amount not in ("0", "f")})
            text = simpler_equivalent(text, known, self.parameter.name, self.xs)
        state.stats["time_s"]["derive"] += time.perf_counter() - clock
        values = evaluate_amount(text, self.parameter.name, self.xs)
        if op is not screened.op:
            values = -values
        if not np.allclose(values, screened.f, atol=1e-6 * max(1.0, float(np.abs(screened.f).max()))):
            if screened.kind == "affine" and not broken:
                return None
        return dataclasses.replace(op, amount=text)

    def compound_form(self, state: _State, screened: Screened, rest, constraints, broken) -> list[EditOp] | None:
        """The fewest ops equal to a screened compound, each amount derived with the CAS.

        The basis amounts are ``f = -pinv(A^T) r(x)`` over the kept constraints' residual
        columns; every output op's amount is a fixed combination of them (compound.simplify).
        """
        clock = time.perf_counter()
        residual, columns = self._kept_residual(state, rest, constraints, broken)
        solver = compound_solver(screened.a, columns)                    # (B, K')
        compound: Compound = screened.op
        ops = []
        for term in simplify(compound, screened.f, self.shape.size):
            weights = -(np.asarray(term.weights) @ solver)
            if not np.all(np.isfinite(weights)):
                return None
            expr = self.backend.expand(linear_combination(self.backend, weights, residual))
            try:
                text = amount_text(self.backend, expr)
                if not np.all(np.isfinite(evaluate_amount(text, self.parameter.name, self.xs))):
                    return None
            except (ParselError, ValueError):  # a residual term that is not finite
                return None
            values = evaluate_amount(text, self.parameter.name, self.xs)
            expected = screened.f @ np.asarray(term.weights)
            if not broken and not np.allclose(values, expected, atol=1e-6 * max(1.0, float(np.abs(expected).max()))):
                return None
            if text != "0":
                ops.append(dataclasses.replace(term.op, amount=text))
        state.stats["time_s"]["derive"] += time.perf_counter() - clock
        return ops

    @staticmethod
    def _offset(screened: Screened, columns) -> np.ndarray:
        return screened.offset[columns]


def _copied(op: EditOp, operand: str, amount: str, hint: str | None) -> EditOp | None:
    """``op`` with its origin and direction on another operand, or ``None``: an op on a
    feature, one whose parameters do not fit, or one the operand's type hint excludes."""
    if op.feature is not None:
        return None
    try:
        copy = type(op)(operand, amount, **op.params())
    except Exception:  # an operator whose parameters do not fit another operand
        return None
    if hint in HINT_TYPES and candidate_family(copy) not in HINT_TYPES[hint]:
        return None
    return copy


class AnchorScale:
    """Screening stand-in for "scale the virtual parent, lay the group out top-down".

    Under that layout an anchor member keeps its shape and moves with its centre:
    ``c -> o + (c - o) + f ((c - o) . n) n``, a translation affine in ``f``.
    """

    name = "scale_1d"
    feature = None
    acts_on = "part"

    def __init__(self, operand: str, origin, direction) -> None:
        self.operand, self.origin, self.dir = operand, origin, direction

    def apply(self, corners: np.ndarray, amount, math) -> np.ndarray:
        n = np.asarray(self.dir)
        centre = corners.mean(axis=-2, keepdims=True)
        along = (centre - np.asarray(self.origin)) @ n
        return corners + along[..., None] * n * amount


def propagate(request: SolveRequest) -> SolveResult:
    """Run AEP on a request (see :class:`Propagation`).

    BLAS runs on one thread throughout: the systems are small (at most a few hundred
    rows), OpenBLAS's threads cost many times their work in CPU time on a busy machine,
    and their rounding depends on the thread count, so one thread also makes the
    program the same bits whatever the number of cores (not whatever the processor:
    docs/aep.md). The cyclic garbage collector runs less often meanwhile
    (parsel_core.collector)."""
    if not started_on_one_thread():  # (else they load at the first system they solve, on one thread)
        cluster_module.lapack_wrappers()  # (before the block, which then keeps their OpenBLAS on one thread)
    with one_blas_thread(), fewer_collections():
        return Propagation(request).run()


def group_ids(shape: ShapeGraph) -> list[str]:
    return [rid for rid, r in shape.relations.items() if r.kind in GROUP_KINDS]
