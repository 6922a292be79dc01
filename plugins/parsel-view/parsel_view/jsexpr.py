"""Amount expressions as JavaScript, written by walking the validated expression tree.

The slider page evaluates every amount in the browser, so each amount becomes a small
JavaScript function of the parameter values. The text is produced from the tree that
:func:`parsel_core.expressions.parse_expression` has already checked against its
whitelist (numbers, parameters, ``pi``/``e``, arithmetic and the listed functions), so
nothing but those constructs can reach the page, and no amount is ever evaluated with
``eval`` on either side. Every sub-expression is parenthesised, so JavaScript's operator
precedence (``-x ** 2`` is a syntax error there) never has to agree with Python's.
"""

from __future__ import annotations

import ast
import json
import math
from collections.abc import Mapping, Sequence

from parsel_core.errors import ProgramFormatError
from parsel_core.expressions import FUNCTIONS, parse_expression

#: The whitelisted functions as JavaScript, with numpy's argument order (``atan2(y, x)``).
JS_FUNCTIONS: dict[str, str] = {
    "sin": "Math.sin", "cos": "Math.cos", "tan": "Math.tan", "asin": "Math.asin", "acos": "Math.acos",
    "atan": "Math.atan", "atan2": "Math.atan2", "sqrt": "Math.sqrt", "exp": "Math.exp", "log": "Math.log",
    "abs": "Math.abs", "floor": "Math.floor", "ceiling": "Math.ceil", "min": "Math.min", "max": "Math.max",
}
JS_CONSTANTS: dict[str, str] = {"pi": "Math.PI", "e": "Math.E"}
_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}

assert set(JS_FUNCTIONS) == set(FUNCTIONS), "every whitelisted function needs a JavaScript form"


def js_number(value: float) -> str:
    """A float literal JavaScript reads back to the same double (shortest round trip)."""
    value = float(value)
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Infinity" if value > 0 else "(-Infinity)"
    return repr(value)


def _js(node: ast.AST, parameter: str, names: frozenset[str], text: str) -> str:
    if isinstance(node, ast.Constant):
        return f"({js_number(node.value)})"
    if isinstance(node, ast.Name):
        if node.id in names:
            # Bracket access with a JSON string: a parameter named like a JS keyword still works.
            return f"{parameter}[{json.dumps(node.id)}]"
        if node.id in JS_CONSTANTS:
            return JS_CONSTANTS[node.id]
        raise ProgramFormatError(f"amount {text!r}: unknown parameter {node.id!r}")
    if isinstance(node, ast.BinOp):
        left = _js(node.left, parameter, names, text)
        right = _js(node.right, parameter, names, text)
        if isinstance(node.op, ast.Pow):
            return f"Math.pow({left}, {right})"
        return f"({left} {_BINARY[type(node.op)]} {right})"
    if isinstance(node, ast.UnaryOp):
        operand = _js(node.operand, parameter, names, text)
        return f"(-{operand})" if isinstance(node.op, ast.USub) else f"(+{operand})"
    if isinstance(node, ast.Call):
        args = ", ".join(_js(arg, parameter, names, text) for arg in node.args)
        return f"{JS_FUNCTIONS[node.func.id]}({args})"
    raise ProgramFormatError(f"amount {text!r}: {type(node).__name__} has no JavaScript form")


def amount_to_js(text: str, parameters: Sequence[str], parameter: str = "p") -> str:
    """The amount ``text`` as a JavaScript expression reading values from object ``parameter``.

    ``parameters`` are the program's parameter names; any other name is an error (the
    program's own validation already refuses undeclared names).
    """
    expression = parse_expression(text)
    return _js(expression.tree, parameter, frozenset(parameters), expression.text)


def amounts_script(texts: Sequence[str], parameters: Sequence[str], point_maps: Mapping[int, str] | None = None) -> str:
    """A script defining ``PARSEL_AMOUNTS`` (one function of the parameter values per op) and
    ``PARSEL_POINT_MAPS`` (op index -> generated point map, :mod:`parsel_view.opjs`)."""
    lines = ["\"use strict\";", "var PARSEL_AMOUNTS = ["]
    for i, text in enumerate(texts):
        body = amount_to_js(text, parameters)
        comment = " ".join(str(text).split()).replace("*/", "* /")
        lines.append(f"  /* op {i}: {comment} */ function (p) {{ return {body}; }},")
    lines.append("];")
    lines.append("var PARSEL_POINT_MAPS = {")
    for index, text in sorted((point_maps or {}).items()):
        lines.append(f"  {int(index)}: {text},")
    lines.append("};")
    lines.append("if (typeof window !== \"undefined\") { window.PARSEL_AMOUNTS = PARSEL_AMOUNTS; "
                 "window.PARSEL_POINT_MAPS = PARSEL_POINT_MAPS; }")
    lines.append("if (typeof module !== \"undefined\") { module.exports = { amounts: PARSEL_AMOUNTS, "
                 "pointMaps: PARSEL_POINT_MAPS }; }")
    return "\n".join(lines) + "\n"
