"""Closed forms of the surviving candidates' amounts, derived and checked with the CAS.

Screening found, at every sample, the amount that zeroes the constraints in the least
squares sense. Here the same equations are written symbolically — the other parts'
corners are expressions of the control parameter — and solved for the unknown amount
``f`` through the backend: the normal equation ``sum_k a_k (a_k f + b_k(x)) = 0`` for
affine ops, and ``f = atan2(s(x), c(x))`` with ``(c, s)`` the least-squares solution of
``A c + B s + gamma(x) = 0`` for rotations.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import numpy as np

from parsel_core.cas import CASBackend
from parsel_core.expressions import numpy_functions, parse_expression
from parsel_core.relations import Relation

_NUMBER = re.compile(r"(?<![A-Za-z_0-9.])(\d+\.\d*(?:e[-+]?\d+)?|\d+e[-+]?\d+|\.\d+(?:e[-+]?\d+)?)")


def clean_numbers(text: str, digits: int = 12) -> str:
    """Round printed floats to ``digits`` significant digits; drop round-off (< 1e-10) to 0."""

    def fix(match: re.Match) -> str:
        value = float(match.group(0))
        if abs(value) < 1e-10:
            return "0"
        rounded = float(f"{value:.{digits}g}")
        return repr(int(rounded)) if rounded.is_integer() and abs(rounded) < 1e15 else repr(rounded)

    return _NUMBER.sub(fix, text)


def symbolic_residual(constraints: Sequence[Relation], corners: Mapping[str, np.ndarray]) -> list:
    """All residual components of the constraints, as expressions (or floats)."""
    out: list = []
    for relation in constraints:
        out.extend(np.asarray(relation.residual(corners), dtype=object).ravel().tolist())
    return out


def linear_combination(backend: CASBackend, weights: np.ndarray, terms: Sequence) -> object:
    """``sum(w * t)`` of residual terms by the backend (:meth:`CASBackend.linear_combination`)."""
    return backend.linear_combination(weights, terms)


def affine_amount(backend: CASBackend, slope: np.ndarray, residual: Sequence) -> object:
    """Solve the normal equation of ``a f + b(x) = 0`` for ``f`` with the backend."""
    f = backend.symbol("f")
    norm = float(slope @ slope)
    if norm < 1e-18:
        raise ValueError("the candidate does not move the constrained points")
    weights = slope / norm
    equation = f + linear_combination(backend, weights, residual)
    solutions = backend.solve(equation, "f")
    if len(solutions) != 1:
        raise ValueError(f"expected one solution for the amount, got {len(solutions)}")
    return backend.expand(solutions[0])


def rotation_amount(backend: CASBackend, matrix: np.ndarray, offset: np.ndarray, residual: Sequence) -> object:
    """``atan2(s, c)`` with ``(c, s) = -pinv([A B]) (b(x) - A)``."""
    gamma = [term - backend.number(float(o)) for term, o in zip(residual, offset)]
    pseudo = np.linalg.pinv(matrix)
    c = -linear_combination(backend, pseudo[0], gamma)
    s = -linear_combination(backend, pseudo[1], gamma)
    return backend.simplify(backend.functions()["atan2"](backend.expand(s), backend.expand(c)))


def amount_text(backend: CASBackend, expr: object) -> str:
    """Printed, cleaned of round-off (re-parsing drops the zeroed terms) and checked to parse."""
    text = clean_numbers(backend.to_string(expr))
    parsed = backend.parse(text)
    text = clean_numbers(backend.to_string(parsed if "atan2" in text else backend.expand(parsed)))
    parse_expression(text)
    return text


def simpler_equivalent(text: str, known: list[str], name: str, values: np.ndarray) -> str:
    """``k * g`` for an amount ``g`` already in the program when it equals ``text`` on dense samples.

    Rotations come out of the CAS as ``atan2(s(x), c(x))``; when a neighbour turns by
    ``x`` about the same axis that is just ``x``, which symengine cannot simplify. The
    replacement is only taken when it agrees to 1e-10 at 200 points of the range.
    """
    dense = np.linspace(values.min(), values.max(), 200)
    target = evaluate_amount(text, name, dense)
    for g in known:
        base = evaluate_amount(g, name, dense)
        norm = float(base @ base)
        if norm < 1e-18:
            continue
        k = float(target @ base) / norm
        k_text = clean_numbers(repr(k))
        candidate = g if k_text == "1" else f"{k_text}*({g})"
        if np.allclose(evaluate_amount(candidate, name, dense), target, atol=1e-10, rtol=0):
            return candidate
    return text


def evaluate_amount(text: str, name: str, values: np.ndarray) -> np.ndarray:
    """The amount at the given parameter values, numerically."""
    expression = parse_expression(text)
    result = expression.build({name: values}, numpy_functions())
    return np.broadcast_to(np.asarray(result, dtype=float), values.shape)
