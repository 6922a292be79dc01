"""Point maps generated from an operator's transform (parsel_view.opjs): the page's form of plugin ops."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from parsel_core.ops import EditOp, Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate
from parsel_core.program import NUMPY_MATH, Program
from parsel_view.opjs import NoJavaScriptForm, evaluate_point_map, point_map_js
from parsel_view.scene import build_page_data
from parsel_view.testing import node_path

BUILTINS = [
    Translate("p", dir=(0.3, -1, 0.2)),
    Rotate("p", origin=(0.1, 0.2, -0.3), axis=(1, 2, 0.5)),
    Scale1D("p", origin=(0, 0.4, 0), dir=(1, 1, 0)),
    Scale2D("p", origin=(0.2, 0, 0), normal=(0, 1, 0)),
    Scale3D("p", origin=(0.5, 0.5, 0.5)),
    Shear("p", origin=(0, 0, 0), normal=(0, 1, 0), dir=(0, 0, 1)),
]


@dataclass(frozen=True)
class Bend(EditOp):
    """A plugin-style op using sin, cos and sqrt: points turn about y by amount times their distance to it."""

    name: ClassVar[str] = "bend_test"

    def transform(self, points, amount, math):
        x, y, z = points[..., 0:1], points[..., 1:2], points[..., 2:3]
        angle = math.sqrt(x * x + z * z) * amount
        c, s = math.cos(angle), math.sin(angle)
        return np.concatenate([x * c + z * s, y, z * c - x * s], axis=-1)


@dataclass(frozen=True)
class Centre(EditOp):
    """Not a point map: every point moves towards the mean of all of them."""

    name: ClassVar[str] = "centre_test"

    def transform(self, points, amount, math):
        return points + (points.mean(axis=-2, keepdims=True) - points) * amount


POINTS = np.array([[0.3, -0.2, 0.9], [1.1, 0.5, -0.4], [0.0, 0.0, 0.0], [-0.7, 2.0, 0.25]])


@pytest.mark.parametrize("op", BUILTINS + [Bend("p")], ids=lambda op: op.name)
def test_generated_map_is_the_transform(op):
    text = point_map_js(op)
    for amount in (0.0, 0.37, -1.3):
        expected = op.transform(POINTS, amount, NUMPY_MATH)
        got = np.array([evaluate_point_map(text, point, amount) for point in POINTS])
        np.testing.assert_allclose(got, expected, atol=1e-12, err_msg=f"{op.name} at {amount}")


def test_the_text_uses_only_the_small_grammar():
    text = point_map_js(Bend("p"))
    assert text.startswith("function (q, a, pr, out) { ") and "Math.sqrt(" in text and "Math.sin(" in text
    assert "out[0] = " in text and "out[2] = " in text
    with pytest.raises(ValueError, match="not in the point-map grammar"):
        evaluate_point_map(text.replace("Math.sin(", "alert("), (0, 0, 0), 0.1)


def test_an_op_mixing_points_is_refused_by_name():
    with pytest.raises(NoJavaScriptForm, match=r"centre_test: a point's image depends on other points"):
        point_map_js(Centre("p"))


@pytest.mark.skipif(node_path() is None, reason="node is not installed (the page's JS runs in Node here)")
def test_the_page_evaluates_a_plugin_op_like_python(chair):
    from .test_page_eval import assert_same

    program = Program((Bend("seat", amount="x"), Bend("leg.000", amount="2 * x", feature="v+"),
                       Translate("seat", dir=(0, 1, 0), amount="0.1 * x")))
    scene = build_page_data(program, chair).scene
    assert [op.get("generated") for op in scene["ops"]] == [True, True, False]
    assert_same(program, chair, [{"x": 0.0}, {"x": 0.4}, {"x": 1.0}])


def twist_program() -> Program:
    from parsel_core.plugins import edit_operators

    if "twist" not in edit_operators():
        pytest.skip("the twist example plugin (plugins/parsel-example-twist) is not installed")
    return Program.from_text("param x in [-1, 1] default 0\n"
                             "twist('leg.000', origin=(-0.19, 0, -0.19), axis=(0, 1, 0), amount=3 * x)\n"
                             "twist(face(seat, 'v+'), origin=(0, 0.43, 0), axis=(0, 1, 0), amount=x)\n")


@pytest.mark.skipif(node_path() is None, reason="node is not installed (the page's JS runs in Node here)")
def test_the_twist_example_on_the_page(chair):
    from .test_page_eval import assert_same

    program = twist_program()
    assert [op.get("generated") for op in build_page_data(program, chair).scene["ops"]] == [True, True]
    results = assert_same(program, chair, [{"x": 0.0}, {"x": 0.6}, {"x": -1.0}])
    assert results[1]["parts"]["leg.000"] != results[0]["parts"]["leg.000"]  # it moved
