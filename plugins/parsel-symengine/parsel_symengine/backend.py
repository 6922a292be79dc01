"""symengine behind :class:`parsel_core.cas.CASBackend`."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from parsel_core.cas import CASBackend, normalise_printed

#: symengine and its ``solve``, imported by the first ``SymengineBackend()``, so that the
#: class can be listed (``parsel plugins``, picking another backend) without importing it.
symengine: Any = None
_solve: Any = None


def _import_symengine() -> None:
    global symengine, _solve
    if symengine is None:
        import symengine as module
        from symengine.lib.symengine_wrapper import solve

        symengine, _solve = module, solve


class SymengineBackend(CASBackend):
    """Fast expression building and compilation; affine constraints solved directly,
    other ones with ``symengine.solve`` (polynomials) where it can."""

    name = "symengine"

    def __init__(self) -> None:
        _import_symengine()
        self._symbols: dict[str, symengine.Symbol] = {}
        self._functions = {
            "sin": symengine.sin, "cos": symengine.cos, "tan": symengine.tan, "asin": symengine.asin,
            "acos": symengine.acos, "atan": symengine.atan, "atan2": symengine.atan2, "sqrt": symengine.sqrt,
            "exp": symengine.exp, "log": symengine.log, "abs": symengine.Abs, "floor": symengine.floor,
            "ceiling": symengine.ceiling, "min": symengine.Min, "max": symengine.Max,
            "pi": symengine.pi, "e": symengine.E,
        }

    def symbol(self, name: str):
        if name not in self._symbols:
            self._symbols[name] = symengine.Symbol(name)
        return self._symbols[name]

    def number(self, value: float):
        if isinstance(value, int) or float(value).is_integer() and abs(value) < 2**53:
            return symengine.Integer(int(value))
        return symengine.RealDouble(float(value))

    def linear_combination(self, weights: Sequence[float], terms: Sequence) -> object:
        """The shared loop's expression, object for object, with the products of float terms
        taken in Python: symengine multiplies two doubles as IEEE does and turns a zero
        product into an exact 0, which adding leaves out, so adding ``w * t`` as a float (if
        not zero) is the same step without building two numbers first (most residual terms
        of a joint edit are floats: constraints among the edited parts themselves)."""
        total = self.number(0)
        for w, term in zip(weights, terms):
            if abs(w) > 1e-15:
                if type(term) is float:
                    product = float(w) * term
                    if product != 0.0:
                        total = total + product
                else:
                    total = total + self.number(float(w)) * term
        return total

    def functions(self) -> Mapping[str, Callable]:
        return self._functions

    def simplify(self, expr):
        return symengine.expand(expr)

    def expand(self, expr):
        return symengine.expand(expr)

    def subs(self, expr, values):
        return symengine.sympify(expr).xreplace(
            {self.symbol(k): symengine.sympify(v) for k, v in values.items()})

    def diff(self, expr, name):
        return symengine.diff(expr, self.symbol(name))

    def free_symbols(self, expr) -> set[str]:
        return {str(s) for s in symengine.sympify(expr).free_symbols}

    def solve(self, expr, unknown):
        affine = self.solve_affine(expr, unknown)
        if affine is not None:
            return [affine]
        try:
            solutions = _solve(expr, self.symbol(unknown))
        except (RuntimeError, NotImplementedError, TypeError):
            return []  # e.g. trigonometric equations: symengine has no solver for them
        # A FiniteSet of roots; other set kinds (intervals, condition sets) are not closed forms.
        return list(solutions.args) if type(solutions).__name__ == "FiniteSet" else []

    def compile(self, params: Sequence[str], exprs: Sequence[object]):
        args = [self.symbol(p) for p in params]
        function = symengine.Lambdify(args, list(exprs), cse=True) if args else None
        constants = None if args else np.array([float(e) for e in exprs])

        def call(*values):
            if function is None:
                return constants
            shape = np.broadcast_shapes(*(np.shape(v) for v in values))
            stacked = np.stack([np.broadcast_to(np.asarray(v, dtype=float), shape) for v in values], axis=-1)
            out = np.asarray(function(stacked.reshape(-1, len(args))))  # (samples, n_exprs)
            return np.moveaxis(out.reshape(shape + (len(exprs),)), -1, 0)

        return call

    def to_string(self, expr) -> str:
        return normalise_printed(str(expr))

    def to_float(self, expr) -> float:
        return float(symengine.sympify(expr).evalf())
