"""Relation reports: which relations a program keeps over its whole parameter range.

A relation is *kept* when its constraint holds (``||C||_inf < tol``) at every sampled
parameter value, *broken on purpose* when the user (or the language model) allowed it
to break, and *broken* otherwise (paper eq. 1: checked at random samples of the range,
both ends included). A program with several parameters is checked on the joint box of
ranges: its corners, then random points (``parsel_core.joint.joint_samples``); each
relation's report names the sample where its error is largest.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.cage import approximate_cube_coordinates, batched_cube_coordinates
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import CORNER_BITS
from parsel_core.joint import joint_samples, sample_at
from parsel_core.program import Program, evaluate, evaluator, laid_out_groups
from parsel_core.relations import Attachment, Relation
from parsel_core.verbosity import logger

#: Default constraint tolerance as a fraction of the shape's size.
RELATIVE_TOLERANCE = 1e-4
DEFAULT_SAMPLES = 50


def tolerance_for(shape: ShapeGraph, relative: float = RELATIVE_TOLERANCE) -> float:
    return relative * shape.size


def sample_values(program: Program, count: int = DEFAULT_SAMPLES, seed: int = 0) -> dict[str, np.ndarray]:
    """``count`` joint samples of every parameter (ends of each range included)."""
    return {p.name: p.samples(count, seed=seed + i) for i, p in enumerate(program.parameters)}


@dataclass
class RelationState:
    id: str
    kind: str
    members: tuple[str, ...]
    state: str  # "kept" | "broken_on_purpose" | "broken"
    max_error: float
    #: Parameter values of the joint sample with the largest error (programs with several parameters).
    worst_at: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        data = {"id": self.id, "kind": self.kind, "members": list(self.members), "state": self.state,
                "max_error": self.max_error}
        if self.worst_at is not None:
            data["worst_at"] = dict(self.worst_at)
        return data


@dataclass
class RelationReport:
    """Every relation of a shape with its state under a program."""

    relations: list[RelationState]
    tolerance: float
    samples: int
    extra: dict[str, Any] = field(default_factory=dict)
    #: How many of the samples are corners of the box of ranges (0 for one parameter).
    box_corners: int = 0

    def states(self) -> dict[str, str]:
        return {r.id: r.state for r in self.relations}

    def counts(self) -> dict[str, int]:
        out = {"kept": 0, "broken_on_purpose": 0, "broken": 0}
        for r in self.relations:
            out[r.state] += 1
        return out

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {"tolerance": self.tolerance, "samples": self.samples}
        if self.box_corners:
            data["box_corners"] = self.box_corners
        return {**data, "counts": self.counts(), "relations": [r.to_dict() for r in self.relations], **self.extra}


def sliding_error(relation: Attachment, corners: Mapping[str, np.ndarray], member: str, strict: bool = False,
                  approximate: bool = False) -> np.ndarray:
    """How far a laid-out group member's contact slid *off* the other part, per sample.

    When a group's count or spacing changes, its instances sit at new places along the
    part they rest on (boards along a side panel, slats along a rail), so the contact
    cannot stay at fixed cage coordinates of that part. It must stay on the same face:
    the contact point keeps the other part's cage coordinates that were on its boundary
    (0 or 1) and stays within [0, 1] in the others. Errors are in world units. A
    degenerate cage makes every error infinite, or with ``strict`` raises
    ``LinAlgError``. With ``approximate`` the contact's cage coordinates are those of
    :func:`~parsel_core.cage.approximate_cube_coordinates` (the same to within rounding).
    """
    a, b = relation.members
    own_weights, other_weights = (relation.weights_a, relation.weights_b) if member == a else (
        relation.weights_b, relation.weights_a)
    other = b if member == a else a
    own = np.asarray(corners[member], dtype=float)
    target = np.asarray(corners[other], dtype=float)
    batch = np.broadcast_shapes(own.shape[:-2], target.shape[:-2])
    own, target = np.broadcast_to(own, batch + (8, 3)), np.broadcast_to(target, batch + (8, 3))
    rest_uvw = np.asarray(other_weights) @ CORNER_BITS                                  # (k, 3)
    on_boundary = (np.abs(rest_uvw) < 1e-9) | (np.abs(rest_uvw - 1) < 1e-9)
    # A removed instance (NaN corners) has no contact to keep.
    present = ~(np.isnan(own).any(axis=(-1, -2)) | np.isnan(target).any(axis=(-1, -2)))
    errors = np.zeros(batch)
    if not present.any():
        return errors
    own, target = own[present], target[present]
    points = np.asarray(own_weights) @ own                                              # (B, k, 3)
    try:
        uvw = (approximate_cube_coordinates if approximate else batched_cube_coordinates)(target, points)
    except np.linalg.LinAlgError:  # a degenerate cage: the contact cannot be located
        if strict:
            raise
        errors[present] = np.inf
        return errors
    extents = np.linalg.norm(np.stack([target[:, 4] - target[:, 0], target[:, 2] - target[:, 0],
                                       target[:, 1] - target[:, 0]], axis=1), axis=-1)  # (B, 3)
    drift = np.where(on_boundary, np.abs(uvw - rest_uvw), np.maximum(0, -uvw) + np.maximum(0, uvw - 1))
    errors[present] = (drift * extents[:, None, :]).max(axis=(-1, -2))
    return errors


def sample_errors(relation: Relation, corners: Mapping[str, np.ndarray], sliding: Iterable[str] = ()) -> np.ndarray:
    """The relation's error at each sample (NaN where a member was removed); its largest
    finite value is :func:`relation_error`. Attachments of laid-out members may slide."""
    sliding = set(sliding)
    if isinstance(relation, Attachment):
        members = [m for m in relation.members if m in sliding]
        if members:
            # A laid-out member may slide along its contact, or stay where it was.
            slide = np.max([np.asarray(sliding_error(relation, corners, m), dtype=float) for m in members], axis=0)
            exact = np.asarray(relation.error(corners), dtype=float)
            return np.where(np.isnan(exact), slide, np.fmin(exact, slide))
    errors = np.asarray(relation.error(corners), dtype=float)
    finite = errors[~np.isnan(errors)]  # removed members (NaN corners) are not checked
    error = float(finite.max()) if finite.size else 0.0
    if error > 0 and isinstance(relation, Attachment) and relation.contact == "face":
        # Two faces in contact stay attached while they stay flush and one stays within the
        # other: a board may slide along the panel it rests on (docs/relations.md).
        slides = [np.asarray(sliding_error(relation, corners, m), dtype=float) for m in relation.members]
        best = min(range(len(slides)), key=lambda i: float(np.max(slides[i])))
        if float(np.max(slides[best])) < error:
            return slides[best]
    return errors


def relation_error(relation: Relation, corners: Mapping[str, np.ndarray], sliding: Iterable[str] = (),
                   below: float | None = None) -> float:
    """Largest constraint error over the samples; attachments of laid-out members may slide.

    With ``below``, a face contact whose exact error is already under it is not checked as
    a sliding contact (which could only lower it): the exact error is returned. A caller
    that only compares the error with ``below`` gets the same answer for less."""
    if below is not None and isinstance(relation, Attachment) and relation.contact == "face" \
            and not set(relation.members) & set(sliding):
        exact = np.asarray(relation.error(corners), dtype=float)
        exact = exact[~np.isnan(exact)]
        largest = float(exact.max()) if exact.size else 0.0
        if largest < below:
            return largest
    errors = np.asarray(sample_errors(relation, corners, sliding), dtype=float)
    errors = errors[~np.isnan(errors)]
    return float(errors.max()) if errors.size else 0.0


def batch_relation_errors(relation: Relation, corners: Mapping[str, np.ndarray], sliding: Iterable[str] = ()
                          ) -> np.ndarray:
    """:func:`relation_error` of every row of a batch, (C,): corners of shape (C, S, 8, 3)
    (C alternatives, such as candidate edits, each at S samples) or (S, 8, 3) (the same in
    every row), in one evaluation with the rules of :func:`sample_errors` applied row by
    row. Values may differ from the row-by-row ones in the last bits (batched products, and
    sliding contacts located by :func:`~parsel_core.cage.approximate_cube_coordinates`):
    callers comparing them with a threshold re-check near-ties row by row."""
    sliding = set(sliding)
    rows = max(np.shape(corners[m])[0] for m in relation.members if np.ndim(corners[m]) == 4)
    exact = _rows(relation.error(corners), rows)
    slid = [m for m in relation.members if m in sliding] if isinstance(relation, Attachment) else []
    if slid:
        slide = np.max([_sliding_error_rows(relation, corners, m, rows) for m in slid], axis=0)
        return _largest(np.where(np.isnan(exact), slide, np.fmin(exact, slide)))
    largest = _largest(exact)
    if not (isinstance(relation, Attachment) and relation.contact == "face" and np.any(largest > 0)):
        return largest
    slides = [_sliding_error_rows(relation, corners, m, rows) for m in relation.members]
    worst = [s.max(axis=-1) for s in slides]  # NaN where a sample is NaN, as np.max
    best = np.zeros(rows, dtype=int)
    for i in range(1, len(slides)):  # min(range(k), key=...): the first of the least
        best = np.where(worst[i] < np.choose(best, worst), i, best)
    use = (largest > 0) & (np.choose(best, worst) < largest)
    chosen = np.choose(best[:, None], slides)
    return np.where(use, _largest(chosen), largest)


def _rows(values, rows: int) -> np.ndarray:
    """Per-sample values as (rows, S)."""
    values = np.asarray(values, dtype=float)
    return np.broadcast_to(values, (rows, values.shape[-1]))


def _largest(errors: np.ndarray) -> np.ndarray:
    """The largest value of each row that is not NaN (0 where every value is NaN)."""
    missing = np.isnan(errors)
    return np.where(missing.all(axis=-1), 0.0, np.where(missing, -np.inf, errors).max(axis=-1))


def _sliding_error_rows(relation: Attachment, corners: Mapping[str, np.ndarray], member: str, rows: int
                        ) -> np.ndarray:
    """:func:`sliding_error` of a batch, (rows, S); a degenerate cage makes only its own
    row infinite (for the whole batch at once it would make every row so)."""
    try:
        return _rows(sliding_error(relation, corners, member, strict=True, approximate=True), rows)
    except np.linalg.LinAlgError:
        return np.stack([np.asarray(sliding_error(relation, {m: c[row] if np.ndim(c) == 4 else c
                                                            for m, c in corners.items()}, member), dtype=float)
                         for row in range(rows)])


def relation_errors(shape: ShapeGraph, corners: Mapping[str, np.ndarray], sliding: Iterable[str] = ()
                    ) -> dict[str, float]:
    """Largest constraint error of each relation over the sampled corners."""
    return {rid: relation_error(r, corners, sliding) for rid, r in shape.relations.items()}


def sliding_members(shape: ShapeGraph, program: Program) -> set[str]:
    """Members of the groups whose layout the program changes."""
    return {m for g in laid_out_groups(program) for m in shape.relations[g].members}


def check_program(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
                  samples: int = DEFAULT_SAMPLES, tolerance: float | None = None,
                  backend: str | None = None) -> RelationReport:
    """The relation report of ``program`` on ``shape`` (``parsel check``); ``backend`` evaluates
    through that CAS backend's compiled program instead of the numpy reference."""
    from parsel_core.config import check_limit

    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 2:
        raise ParselError(f"samples must be an integer of at least 2 (both ends of the range), got {samples!r}")
    check_limit("max_samples", "parameter samples", samples)
    breaks = set(breaks)
    for rid in breaks:
        shape.relation(rid)
    tolerance = tolerance_for(shape) if tolerance is None else tolerance
    values, box = joint_samples(program, samples)
    started = time.perf_counter()
    corners = evaluator(program, shape, backend)(values).parts
    logger.debug(f"evaluated {len(program.ops)} ops at {samples} parameter values with "
                 f"{backend or 'the numpy reference'} in {time.perf_counter() - started:.3f} s")
    sliding = sliding_members(shape, program)
    joint = len(program.parameters) > 1
    states = []
    for rid, relation in shape.relations.items():
        errors = np.asarray(sample_errors(relation, corners, sliding), dtype=float).reshape(-1)
        finite = np.where(np.isnan(errors), -np.inf, errors)
        worst = int(np.argmax(finite)) if errors.size else 0
        error = float(finite[worst]) if errors.size and np.isfinite(finite[worst]) else 0.0
        state = "kept" if error < relation.allowance(tolerance) else "broken_on_purpose" if rid in breaks else "broken"
        at = sample_at(values, worst) if joint and errors.size == len(next(iter(values.values()))) else None
        states.append(RelationState(rid, relation.kind, relation.members, state, error, at))
    count = len(next(iter(values.values()))) if values else samples
    return RelationReport(states, tolerance, count, box_corners=box)


def report_from_errors(shape: ShapeGraph, errors: Mapping[str, float], breaks: Iterable[str] = (),
                       samples: int = DEFAULT_SAMPLES, tolerance: float | None = None) -> RelationReport:
    """The report of a solver that checked its own edits (the online baseline re-solves at
    each value, so its program alone, the seed, says nothing about the other parts)."""
    breaks = set(breaks)
    tolerance = tolerance_for(shape) if tolerance is None else tolerance
    states = []
    for rid, relation in shape.relations.items():
        error = float(errors.get(rid, 0.0))
        state = "kept" if error < relation.allowance(tolerance) else "broken_on_purpose" if rid in breaks else "broken"
        states.append(RelationState(rid, relation.kind, relation.members, state, error))
    return RelationReport(states, tolerance, samples)


def each_parameter_states(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
                          samples: int = DEFAULT_SAMPLES, tolerance: float | None = None
                          ) -> dict[str, dict[str, str]]:
    """Each relation's state with one slider moving at a time, the others at their lower end.

    What each slider keeps alone is what a program with several parameters must keep at
    every combination of them (the joint check, :func:`check_program`)."""
    breaks = set(breaks)
    tolerance = tolerance_for(shape) if tolerance is None else tolerance
    sliding = sliding_members(shape, program)
    out = {}
    for i, parameter in enumerate(program.parameters):
        values = {p.name: np.full(samples, p.lo) for p in program.parameters}
        values[parameter.name] = parameter.samples(samples, seed=i)
        corners = evaluate(program, shape, values).parts
        states = {}
        for rid, error in relation_errors(shape, corners, sliding).items():
            kept = error < shape.relations[rid].allowance(tolerance)
            states[rid] = "kept" if kept else "broken_on_purpose" if rid in breaks else "broken"
        out[parameter.name] = states
    return out


def check_each_parameter(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
                         samples: int = DEFAULT_SAMPLES, tolerance: float | None = None) -> dict[str, dict[str, int]]:
    """State counts with one slider moving at a time, the others at their lower end."""
    out = {}
    for name, states in each_parameter_states(shape, program, breaks, samples, tolerance).items():
        counts = {"kept": 0, "broken_on_purpose": 0, "broken": 0}
        for state in states.values():
            counts[state] += 1
        out[name] = counts
    return out


def kept_alone(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
               samples: int = DEFAULT_SAMPLES) -> set[str]:
    """Relations every slider keeps when it moves alone: the ones the joint box must keep."""
    per = each_parameter_states(shape, program, breaks, samples)
    return {rid for rid in shape.relations if all(states[rid] == "kept" for states in per.values())}
