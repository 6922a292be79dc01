"""An operator's point map as JavaScript, generated from its Python ``transform``.

The page re-implements the built-in ops by hand (``static/parsel_eval.js``). Any other
part op, a plugin's included, gets its JavaScript from the same definition the engine
uses: ``transform`` is run once on one symbolic point ``(qx, qy, qz)`` and a symbolic
amount ``a`` with sympy (its fields are numbers by then), which gives the map as three
closed-form expressions; common sub-expressions are shared, and the expression trees
are written out by a walker that knows numbers, the point, the amount, ``+ - * /``,
integer and square-root powers, ``sin`` and ``cos`` (:mod:`parsel_core.opmath`) and
nothing else. An operator that uses anything more (a branch on a value, a numpy
function the CAS cannot follow, a dependence between points) has no JavaScript form
and the page says so, naming the op.

Generated text is also read back by :func:`evaluate_point_map` (Python's ``ast`` over
the same short grammar, no ``eval``), so the conformance kit can check the JavaScript
against ``transform`` without a browser.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from parsel_core import opmath
from parsel_core.errors import ParselError
from parsel_core.ops import EditOp
from parsel_view.jsexpr import js_number

_POINT = ("qx", "qy", "qz")
_JS_NAMES = {"qx": "q[0]", "qy": "q[1]", "qz": "q[2]", "a": "a"}


class NoJavaScriptForm(ParselError):
    """An operator's point map cannot be written in the page's expression form."""


def trace(op: EditOp, points: int = 1) -> tuple[list[list[Any]], list[Any]]:
    """``op.transform`` on ``points`` symbolic points and a symbolic amount: sympy expressions
    per point and coordinate, and the point symbols."""
    import sympy

    rows = [[sympy.Symbol(f"{name}{i}" if i else name, real=True) for name in _POINT] for i in range(points)]
    amount = sympy.Symbol("a", real=True)
    try:
        moved = op.transform(np.array(rows, dtype=object), amount, opmath)
        moved = np.broadcast_to(np.asarray(moved, dtype=object), (points, 3))
    except Exception as exc:  # any failure means the map cannot be followed symbolically
        raise NoJavaScriptForm(f"{op.name}: transform cannot run on symbols ({type(exc).__name__}: {exc}), "
                               f"so it has no JavaScript form") from None
    return [[sympy.sympify(v) for v in row] for row in moved], rows


def point_map_expressions(op: EditOp) -> list[Any]:
    """The three sympy expressions of ``op``'s point map in ``qx, qy, qz`` and ``a``.

    Raises :class:`NoJavaScriptForm` when ``transform`` cannot run on symbols or when a
    point's image depends on another point (it is not a point map)."""
    moved, _ = trace(op, points=2)
    for expr in moved[0]:
        extra = {s.name for s in expr.free_symbols} - set(_JS_NAMES)
        if extra:
            raise NoJavaScriptForm(f"{op.name}: a point's image depends on other points ({', '.join(sorted(extra))}),"
                                   f" so it is not a point map and has no JavaScript form")
    return moved[0]


def _js(expr: Any, names: dict[str, str], op_name: str) -> str:
    import sympy

    def js(e: Any) -> str:
        return _js(e, names, op_name)

    if expr.is_Symbol:
        if expr.name not in names:
            raise NoJavaScriptForm(f"{op_name}: unknown symbol {expr.name!r} in the point map")
        return names[expr.name]
    if expr is sympy.pi:
        return "Math.PI"
    if expr.is_Number:
        value = float(expr)
        if not math.isfinite(value):
            raise NoJavaScriptForm(f"{op_name}: the point map has a non-finite constant")
        return f"({js_number(value)})"
    if expr.is_Add:
        return "(" + " + ".join(js(arg) for arg in expr.args) + ")"
    if expr.is_Mul:
        return "(" + " * ".join(js(arg) for arg in expr.args) + ")"
    if expr.is_Pow:
        base, exponent = expr.args
        if exponent == sympy.Rational(1, 2):
            return f"Math.sqrt({js(base)})"
        if exponent == sympy.Rational(-1, 2):
            return f"(1 / Math.sqrt({js(base)}))"
        if exponent.is_Integer and 0 < abs(int(exponent)) <= 4:
            power = "(" + " * ".join([js(base)] * abs(int(exponent))) + ")"
            return power if int(exponent) > 0 else f"(1 / {power})"
        return f"Math.pow({js(base)}, {js(exponent)})"
    if isinstance(expr, sympy.sin):
        return f"Math.sin({js(expr.args[0])})"
    if isinstance(expr, sympy.cos):
        return f"Math.cos({js(expr.args[0])})"
    raise NoJavaScriptForm(f"{op_name}: {type(expr).__name__} in the point map has no JavaScript form "
                           f"(allowed: arithmetic, powers, sin, cos, sqrt)")


def point_map_js(op: EditOp) -> str:
    """``function (q, a, pr, out) {...}``: ``op``'s map of one point ``q`` at amount ``a``
    (``pr`` is unused: the op's fields are constants in the text)."""
    import sympy

    shared, reduced = sympy.cse(point_map_expressions(op), symbols=sympy.numbered_symbols("t"))
    names = dict(_JS_NAMES)
    lines = []
    for symbol, value in shared:
        lines.append(f"var {symbol.name} = {_js(value, names, op.name)};")
        names[symbol.name] = symbol.name
    lines += [f"out[{k}] = {_js(expr, names, op.name)};" for k, expr in enumerate(reduced)]
    return "function (q, a, pr, out) { " + " ".join(lines) + " }"


_BINARY = {ast.Add: lambda x, y: x + y, ast.Sub: lambda x, y: x - y, ast.Mult: lambda x, y: x * y,
           ast.Div: lambda x, y: x / y}
_MATH = {"sin": math.sin, "cos": math.cos, "sqrt": math.sqrt, "pow": math.pow}


def _evaluate(node: ast.AST, names: dict[str, float], q: Sequence[float]) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in names:
        return names[node.id]
    if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "q" \
            and isinstance(node.slice, ast.Constant) and node.slice.value in (0, 1, 2):
        return float(q[node.slice.value])
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "Math" \
            and node.attr == "PI":
        return math.pi
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _BINARY[type(node.op)](_evaluate(node.left, names, q), _evaluate(node.right, names, q))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _evaluate(node.operand, names, q)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and isinstance(node.func.value, ast.Name) \
            and node.func.value.id == "Math" and node.func.attr in _MATH and not node.keywords:
        return _MATH[node.func.attr](*(_evaluate(arg, names, q) for arg in node.args))
    raise ValueError(f"not in the point-map grammar: {ast.dump(node)[:80]}")


def evaluate_point_map(text: str, point: Sequence[float], amount: float) -> list[float]:
    """Run a :func:`point_map_js` text on one point in Python (its grammar only, read with ``ast``)."""
    prefix, suffix = "function (q, a, pr, out) { ", " }"
    if not (text.startswith(prefix) and text.endswith(suffix)):
        raise ValueError("not a generated point map")
    names: dict[str, float] = {"a": float(amount)}
    out = [math.nan] * 3
    for statement in filter(None, (s.strip() for s in text[len(prefix):-len(suffix)].split(";"))):
        target, _, expression = statement.partition(" = ")
        value = _evaluate(ast.parse(expression, mode="eval").body, names, point)
        if target.startswith("var "):
            names[target[4:]] = value
        elif target in ("out[0]", "out[1]", "out[2]"):
            out[int(target[4])] = value
        else:
            raise ValueError(f"not in the point-map grammar: {statement[:80]}")
    return out
