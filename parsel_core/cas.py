"""The computer-algebra interface that the sympy and symengine plugins implement.

The engine never imports a CAS directly: it asks the plugin manager for a backend by
name (configuration, ``--backend`` or the default) and works through this interface.
Expressions are the backend's own objects; corners are numpy object arrays of them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from parsel_core.expressions import FUNCTIONS, parse_expression


class CASBackend(ABC):
    """Build, simplify, substitute, solve and compile symbolic expressions."""

    #: The name users select the backend by (``--backend NAME``).
    name: str = ""

    @abstractmethod
    def symbol(self, name: str) -> object:
        """A symbol (a control parameter or an unknown amount ``f``)."""

    @abstractmethod
    def number(self, value: float) -> object:
        """A constant; integers stay exact."""

    @abstractmethod
    def functions(self) -> Mapping[str, Callable]:
        """Every name of :data:`parsel_core.expressions.FUNCTIONS`, plus ``pi`` and ``e``."""

    @abstractmethod
    def simplify(self, expr: object) -> object:
        """A simpler equal expression."""

    @abstractmethod
    def expand(self, expr: object) -> object:
        """The expression with products and powers multiplied out."""

    @abstractmethod
    def subs(self, expr: object, values: Mapping[str, object]) -> object:
        """Substitute symbols (by name) with numbers or expressions."""

    @abstractmethod
    def diff(self, expr: object, name: str) -> object:
        """Derivative with respect to the symbol ``name``."""

    @abstractmethod
    def free_symbols(self, expr: object) -> set[str]:
        """Names of the symbols the expression depends on."""

    @abstractmethod
    def solve(self, expr: object, unknown: str) -> list[object]:
        """Solutions of ``expr == 0`` for the symbol ``unknown``, as expressions of the others.

        Used by edit propagation with ``unknown`` the amount ``f`` of a candidate edit, so
        each solution is the amount as a closed-form function of the control parameter.
        """

    @abstractmethod
    def compile(self, params: Sequence[str], exprs: Sequence[object]) -> Callable[..., np.ndarray]:
        """A numpy function ``f(*param_values) -> array(len(exprs), *broadcast_shape)``."""

    @abstractmethod
    def to_string(self, expr: object) -> str:
        """Text that :func:`parsel_core.expressions.parse_expression` reads back."""

    @abstractmethod
    def to_float(self, expr: object) -> float:
        """The value of a constant expression."""

    # -- shared conveniences ---------------------------------------------------------

    def parse(self, text: str) -> object:
        """Build an amount's text as a backend expression (safely; see expressions.py)."""
        expression = parse_expression(text)
        names = {name: self.symbol(name) for name in expression.names}
        return expression.build(names, self.functions(), self.number)

    def solve_affine(self, expr: object, unknown: str) -> object | None:
        """The solution of ``a*f + b == 0`` when ``expr`` is affine in ``f``, else ``None``.

        Translations, scalings and shears put their amount linearly into the corners,
        so most constraints are affine in ``f`` (reference section 4): one derivative
        and one substitution solve them without a general solver.
        """
        slope = self.diff(expr, unknown)
        if unknown in self.free_symbols(slope):
            return None
        if self.free_symbols(slope) == set() and abs(self.to_float(slope)) < 1e-12:
            return None
        offset = self.subs(expr, {unknown: self.number(0)})
        return self.simplify(-offset / slope)

    def linear_combination(self, weights: Sequence[float], terms: Sequence) -> object:
        """``sum(w * t)`` over the weights above 1e-15 in magnitude, the products added one
        at a time in order (the amounts edit propagation derives are such sums of residual
        terms). A backend may override it with a faster way to build the same expression."""
        total = self.number(0)
        for w, term in zip(weights, terms):
            if abs(w) > 1e-15:
                total = total + self.number(float(w)) * term
        return total

    def corners(self, corners: np.ndarray) -> np.ndarray:
        """Numeric corners as an object array of backend numbers."""
        out = np.empty(np.shape(corners), dtype=object)
        for index, value in np.ndenumerate(np.asarray(corners, dtype=float)):
            out[index] = self.number(float(value))
        return out


_PRINTED_NAMES = {"Abs": "abs", "Min": "min", "Max": "max", "E": "e"}


def normalise_printed(text: str) -> str:
    """Rename the CAS printers' function names to the amount language's (``Abs`` -> ``abs``)."""
    import re

    return re.sub(r"\b(Abs|Min|Max|E)\b", lambda m: _PRINTED_NAMES[m.group(1)], text)


def check_backend(backend: CASBackend) -> None:
    """Raise ``TypeError`` if a plugin's backend misses part of the interface."""
    missing = [name for name in (*FUNCTIONS, "pi", "e") if name not in backend.functions()]
    if missing:
        raise TypeError(f"CAS backend {backend.name!r} lacks functions {missing}")
