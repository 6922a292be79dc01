"""Per-value numeric re-solving of part placements (scipy least squares)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import least_squares

from parsel_core.graph import orthonormal_axes
from parsel_core.interfaces import SolveRequest
from parsel_core.program import evaluate
from parsel_core.report import tolerance_for

#: Weight of the penalty that keeps unconstrained parts where they are.
REGULARISATION = 1e-3


class OnlineEditor:
    """Solves the free parts' placements at one parameter value at a time, warm-started."""

    def __init__(self, request: SolveRequest) -> None:
        self.request = request
        self.shape = request.shape
        self.relations = [r for r in self.shape.relations.values() if r.id not in set(request.breaks)]
        seeded = {op.operand for op in request.seed.ops if op.acts_on == "part"}
        for op in request.seed.ops:
            if op.operand in self.shape.virtual_parents:
                seeded.update(self.shape.relations[op.operand].members)
        self.free = [pid for pid in self.shape.parts if pid not in seeded]
        rest = self.shape.rest_corners()
        self.rest = rest
        self.frames = {pid: orthonormal_axes(self.shape.parts[pid].hexahedron) for pid in self.free}
        self.centres = {pid: rest[pid].mean(axis=0) for pid in self.free}
        self.local = {pid: (rest[pid] - self.centres[pid]) @ self.frames[pid].T for pid in self.free}
        self.state = np.zeros(6 * len(self.free))
        self.tolerance = tolerance_for(self.shape)

    def _place(self, variables: np.ndarray) -> dict[str, np.ndarray]:
        out = {}
        for i, pid in enumerate(self.free):
            t, s = variables[6 * i: 6 * i + 3], variables[6 * i + 3: 6 * i + 6]
            out[pid] = self.centres[pid] + t + (self.local[pid] * np.exp(s)) @ self.frames[pid]
        return out

    def corners(self, values: Mapping[str, float]) -> dict[str, np.ndarray]:
        """Every part's corners at one parameter value (one nonlinear solve)."""
        seeded = evaluate(self.request.seed, self.shape, values).parts

        def residuals(variables):
            corners = {**seeded, **self._place(variables)}
            terms = [np.asarray(r.residual(corners), dtype=float).ravel() for r in self.relations]
            return np.concatenate(terms + [REGULARISATION * variables])

        if self.free:
            solution = least_squares(residuals, self.state, method="lm" if len(self.state) <= 600 else "trf",
                                     xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
            self.state = solution.x
            return {**seeded, **self._place(solution.x)}
        return dict(seeded)

    def sweep(self, samples: int = 11) -> dict:
        """Solve across the first parameter's range; report which relations failed where."""
        parameter = self.request.seed.parameters[0]
        errors = {r.id: 0.0 for r in self.relations}
        for value in np.linspace(parameter.lo, parameter.hi, samples):
            corners = self.corners({parameter.name: float(value)})
            for r in self.relations:
                errors[r.id] = max(errors[r.id], float(np.max(r.error(corners))))
        broken = [r.id for r in self.relations if not errors[r.id] < r.allowance(self.tolerance)]
        return {"samples": samples, "broken": sorted(broken), "free_parts": len(self.free), "errors": errors}
