"""Amounts as JavaScript: written from the safe tree, evaluated by Node like numpy evaluates them."""

from __future__ import annotations

import json
import math
import subprocess

import pytest

from parsel_core.errors import ProgramFormatError
from parsel_core.expressions import numpy_functions, parse_expression
from parsel_view.jsexpr import amount_to_js, amounts_script, js_number
from parsel_view.testing import node_path

EXPRESSIONS = [
    "x", "0.5 * x", "-x ** 2", "(-x) ** 2", "x ** 0.5 + y / 3", "2 ** -x", "-(x + y) * 3 - -1",
    "sin(x) * cos(y) + tan(x / 3)", "atan2(y, x)", "asin(x / 2) + acos(-x / 2) + atan(y)",
    "sqrt(x) + exp(-y) + log(x + 1)", "abs(y) + floor(3.7 * x) + ceiling(-2.2 * y)",
    "min(x, y) - max(x, 0.25)", "pi * x + e", "1e-3 * x + 4", "0.190000005066*x",
]


def test_parameters_are_read_by_name_and_constants_mapped():
    assert amount_to_js("2 * x + pi", ["x"]) == '(((2.0) * p["x"]) + Math.PI)'
    assert amount_to_js("x ** 2", ["x"]) == 'Math.pow(p["x"], (2.0))'
    assert amount_to_js("ceiling(x)", ["x"]) == 'Math.ceil(p["x"])'


def test_numbers_round_trip():
    assert js_number(0.1) == "0.1"
    assert float(js_number(1 / 3)) == 1 / 3
    assert js_number(float("inf")) == "Infinity"


def test_names_outside_the_program_are_refused():
    with pytest.raises(ProgramFormatError, match="unknown parameter 'y'"):
        amount_to_js("x + y", ["x"])


def test_refused_expressions_never_reach_javascript():
    for text in ("__import__('os')", "x.real", "[x]", "x if x else 1", "lambda: 1"):
        with pytest.raises(ProgramFormatError):
            amount_to_js(text, ["x"])


@pytest.mark.skipif(node_path() is None, reason="node is not installed")
def test_node_evaluates_like_numpy(tmp_path):
    script = tmp_path / "amounts.js"
    script.write_text(amounts_script(EXPRESSIONS, ["x", "y"]), encoding="utf-8")
    points = [{"x": 0.3, "y": -0.7}, {"x": 1.7, "y": 0.2}, {"x": 0.0, "y": 0.0}]
    runner = ("const f = require(process.argv[1]).amounts; const pts = JSON.parse(process.argv[2]);"
              "process.stdout.write(JSON.stringify(pts.map(p => f.map(g => { const v = g(p); "
              "return Number.isFinite(v) ? v : String(v); }))));")
    done = subprocess.run([node_path(), "-e", runner, str(script), json.dumps(points)], capture_output=True, text=True,
                          check=True)
    for point, row in zip(points, json.loads(done.stdout)):
        for text, got in zip(EXPRESSIONS, row):
            with __import__("numpy").errstate(all="ignore"):
                expected = float(parse_expression(text).build(point, numpy_functions()))
            if math.isnan(expected) or math.isinf(expected):
                assert str(got) in ("NaN", "Infinity", "-Infinity"), (text, point)
            else:
                assert got == pytest.approx(expected, rel=1e-14, abs=1e-15), (text, point)
