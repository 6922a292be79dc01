"""Fitting a program's parameters to target points by the Chamfer distance (scipy).

The objective is the Chamfer distance between the edited shape's fixed surface samples
(``surface.SurfaceSampler``) and the target's points. Each parameter is mapped to
[0, 1] over its range, and scipy's bounded Powell search (derivative-free: the distance
is only piecewise smooth, nearest neighbours change as the shape moves) runs from
several starts: the program's defaults and a deterministic Latin-hypercube spread over
the box (both sides of the defaults wherever the range has room), on a quarter of the
samples; the best :data:`POLISHED` distinct end points are then polished on all of them,
and the best is kept only if it beats the defaults, so the fit is never worse than the
defaults. When nothing beats the defaults, :func:`explain_no_gain` says why: which
parameters sit at an end of their range with the helpful direction outside it, and
which would make the distance grow either way.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.program import Program
from parsel_core.verbosity import logger
from parsel_fit.chamfer import ChamferTarget
from parsel_fit.surface import DEFAULT_SAMPLES, SurfaceSampler

DEFAULT_STARTS = 4
#: The coarse search uses one in this many samples and target points.
COARSE = 4
#: How many of the best distinct coarse end points are polished on all samples.
POLISHED = 2
#: The step (a fraction of a parameter's range) of the slopes :func:`explain_no_gain` measures.
PROBE = 0.02


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
    #: Why the fit could not lower the distance (None when it did): see :func:`explain_no_gain`.
    no_gain: str | None = None

    @property
    def lowered(self) -> bool:
        return self.distance_after < self.distance_before

    def to_dict(self) -> dict[str, Any]:
        out = {"values": self.values, "start_values": self.start_values,
               "distance_before": self.distance_before, "distance_after": self.distance_after,
               "evaluations": self.evaluations, "cpu_s": self.cpu_s, "wall_s": self.wall_s, "starts": self.starts}
        if self.no_gain is not None:
            out["no_gain"] = self.no_gain
        return out


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
                xtol: float = 1e-3, backend: str | None = None, progress: bool = False) -> FitResult:
    """The parameter values (within their ranges) that bring the edited shape closest to ``target``.

    ``fixed`` holds parameters that are not fitted; every other parameter is. The starts
    are searched on a quarter of the samples and of the target (coarse), then the best end
    points are polished on all of them (fine); distances reported are the fine ones.
    ``backend`` evaluates the program compiled by that CAS backend instead of numpy;
    ``progress`` allows a display on stderr counting the searches (``parsel fit``)."""
    from scipy.optimize import minimize

    from parsel_core.program import evaluator
    from parsel_core.progress import progress as progress_display

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
    evaluate_at = evaluator(program, shape, backend)

    def values_of(z: np.ndarray) -> dict[str, float]:
        out = dict(base)
        for p, zi in zip(free, np.clip(z, 0.0, 1.0)):
            out[p.name] = float(p.lo + zi * (p.hi - p.lo))
        return out

    def objective(z: np.ndarray, level=fine) -> float:
        nonlocal evaluations
        evaluations += 1
        sampler, chamfer = level
        points = sampler.points(shape, evaluate_at(values_of(z)))
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
        z_starts = [z0, *_starts(starts, len(free), seed)]
        bar = progress_display(len(z_starts) + min(POLISHED, len(z_starts)), "fit searches", unit="search",
                               enabled=progress)
        for z_start in z_starts:
            z_end, d = search(z_start, coarse)
            bar.update(1)
            runs.append({"start": values_of(z_start), "end": values_of(z_end), "coarse_distance": d})
            logger.debug(f"fit start {_short(values_of(z_start))} -> {_short(values_of(z_end))}: "
                         f"coarse distance {d:.5g}")
            ends.append((d, z_end))
        polished: list[np.ndarray] = []
        for _, z_end in sorted(ends, key=lambda e: e[0]):
            if len(polished) == POLISHED:
                break
            if any(np.max(np.abs(z_end - other)) <= 10 * xtol for other in polished):
                continue  # two starts that ended in the same basin are polished once
            polished.append(z_end)
            z_fine, d = search(z_end, fine)
            bar.set_postfix_str(f"distance {min(d, best_d):.4g}")
            bar.update(1)
            logger.debug(f"fit polish {_short(values_of(z_end))} -> {_short(values_of(z_fine))}: distance {d:.5g}")
            if d < best_d:
                best_z, best_d = z_fine, d
        bar.update(min(POLISHED, len(z_starts)) - len(polished))  # the polishes one basin saved
        bar.close()
    no_gain = None
    if not best_d < before:
        no_gain = explain_no_gain(program, free, lambda v: objective(_z_of(free, v)), values_of(z0), before) \
            if free else "no parameter is free to fit (all are fixed, or have an empty range)"
    return FitResult(values_of(best_z), values_of(z0), before, best_d, evaluations,
                     time.process_time() - cpu0, time.perf_counter() - wall0, runs, no_gain)


def _short(values: dict[str, float]) -> str:
    return "(" + ", ".join(f"{k}={v:.4g}" for k, v in values.items()) + ")"


def _z_of(free: list[Any], values: dict[str, float]) -> np.ndarray:
    return np.array([(values[p.name] - p.lo) / (p.hi - p.lo) for p in free])


def explain_no_gain(program: Program, free: list[Any], distance: Any, at: dict[str, float],
                    base: float) -> str:
    """Why no parameter setting beat ``at``: for each free parameter, the distance one small
    step (:data:`PROBE` of its range) to each side that its range allows. A parameter at an
    end of its range whose only allowed step makes the distance grow cannot move toward the
    target; one that grows both ways sits at a minimum along its own direction."""
    reasons = []
    for p in free:
        step = PROBE * (p.hi - p.lo)
        slopes = {}
        for sign, side in ((-1, "down"), (1, "up")):
            value = at[p.name] + sign * step
            if p.lo - 1e-12 <= value <= p.hi + 1e-12:
                slopes[side] = (distance({**at, p.name: value}) - base) / step
        at_end = "lower end" if at[p.name] <= p.lo + 1e-12 else "upper end" if at[p.name] >= p.hi - 1e-12 else ""
        grows = ", ".join(f"{side} {slope:+.3g}" for side, slope in slopes.items())
        if at_end and len(slopes) == 1 and min(slopes.values()) >= 0:
            outside = "below" if at_end == "lower end" else "above"
            reasons.append(f"{p.name} is at the {at_end} of [{p.lo:g}, {p.hi:g}] and moving into the range makes "
                           f"the distance grow (slope {grows}); only values {outside} the range could come closer")
        elif slopes and min(slopes.values()) >= 0:
            reasons.append(f"{p.name} = {at[p.name]:g} is a minimum along {p.name} (slopes {grows})")
        else:
            reasons.append(f"{p.name}: a step lowers the distance alone (slopes {grows}) but no search found a "
                           "setting of all parameters together that does")
    return "; ".join(reasons)


def fitted_program(program: Program, result: FitResult, target: str, timings: bool = True) -> Program:
    """The program with the fitted values as its parameters' defaults and the fit in its metadata
    (without the times when ``timings`` is false, so that a batch's outputs are reproducible)."""
    from dataclasses import replace

    parameters = tuple(replace(p, default=result.values[p.name]) for p in program.parameters)
    dropped = {"starts"} | (set() if timings else {"cpu_s", "wall_s"})
    fit = {"target": target, **{k: v for k, v in result.to_dict().items() if k not in dropped}}
    return replace(program, parameters=parameters, metadata={**program.metadata, "fit": fit})
