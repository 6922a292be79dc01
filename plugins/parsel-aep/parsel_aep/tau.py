"""Choosing the parameter range [0, tau] automatically (reference section 4).

tau is the largest value up to which the seed edit leaves every hexahedron it moves
non-degenerate: no corner turned inside out, no side collapsed.
"""

from __future__ import annotations

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import corner_jacobians
from parsel_core.program import Parameter, Program, evaluate

#: A hexahedron whose smallest side or volume shrinks below this fraction counts as collapsed.
COLLAPSE = 0.05

def degenerate(rest: np.ndarray, edited: np.ndarray) -> np.ndarray:
    """Which samples (...,) of an edited hexahedron are flipped or collapsed (the frame at a
    corner turned inside out, or shrunk below COLLAPSE of its rest volume)."""
    removed = np.isnan(edited).all(axis=(-1, -2))  # an instance a count change took away
    with np.errstate(invalid="ignore", over="ignore"):
        orientation = corner_jacobians(np.where(removed[..., None, None], rest, edited))
        rest_orientation = corner_jacobians(rest)
        flipped = np.any(~(orientation * np.sign(rest_orientation) > COLLAPSE * np.abs(rest_orientation)), axis=-1)
    return flipped & ~removed


def automatic_tau(shape: ShapeGraph, seed: Program, tau_max: float = 1.0, steps: int = 200) -> float:
    """The largest tau <= tau_max for which the seed keeps its hexahedra non-degenerate."""
    parameter = seed.parameters[0]
    probe = Program(seed.ops, (Parameter(parameter.name, 0.0, tau_max),) + seed.parameters[1:])
    values = np.linspace(0.0, tau_max, steps + 1)[1:]
    corners = evaluate(probe, shape, {parameter.name: values}).parts
    moved = {op.operand for op in seed.ops if op.acts_on == "part"}
    for op in seed.ops:
        if op.operand in shape.virtual_parents:
            moved.update(shape.relations[op.operand].members)
    bad = np.zeros(values.shape, dtype=bool)
    rest = shape.rest_corners()
    for pid in moved:
        bad |= degenerate(rest[pid], corners[pid])
    if not bad.any():
        return float(tau_max)
    first = int(np.argmax(bad))
    if first == 0:
        raise ParselError("the seed edit collapses or flips a part at once; give it a smaller amount or --tau")
    return float(np.floor(values[first - 1] * 1000) / 1000)
