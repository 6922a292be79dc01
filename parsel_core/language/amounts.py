"""Checks on the amounts a model writes, over the slider's range, before any solver sees them.

A model's amount is parsed (never evaluated as code), but a well-formed expression can
still be unusable: ``x / 0``, ``log(0) + x``, ``sqrt(-1) * x``, ``9**9**9**9``,
``1e300 * x`` or ``x**-1`` (at 0) give no finite edit somewhere in the range, and a
rotation written in degrees (``-15 * x``) turns a part through more than a full turn.
:func:`check_ops` samples every amount on the parameter's range with plain floats and
says what is wrong with the first bad one; the reply is then rejected with that reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from parsel_core.expressions import parse_expression
from parsel_core.language.api import ReplyError
from parsel_core.ops import EditOp

#: Samples of the parameter range an amount is checked at (ends included).
SAMPLES = 33
#: Amounts larger than this (in size: a scale factor, a distance in shape units, a count)
#: make corners whose products overflow; no edit a user asks for needs them.
LIMIT = 1e6
#: Operators whose amount is an angle in radians.
ANGLE_OPS = frozenset({"rotate"})
FULL_TURN = 2 * math.pi


def _safe(function):
    def call(*args: float) -> float:
        try:
            value = function(*args)
        except (ValueError, ZeroDivisionError, OverflowError) as exc:
            raise ArithmeticError(f"{function.__name__}{tuple(args)}: {exc}") from None
        if isinstance(value, complex):
            raise ArithmeticError(f"{function.__name__}{tuple(args)} is not real")
        return float(value)
    return call


_FUNCTIONS = {name: _safe(getattr(math, name)) for name in (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sqrt", "exp", "log", "floor")}
_FUNCTIONS.update({"abs": _safe(abs), "ceiling": _safe(math.ceil), "min": _safe(min), "max": _safe(max)})


def amount_values(text: str, parameter: str, lo: float, hi: float, samples: int = SAMPLES) -> list[float]:
    """The amount at evenly spaced parameter values; raises ArithmeticError where it has no finite value."""
    expression = parse_expression(text)
    values = []
    for k in range(samples):
        t = lo + (hi - lo) * k / (samples - 1)
        try:
            value = expression.build({parameter: t}, _FUNCTIONS, float)
        except (ZeroDivisionError, OverflowError, ValueError) as exc:
            raise ArithmeticError(f"at {parameter} = {t:g}: {exc or type(exc).__name__}") from None
        except ArithmeticError as exc:
            raise ArithmeticError(f"at {parameter} = {t:g}: {exc}") from None
        if isinstance(value, complex) or not math.isfinite(value):
            raise ArithmeticError(f"at {parameter} = {t:g} it is {value}")
        if abs(value) > LIMIT:
            raise ArithmeticError(f"at {parameter} = {t:g} it is {value:.3g}, beyond +-{LIMIT:g}")
        values.append(float(value))
    return values


def check_ops(ops: Sequence[EditOp], parameter: str = "x", lo: float = 0.0, hi: float = 1.0) -> None:
    """Raise :class:`ReplyError` for the first op whose amount is unusable on [lo, hi]."""
    for op in ops:
        try:
            values = amount_values(op.amount, parameter, lo, hi)
        except ArithmeticError as exc:
            raise ReplyError(f"{op.name}({op.operand}): amount {op.amount!r} is not a finite number {exc}") from None
        if op.name in ANGLE_OPS:
            largest = max(abs(v) for v in values)
            if largest > FULL_TURN:
                raise ReplyError(f"{op.name}({op.operand}): amount {op.amount!r} reaches {largest:.3g} radians "
                                 f"over {parameter} in [{lo:g}, {hi:g}], more than a full turn; if it is in "
                                 f"degrees write radians({largest:g}) * {parameter} (or pi / 180 * ...)")
