"""sympy behind :class:`parsel_core.cas.CASBackend`."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from parsel_core.cas import CASBackend, normalise_printed

#: The sympy module, imported by the first ``SympyBackend()``: listing the installed
#: backends imports this class, and sympy takes longer to import than a whole request.
sympy: Any = None


def _import_sympy() -> None:
    global sympy
    if sympy is None:
        import sympy as module

        sympy = module


class SympyBackend(CASBackend):
    """Exact rational arithmetic where the input is exact; ``sympy.solve`` for the rest."""

    name = "sympy"

    def __init__(self) -> None:
        _import_sympy()
        self._symbols: dict[str, sympy.Symbol] = {}
        self._functions = {
            "sin": sympy.sin, "cos": sympy.cos, "tan": sympy.tan, "asin": sympy.asin, "acos": sympy.acos,
            "atan": sympy.atan, "atan2": sympy.atan2, "sqrt": sympy.sqrt, "exp": sympy.exp, "log": sympy.log,
            "abs": sympy.Abs, "floor": sympy.floor, "ceiling": sympy.ceiling, "min": sympy.Min, "max": sympy.Max,
            "pi": sympy.pi, "e": sympy.E,
        }

    def symbol(self, name: str):
        if name not in self._symbols:
            self._symbols[name] = sympy.Symbol(name, real=True)
        return self._symbols[name]

    def number(self, value: float):
        if isinstance(value, int) or float(value).is_integer() and abs(value) < 2**53:
            return sympy.Integer(int(value))
        return sympy.Float(value)

    def functions(self) -> Mapping[str, Callable]:
        return self._functions

    def simplify(self, expr):
        return sympy.simplify(expr)

    def expand(self, expr):
        return sympy.expand(expr)

    def subs(self, expr, values):
        return sympy.sympify(expr).xreplace({self.symbol(k): sympy.sympify(v) for k, v in values.items()})

    def diff(self, expr, name):
        return sympy.diff(expr, self.symbol(name))

    def free_symbols(self, expr) -> set[str]:
        return {s.name for s in sympy.sympify(expr).free_symbols}

    def solve(self, expr, unknown):
        affine = self.solve_affine(expr, unknown)
        if affine is not None:
            return [affine]
        try:
            return list(sympy.solve(sympy.Eq(expr, 0), self.symbol(unknown)))
        except (NotImplementedError, TypeError):
            return []

    def compile(self, params: Sequence[str], exprs: Sequence[object]):
        function = sympy.lambdify([self.symbol(p) for p in params], list(exprs), modules="numpy", cse=True)

        def call(*values):
            out = function(*values)
            shape = np.broadcast_shapes(*(np.shape(v) for v in values)) if values else ()
            return np.array([np.broadcast_to(np.asarray(v, dtype=float), shape) for v in out])

        return call

    def to_string(self, expr) -> str:
        return normalise_printed(str(expr))

    def to_float(self, expr) -> float:
        return float(sympy.N(expr))
