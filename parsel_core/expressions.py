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


def _check(node: ast.AST, text: str, names: set[str]) -> None:
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise ProgramFormatError(f"amount {text!r}: only numbers are allowed as literals, not {node.value!r}")
    elif isinstance(node, ast.Name):
        if node.id.startswith("_"):
            raise ProgramFormatError(f"amount {text!r}: name {node.id!r} is not allowed")
        if node.id not in CONSTANTS:
            names.add(node.id)
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BINARY:
            raise ProgramFormatError(f"amount {text!r}: operator {type(node.op).__name__} is not allowed")
        _check(node.left, text, names)
        _check(node.right, text, names)
    elif isinstance(node, ast.UnaryOp):
        if type(node.op) not in _UNARY:
            raise ProgramFormatError(f"amount {text!r}: operator {type(node.op).__name__} is not allowed")
        _check(node.operand, text, names)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            called = ast.unparse(node.func)
            raise ProgramFormatError(f"amount {text!r}: call to {called!r} is not allowed "
                                     f"(allowed: {', '.join(sorted(FUNCTIONS))})")
        if node.keywords or len(node.args) != FUNCTIONS[node.func.id]:
            raise ProgramFormatError(f"amount {text!r}: {node.func.id}() takes {FUNCTIONS[node.func.id]} "
                                     "positional argument(s)")
        for arg in node.args:
            _check(arg, text, names)
    else:
        raise ProgramFormatError(f"amount {text!r}: {type(node).__name__} is not allowed in an amount")


@lru_cache(maxsize=4096)
def parse_expression(text: str) -> Expression:
    """Parse and validate an amount; raises :class:`ProgramFormatError` naming the text."""
    if not isinstance(text, str) or not text.strip():
        raise ProgramFormatError(f"amount {text!r} is empty")
    if len(text) > 2000:
        raise ProgramFormatError(f"amount of {len(text)} characters is too long (limit 2000)")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ProgramFormatError(f"amount {text!r} does not parse: {exc.msg}") from None
    names: set[str] = set()
    _check(tree, text, names)
    return Expression(text.strip(), tree, frozenset(names))


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
