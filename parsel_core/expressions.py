"""Safe parsing of amount expressions such as ``0.5*x``, ``sin(x)/2`` or ``-(x + y)**2``.

Amounts come from program files and from language models, so they are parsed with
:mod:`ast` against a whitelist and then *built* by walking the tree with the caller's
own constructors: numpy values for the numeric path, CAS symbols for the symbolic one.
Nothing is ever passed to ``eval``.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache

from parsel_core.errors import ProgramFormatError

#: Functions an amount may call, with their arity.
FUNCTIONS: dict[str, int] = {
    "sin": 1, "cos": 1, "tan": 1, "asin": 1, "acos": 1, "atan": 1, "atan2": 2,
    "sqrt": 1, "exp": 1, "log": 1, "abs": 1, "floor": 1, "ceiling": 1,
    "min": 2, "max": 2,
}
#: Named constants an amount may use.
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}

_BINARY = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.Pow: operator.pow,
}
_UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}


@dataclass(frozen=True)
class Expression:
    """A validated amount expression: its text, its tree and the parameter names it uses."""

    text: str
    tree: ast.expr
    names: frozenset[str]

    def build(self, names: Mapping[str, object], functions: Mapping[str, Callable],
              number: Callable[[float], object] = float) -> object:
        """Evaluate the tree with the given leaves: values, arrays or CAS symbols."""
        return _build(self.tree, names, functions, number, self.text)


def _check(tree: ast.AST, text: str, names: set[str], max_depth: int) -> None:
    """Walk the tree with an explicit stack (no recursion limit to hit), refusing what is not whitelisted."""
    stack: list[tuple[ast.AST, int]] = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > max_depth:
            raise ProgramFormatError(f"amount {_short(text)}: nests deeper than the limit max_expression_depth = "
                                     f"{max_depth} (raise it with PARSEL_MAX_EXPRESSION_DEPTH)")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise ProgramFormatError(f"amount {_short(text)}: only numbers are allowed as literals, "
                                         f"not {_short(repr(node.value))}")
            if not _finite_number(node.value):
                raise ProgramFormatError(f"amount {_short(text)}: the number {_short(repr(node.value))} is not a "
                                         "finite float")
        elif isinstance(node, ast.Name):
            if node.id.startswith("_"):
                raise ProgramFormatError(f"amount {_short(text)}: name {node.id!r} is not allowed")
            if node.id not in CONSTANTS:
                names.add(node.id)
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                raise ProgramFormatError(f"amount {_short(text)}: operator {type(node.op).__name__} is not allowed")
            stack += [(node.left, depth + 1), (node.right, depth + 1)]
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                raise ProgramFormatError(f"amount {_short(text)}: operator {type(node.op).__name__} is not allowed")
            stack.append((node.operand, depth + 1))
        elif isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                called = node.func.id if isinstance(node.func, ast.Name) else type(node.func).__name__
                raise ProgramFormatError(f"amount {_short(text)}: call to {_short(called)} is not allowed "
                                         f"(allowed: {', '.join(sorted(FUNCTIONS))})")
            if node.keywords or len(node.args) != FUNCTIONS[node.func.id]:
                raise ProgramFormatError(f"amount {_short(text)}: {node.func.id}() takes "
                                         f"{FUNCTIONS[node.func.id]} positional argument(s)")
            stack += [(arg, depth + 1) for arg in node.args]
        else:
            raise ProgramFormatError(f"amount {_short(text)}: {type(node).__name__} is not allowed in an amount")


def _finite_number(value: int | float) -> bool:
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an integer literal beyond any float
        return False


def _short(text: str, width: int = 60) -> str:
    """``text`` quoted for an error line: one line, at most ``width`` characters."""
    quoted = repr(text)
    return quoted if len(quoted) <= width else quoted[: width - 4] + "...'"


@lru_cache(maxsize=4096)
def parse_expression(text: str) -> Expression:
    """Parse and validate an amount; raises :class:`ProgramFormatError` naming the text.

    Amounts are one line of arithmetic: no comments, no control characters (they travel
    into text programs and the slider page), bounded in length and nesting depth.
    """
    from parsel_core.config import limit

    if not isinstance(text, str) or not text.strip():
        raise ProgramFormatError(f"amount {_short(repr(text))} is empty or not text")
    max_chars = int(limit("max_expression_chars"))
    if len(text) > max_chars:
        raise ProgramFormatError(f"amount of {len(text)} characters is over the limit max_expression_chars = "
                                 f"{max_chars} (raise it with PARSEL_MAX_EXPRESSION_CHARS)")
    bad = next((c for c in text if c == "#" or not c.isprintable()), None)
    if bad is not None:
        raise ProgramFormatError(f"amount {_short(text)}: character {bad!r} is not allowed (one line of "
                                 "arithmetic, no comments)")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ProgramFormatError(f"amount {_short(text)} does not parse: {exc.msg}") from None
    except (RecursionError, MemoryError) as exc:  # nesting beyond the parser's stack
        raise ProgramFormatError(f"amount {_short(text)} does not parse: nested too deeply "
                                 f"({type(exc).__name__})") from None
    except ValueError as exc:  # digits beyond int()
        raise ProgramFormatError(f"amount {_short(text)} does not parse: {' '.join(str(exc).split())[:120]}") \
            from None
    names: set[str] = set()
    _check(tree, text, names, int(limit("max_expression_depth")))
    return Expression(text.strip(), tree, frozenset(names))


def check_finite(expression: Expression, ranges: Mapping[str, tuple[float, float]], what: str = "amount",
                 samples: int = 33) -> None:
    """Refuse an amount that is not a finite number of sane magnitude over its parameters' ranges.

    The amount is evaluated with numpy at ``samples`` points of every range (ends
    included; all parameters move together), so overflow (``2**99999``), division by zero
    and towers of powers are caught here, before a CAS tries to expand them.
    """
    import numpy as np

    from parsel_core.config import limit

    bound = limit("max_magnitude")
    grid = np.linspace(0.0, 1.0, samples)
    values = {}
    for name in expression.names:
        if name not in ranges:
            raise ProgramFormatError(f"{what} {_short(expression.text)}: unknown parameter {name!r}")
        lo, hi = ranges[name]
        values[name] = lo + (hi - lo) * grid
    with np.errstate(all="ignore"):
        try:
            result = expression.build(values, numpy_functions(), np.float64)
            result = np.broadcast_to(np.asarray(result, dtype=float), grid.shape)
        except (OverflowError, ZeroDivisionError, ValueError, TypeError, FloatingPointError):
            result = np.array([np.nan])
    if not np.all(np.isfinite(result)):
        span = ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in sorted(ranges.items()))
        raise ProgramFormatError(f"{what} {_short(expression.text)} is not a finite number over the parameter "
                                 f"range ({span or 'no parameters'})")
    peak = float(np.max(np.abs(result)))
    if peak > bound:
        raise ProgramFormatError(f"{what} {_short(expression.text)} reaches {peak:g}, over the limit "
                                 f"max_magnitude = {bound:g} (raise it with PARSEL_MAX_MAGNITUDE)")


def _build(node, names, functions, number, text):
    if isinstance(node, ast.Constant):
        return number(node.value)
    if isinstance(node, ast.Name):
        if node.id in names:
            return names[node.id]
        if node.id in CONSTANTS:
            # A backend may supply the exact constant (sympy.pi) in place of the float.
            return functions[node.id] if node.id in functions else number(CONSTANTS[node.id])
        raise ProgramFormatError(f"amount {text!r}: unknown parameter {node.id!r}")
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_build(node.left, names, functions, number, text),
                                      _build(node.right, names, functions, number, text))
    if isinstance(node, ast.UnaryOp):
        return _UNARY[type(node.op)](_build(node.operand, names, functions, number, text))
    if isinstance(node, ast.Call):
        args = [_build(arg, names, functions, number, text) for arg in node.args]
        return functions[node.func.id](*args)
    raise ProgramFormatError(f"amount {text!r}: cannot evaluate {type(node).__name__}")


def numpy_functions() -> dict[str, Callable]:
    """The whitelisted functions as numpy ufuncs, for the numeric path."""
    import numpy as np

    return {
        "sin": np.sin, "cos": np.cos, "tan": np.tan, "asin": np.arcsin, "acos": np.arccos,
        "atan": np.arctan, "atan2": np.arctan2, "sqrt": np.sqrt, "exp": np.exp, "log": np.log,
        "abs": np.abs, "floor": np.floor, "ceiling": np.ceil, "min": np.minimum, "max": np.maximum,
    }
