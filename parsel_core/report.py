"""Relation reports: which relations a program keeps over its whole parameter range.

A relation is *kept* when its constraint holds (``||C||_inf < tol``) at every sampled
parameter value, *broken on purpose* when the user (or the language model) allowed it
to break, and *broken* otherwise (paper eq. 1: checked at random samples of the range,
both ends included).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.program import Program, evaluate

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


def relation_errors(shape: ShapeGraph, corners: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Largest constraint error of each relation over the sampled corners."""
    return {rid: float(np.max(r.error(corners))) for rid, r in shape.relations.items()}


def check_program(shape: ShapeGraph, program: Program, breaks: Iterable[str] = (),
                  samples: int = DEFAULT_SAMPLES, tolerance: float | None = None) -> RelationReport:
    """The relation report of ``program`` on ``shape`` (``parsel check``)."""
    breaks = set(breaks)
    for rid in breaks:
        shape.relation(rid)
    tolerance = tolerance_for(shape) if tolerance is None else tolerance
    corners = evaluate(program, shape, sample_values(program, samples)).parts
    states = []
    for rid, error in relation_errors(shape, corners).items():
        relation = shape.relations[rid]
        state = "kept" if error < tolerance else "broken_on_purpose" if rid in breaks else "broken"
        states.append(RelationState(rid, relation.kind, relation.members, state, error))
    return RelationReport(states, tolerance, samples)
