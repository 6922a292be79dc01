"""Analytical Edit Propagation: the ParSEL solver, as a parsel plugin."""

from __future__ import annotations

from parsel_core import hookimpl
from parsel_core.interfaces import Solver, SolveRequest, SolveResult


class AEPSolver(Solver):
    """Seed edit + hints + breakable relations -> a complete closed-form program."""

    name = "aep"

    def solve(self, request: SolveRequest):
        return self.run(request).program

    def run(self, request: SolveRequest) -> SolveResult:
        from parsel_aep.propagate import propagate

        return propagate(request)


@hookimpl
def parsel_solvers():
    return [AEPSolver()]
