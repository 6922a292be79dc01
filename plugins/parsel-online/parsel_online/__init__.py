"""Online edit propagation: the classical baseline ParSEL contrasts with (paper section 2).

Instead of a program, every parameter value is solved on its own: the seed-edited parts
are placed by the seed, and every other part's placement (a translation and a scaling
along its own axes) is found by nonlinear least squares over all relation residuals,
with a small penalty on change. There is no closed form, so each slider step costs a
solve; ``benchmarks/bench_aep.py`` measures that against evaluating an AEP program.
"""

from __future__ import annotations

from parsel_core import hookimpl
from parsel_core.interfaces import Solver, SolveRequest, SolveResult


class OnlineSolver(Solver):
    """``solve`` returns the seed (the only closed-form part); ``editor`` re-solves per value."""

    name = "online"

    def solve(self, request: SolveRequest):
        return request.seed

    def run(self, request: SolveRequest) -> SolveResult:
        from parsel_online.editor import OnlineEditor

        editor = OnlineEditor(request)
        report = editor.sweep(samples=11)
        return SolveResult(request.seed, sorted(report["broken"]), {"online": report})

    def editor(self, request: SolveRequest):
        from parsel_online.editor import OnlineEditor

        return OnlineEditor(request)


@hookimpl
def parsel_solvers():
    return [OnlineSolver()]
