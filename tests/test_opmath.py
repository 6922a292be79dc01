"""parsel_core.opmath: one sin/cos/sqrt for floats, float arrays, object arrays and CAS expressions."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from parsel_core import Hexahedron, Part, Program, ShapeGraph, compile_program, evaluate, hookimpl, opmath
from parsel_core.ops import EditOp


def test_floats_and_float_arrays():
    assert opmath.sin(math.pi / 6) == pytest.approx(0.5)
    assert opmath.cos(0.0) == 1.0
    assert opmath.sqrt(9) == 3.0
    np.testing.assert_allclose(opmath.sqrt(np.array([[4.0], [16.0]])), [[2.0], [4.0]])
    np.testing.assert_allclose(opmath.cos(np.array([0.0, math.pi])), [1.0, -1.0])


def test_object_arrays_of_expressions_entry_by_entry(parsel_backend):
    x = parsel_backend.symbol("x")
    values = np.array([[x * 2], [x + parsel_backend.number(1)]], dtype=object)
    out = opmath.sin(values)
    assert out.shape == (2, 1) and out.dtype == object
    f = parsel_backend.compile(["x"], [out[0, 0], out[1, 0], opmath.sqrt(x * x + 9)])
    np.testing.assert_allclose(np.asarray(f(0.25), dtype=float).ravel(), [math.sin(0.5), math.sin(1.25), 3.0 + 1 / 96],
                               rtol=1e-3)
    np.testing.assert_allclose(np.asarray(f(4.0), dtype=float).ravel(), [math.sin(8), math.sin(5), 5.0])


@dataclass(frozen=True)
class Bulge(EditOp):
    """Moves points away from the y axis by ``amount`` times their distance to it (uses sqrt)."""

    name: ClassVar[str] = "bulge_test"

    def transform(self, points, amount, math):
        radius = math.sqrt(points[..., 0:1] * points[..., 0:1] + points[..., 2:3] * points[..., 2:3])
        grow = radius * amount
        return points + points * np.array([1.0, 0.0, 1.0]) * grow


class _Plugin:
    @hookimpl
    def parsel_edit_operators(self):
        return [Bulge]


def test_an_operator_using_math_sqrt_agrees_on_both_paths(parsel_backend, parsel_register):
    parsel_register(_Plugin())
    shape = ShapeGraph([Part("post", "post", Hexahedron.from_bounds((-1, 0, -1), (1, 2, 1)))])
    program = Program.from_text("param x in [0, 1]\nbulge_test(post, amount=x)")
    numeric = evaluate(program, shape, {"x": 0.5}).parts["post"]
    # Every corner is sqrt(2) from the axis: it moves outwards by 0.5 * sqrt(2) times itself.
    np.testing.assert_allclose(numeric[:, [0, 2]], shape.part("post").hexahedron.corners[:, [0, 2]]
                               * (1 + 0.5 * math.sqrt(2)))
    compiled = compile_program(program, shape, parsel_backend)({"x": 0.5}).parts["post"]
    np.testing.assert_allclose(compiled, numeric, atol=1e-12)
