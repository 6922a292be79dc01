"""Relation reports: which relations a program keeps over its whole parameter range.

A relation is *kept* when its constraint holds (``||C||_inf < tol``) at every sampled
parameter value, *broken on purpose* when the user (or the language model) allowed it
to break, and *broken* otherwise (paper eq. 1: checked at random samples of the range,
both ends included).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.cage import batched_cube_coordinates
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import CORNER_BITS
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

    def to_dict(self) -> dict[str, Any]:
        return {"id": self.id, "kind": self.kind, "members": list(self.members), "state": self.state,
                "max_error": self.max_error}


@dataclass
class RelationReport:
    """Every relation of a shape with its state under a program."""

    relations: list[RelationState]
    tolerance: float
    samples: int
    extra: dict[str, Any] = field(default_factory=dict)

    def states(self) -> dict[str, str]:
        return {r.id: r.state for r in self.relations}

    def counts(self) -> dict[str, int]:
        out = {"kept": 0, "broken_on_purpose": 0, "broken": 0}
        for r in self.relations:
            out[r.state] += 1
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"tolerance": self.tolerance, "samples": self.samples, "counts": self.counts(),
                "relations": [r.to_dict() for r in self.relations], **self.extra}


def sliding_error(relation: Attachment, corners: Mapping[str, np.ndarray], member: str) -> np.ndarray:
    """How far a laid-out group member's contact slid *off* the other part, per sample.

    When a group's count or spacing changes, its instances sit at new places along the
    part they rest on (boards along a side panel, slats along a rail), so the contact
    cannot stay at fixed cage coordinates of that part. It must stay on the same face:
    the contact point keeps the other part's cage coordinates that were on its boundary
    (0 or 1) and stays within [0, 1] in the others. Errors are in world units.
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
        uvw = batched_cube_coordinates(target, points)
    except np.linalg.LinAlgError:  # a degenerate cage: the contact cannot be located
        errors[present] = np.inf
        return errors
    extents = np.linalg.norm(np.stack([target[:, 4] - target[:, 0], target[:, 2] - target[:, 0],
                                       target[:, 1] - target[:, 0]], axis=1), axis=-1)  # (B, 3)
    drift = np.where(on_boundary, np.abs(uvw - rest_uvw), np.maximum(0, -uvw) + np.maximum(0, uvw - 1))
    errors[present] = (drift * extents[:, None, :]).max(axis=(-1, -2))
    return errors


def relation_error(relation: Relation, corners: Mapping[str, np.ndarray], sliding: Iterable[str] = ()) -> float:
    """Largest constraint error over the samples; attachments of laid-out members may slide."""
    sliding = set(sliding)
    if isinstance(relation, Attachment):
        members = [m for m in relation.members if m in sliding]
        if members:
            return float(max(np.max(sliding_error(relation, corners, m)) for m in members))
    errors = np.asarray(relation.error(corners), dtype=float)
    errors = errors[~np.isnan(errors)]  # removed members (NaN corners) are not checked
    error = float(errors.max()) if errors.size else 0.0
    if error > 0 and isinstance(relation, Attachment) and relation.contact == "face":
        # Two faces in contact stay attached while they stay flush and one stays within the
        # other: a board may slide along the panel it rests on (docs/relations.md).
        error = min(error, min(float(np.max(sliding_error(relation, corners, m))) for m in relation.members))
    return error


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
    started = time.perf_counter()
    corners = evaluator(program, shape, backend)(sample_values(program, samples)).parts
    logger.debug(f"evaluated {len(program.ops)} ops at {samples} parameter values with "
                 f"{backend or 'the numpy reference'} in {time.perf_counter() - started:.3f} s")
    states = []
    for rid, error in relation_errors(shape, corners, sliding_members(shape, program)).items():
        relation = shape.relations[rid]
        state = "kept" if error < relation.allowance(tolerance) else "broken_on_purpose" if rid in breaks else "broken"
        states.append(RelationState(rid, relation.kind, relation.members, state, error))
    return RelationReport(states, tolerance, samples)


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


def check_each_parameter(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
                         samples: int = DEFAULT_SAMPLES, tolerance: float | None = None) -> dict[str, dict[str, int]]:
    """State counts with one slider moving at a time, the others at their lower end.

    Stacked programs (proxydural models) are solved one request at a time, so each slider
    keeps what its own program keeps; moving several at once composes edits whose origins
    were fixed for the rest shape and can break more.
    """
    breaks = set(breaks)
    tolerance = tolerance_for(shape) if tolerance is None else tolerance
    sliding = sliding_members(shape, program)
    out = {}
    for i, parameter in enumerate(program.parameters):
        values = {p.name: np.full(samples, p.lo) for p in program.parameters}
        values[parameter.name] = parameter.samples(samples, seed=i)
        corners = evaluate(program, shape, values).parts
        counts = {"kept": 0, "broken_on_purpose": 0, "broken": 0}
        for rid, error in relation_errors(shape, corners, sliding).items():
            kept = error < shape.relations[rid].allowance(tolerance)
            counts["kept" if kept else "broken_on_purpose" if rid in breaks else "broken"] += 1
        out[parameter.name] = counts
    return out
