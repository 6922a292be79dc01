"""Fitting a program's parameters to target points by the Chamfer distance (scipy).

The objective is the Chamfer distance between the edited shape's fixed surface samples
(``surface.SurfaceSampler``) and the target's points. Each parameter is mapped to
[0, 1] over its range, and scipy's bounded Powell search (derivative-free: the distance
is only piecewise smooth, nearest neighbours change as the shape moves) runs from
several starts: the program's defaults and a deterministic Latin-hypercube spread over
the box, on a quarter of the samples; the best end point is then refined on all of them,
and kept only if it beats the defaults, so the fit is never worse than the defaults.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.program import Program, evaluate
from parsel_fit.chamfer import ChamferTarget
from parsel_fit.surface import DEFAULT_SAMPLES, SurfaceSampler

DEFAULT_STARTS = 4
#: The coarse search uses one in this many samples and target points.
COARSE = 4


@dataclass
class FitResult:
    """Fitted values, the distance at the defaults and after, and what it cost."""

    values: dict[str, float]
    start_values: dict[str, float]
    distance_before: float
    distance_after: float
    evaluations: int
    cpu_s: float
    wall_s: float
    starts: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"values": self.values, "start_values": self.start_values,
                "distance_before": self.distance_before, "distance_after": self.distance_after,
                "evaluations": self.evaluations, "cpu_s": self.cpu_s, "wall_s": self.wall_s, "starts": self.starts}


def _starts(count: int, dims: int, seed: int) -> np.ndarray:
    """``count - 1`` Latin-hypercube points of [0, 1]^dims (the defaults are the other start)."""
    rng = np.random.default_rng(seed)
    n = max(count - 1, 0)
    if n == 0:
        return np.zeros((0, dims))
    cols = [(rng.permutation(n) + rng.random(n)) / n for _ in range(dims)]
    return np.stack(cols, axis=1)


def fit_program(shape: ShapeGraph, program: Program, target: np.ndarray, *, starts: int = DEFAULT_STARTS,
                samples: int = DEFAULT_SAMPLES, seed: int = 0, fixed: dict[str, float] | None = None,
                xtol: float = 1e-3) -> FitResult:
    """The parameter values (within their ranges) that bring the edited shape closest to ``target``.

    ``fixed`` holds parameters that are not fitted; every other parameter is. The starts
    are searched on a quarter of the samples and of the target (coarse), then the best end
    point is refined on all of them (fine); distances reported are the fine ones."""
    from scipy.optimize import minimize

    cpu0, wall0 = time.process_time(), time.perf_counter()
    program.validate(shape)
    fixed = dict(fixed or {})
    base = program.values(fixed)
    free = [p for p in program.parameters if p.name not in fixed and p.hi > p.lo]
    if not program.parameters:
        raise ParselError("the program has no parameter to fit")
    target = np.asarray(target, dtype=float)
    fine = (SurfaceSampler.of(shape, samples, seed), ChamferTarget(target))
    coarse = (SurfaceSampler.of(shape, max(samples // COARSE, 256), seed),
              ChamferTarget(target[:: COARSE] if len(target) >= 256 * COARSE else target))
    evaluations = 0

    def values_of(z: np.ndarray) -> dict[str, float]:
        out = dict(base)
        for p, zi in zip(free, np.clip(z, 0.0, 1.0)):
            out[p.name] = float(p.lo + zi * (p.hi - p.lo))
        return out

    def objective(z: np.ndarray, level=fine) -> float:
        nonlocal evaluations
        evaluations += 1
        sampler, chamfer = level
        points = sampler.points(shape, evaluate(program, shape, values_of(z)))
        return chamfer.distance(points) if len(points) else float("inf")

    def search(z_start: np.ndarray, level) -> tuple[np.ndarray, float]:
        result = minimize(objective, z_start, args=(level,), method="Powell", bounds=[(0.0, 1.0)] * len(free),
                          options={"xtol": xtol, "ftol": 1e-9, "maxfev": 400})
        return np.asarray(result.x, dtype=float), float(result.fun)

    z0 = np.array([(base[p.name] - p.lo) / (p.hi - p.lo) for p in free])
    before = objective(z0)
    best_z, best_d = z0, before
    runs = []
    if free:
        ends = []
        for z_start in [z0, *_starts(starts, len(free), seed)]:
            z_end, d = search(z_start, coarse)
            runs.append({"start": values_of(z_start), "end": values_of(z_end), "coarse_distance": d})
            ends.append((d, z_end))
        z_end, d = search(min(ends, key=lambda e: e[0])[1], fine)
        if d < best_d:
            best_z, best_d = z_end, d
    return FitResult(values_of(best_z), values_of(z0), before, best_d, evaluations,
                     time.process_time() - cpu0, time.perf_counter() - wall0, runs)


def fitted_program(program: Program, result: FitResult, target: str, timings: bool = True) -> Program:
    """The program with the fitted values as its parameters' defaults and the fit in its metadata
    (without the times when ``timings`` is false, so that a batch's outputs are reproducible)."""
    from dataclasses import replace

    parameters = tuple(replace(p, default=result.values[p.name]) for p in program.parameters)
    dropped = {"starts"} | (set() if timings else {"cpu_s", "wall_s"})
    fit = {"target": target, **{k: v for k, v in result.to_dict().items() if k not in dropped}}
    return Program(program.ops, parameters, {**program.metadata, "fit": fit}, program.layers)
