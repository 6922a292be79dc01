"""The page's evaluator (parsel_eval.js, run in Node) against parsel's own evaluation and deformer."""

from __future__ import annotations

import numpy as np
import pytest

from parsel_core.hexahedron import Hexahedron, corner_jacobians
from parsel_core.program import Program, evaluate
from parsel_mesh.deform import deformed_vertices
from parsel_mesh.loaders import shape_from_meshes
from parsel_mesh.testing import box_mesh
from parsel_view.inputs import stack_programs
from parsel_view.scene import build_page_data
from parsel_view.testing import node_evaluate, node_path

from .conftest import CHAIR_PROGRAM, TABLE_PROGRAM

pytestmark = pytest.mark.skipif(node_path() is None, reason="node is not installed (the page's JS runs in Node here)")


def assert_same(program: Program, shape, values_list, vertex_atol: float = 2e-7) -> list[dict]:
    """Corners (float64) agree to 1e-12, float32 vertex positions to float32 rounding."""
    results = node_evaluate(build_page_data(program, shape), values_list)
    for values, result in zip(values_list, results):
        reference = evaluate(program, shape, values)
        for pid, corners in reference.parts.items():
            got = np.array([np.nan if v is None else v for v in result["parts"][pid]], dtype=float).reshape(8, 3)
            np.testing.assert_allclose(got, corners, atol=1e-12, err_msg=f"{pid} at {values}")
        assert sorted(result["instances"]) == sorted(reference.instances)
        for group, instances in reference.instances.items():
            np.testing.assert_allclose(np.array(result["instances"][group]).reshape(-1, 8, 3), instances, atol=1e-12)
        assert result["removed"] == sorted(reference.removed)
        expected = deformed_vertices(shape, reference)
        assert sorted(result["vertices"]) == sorted(expected)
        for name, vertices in expected.items():
            np.testing.assert_allclose(np.array(result["vertices"][name]).reshape(-1, 3), vertices, atol=vertex_atol,
                                       err_msg=f"{name} at {values}")
    return results


def test_every_part_op_on_the_chair(chair):
    program = Program.from_text(CHAIR_PROGRAM)
    assert_same(program, chair, [{"x": 0.0, "y": 0.0}, {"x": 0.37, "y": -0.41}, {"x": 1.0, "y": 0.5}])


def jacobian_signs(corners: np.ndarray) -> list[float]:
    """Signs of the cage map's Jacobian at the 8 corners and the centre."""
    return [*np.sign(corner_jacobians(corners)).tolist(), float(np.sign(Hexahedron(corners).volume))]


def test_a_mirroring_or_folding_edit_is_flagged_so_back_faces_are_drawn(chair):
    """scale_1d by an amount below -1 turns the seat inside out; pushing a corner of a leg past
    its neighbours folds part of it; rotations keep orientation."""
    program = Program.from_text("param x in [-3, 1] default 0\n"
                                "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)\n"
                                "rotate('leg.000', origin=(0, 0, 0), axis=(0, 1, 0), amount=3 * x)\n"
                                "translate(corner('leg.001', 'u+v+w+'), dir=(0, -1, 0), amount=-x)\n")
    values = [{"x": 0.5}, {"x": -0.3}, {"x": -0.6}, {"x": -2.0}]
    results = assert_same(program, chair, values)
    # the same test in Python: some Jacobian sign differs from the rest sign
    expected = []
    for v in values:
        edited = evaluate(program, chair, v).parts
        expected.append(sorted(pid for pid in ("seat", "leg.000", "leg.001") if set(jacobian_signs(edited[pid]))
                               != {jacobian_signs(chair.parts[pid].hexahedron.corners)[8]}))
    assert [r["flipped"] for r in results] == expected
    assert expected == [[], [], ["leg.001"], ["leg.001", "seat"]]


def test_amounts_evaluate_like_numpy(chair):
    program = Program.from_text(CHAIR_PROGRAM)
    result = node_evaluate(build_page_data(program, chair), [{"x": 0.3, "y": 0.2}])[0]
    from parsel_core.expressions import numpy_functions, parse_expression

    for op, amount in zip(program.ops, result["amounts"]):
        expected = float(parse_expression(op.amount).build({"x": 0.3, "y": 0.2}, numpy_functions()))
        assert amount == pytest.approx(expected, abs=1e-15), op.amount


@pytest.mark.parametrize("mode", ["top_down", "bottom_up"])
def test_translation_group_layouts(row_shape, mode):
    program = Program.from_text(f"""
param x in [-1, 1] default 0
scale_1d(row, origin=(0, 0, 0), dir=(1, 0, 0), amount=0.5 * x)
change_count(row, mode='{mode}', amount=3 * x)
""")
    assert_same(program, row_shape, [{"x": -1.0}, {"x": -0.4}, {"x": 0.0}, {"x": 0.5}, {"x": 1.0}])


def test_translation_change_delta_top_down_changes_the_count(row_shape):
    program = Program.from_text("""
param x in [-0.5, 1] default 0
change_delta(row, mode='top_down', amount=x)
translate(slat_0, dir=(0, 1, 0), amount=0.1 * x)
""")
    results = assert_same(program, row_shape, [{"x": -0.5}, {"x": 0.0}, {"x": 1.0}])
    assert [len(r["instances"]["row"]) for r in results] == [7, 4, 2]


@pytest.mark.parametrize("text", [
    "change_count(spokes, mode='top_down', amount=4 * x)",
    "change_count(spokes, mode='bottom_up', amount=-4 * x)",
    "change_delta(spokes, mode='top_down', amount=x)",
    "change_delta(spokes, mode='bottom_up', amount=x / 3)",
])
def test_rotation_group_layouts(wheel_shape, text):
    program = Program.from_text(f"param x in [0, 1] default 0\nscale_3d(spokes, origin=(0, 0, 0), amount=0.2 * x)\n"
                                f"{text}\n")
    assert_same(program, wheel_shape, [{"x": 0.0}, {"x": 0.3}, {"x": 1.0}])


def test_a_mesh_that_is_its_own_cage_follows_the_corners_in_the_page():
    """The page's deformation of a box mesh whose vertices are its cage's corners gives the corners
    (parsel-mesh's tests/test_deform.py proves the same for the Python deformer)."""
    shape = shape_from_meshes({"box": box_mesh((0, 0, 0), (1, 0.5, 0.25))}, name="cage")
    program = Program.from_text("translate(face(box, 'u+'), dir=(1, 0, 0), amount=0.3 * x)\n"
                                "rotate(corner(box, 'u-v+w+'), origin=(0, 0, 0), axis=(0, 0, 1), amount=x)\n")
    result = node_evaluate(build_page_data(program, shape), [{"x": 0.8}])[0]
    corners = evaluate(program, shape, {"x": 0.8}).parts["box"]
    vertices = np.array(result["vertices"]["box"]).reshape(-1, 3)
    rest = shape.parts["box"].hexahedron.corners
    order = np.linalg.norm(np.asarray(shape.parts["box"].mesh.vertices)[:, None] - rest[None], axis=2).argmin(axis=1)
    np.testing.assert_allclose(vertices, corners[order], atol=1e-7)  # float32 positions


def test_stacked_programs_keep_separate_sliders(chair):
    first = Program.from_text("param x in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)")
    second = Program.from_text("param x in [0, 0.5]\ntranslate(seat, dir=(0, 1, 0), amount=x * 2)")
    stacked = stack_programs([first, second])
    assert stacked.parameter_names == ("x", "x_2")
    page = build_page_data(stacked, chair)
    assert [p["name"] for p in page.scene["parameters"]] == ["x", "x_2"]
    assert_same(stacked, chair, [{"x": 0.5, "x_2": 0.25}])


def test_hexahedra_only_shapes_are_drawn_as_boxes(parsel_shape):
    program = Program.from_text(TABLE_PROGRAM + "change_count(slat_row, mode='top_down', amount=4 * x)\n")
    page = build_page_data(program, parsel_shape)
    assert all(mesh["vertices"] == 8 and mesh["faces"] == 12 for mesh in page.scene["meshes"])
    results = node_evaluate(page, [{"x": 0.0}, {"x": 0.5}])
    for values, result in zip([{"x": 0.0}, {"x": 0.5}], results):
        reference = evaluate(program, parsel_shape, values)
        np.testing.assert_allclose(np.array(result["instances"]["slat_row"]).reshape(-1, 8, 3),
                                   reference.instances["slat_row"], atol=1e-12)
        np.testing.assert_allclose(np.array(result["vertices"]["top"]).reshape(8, 3), reference.parts["top"],
                                   atol=1e-6)


def test_parts_named_like_javascript_object_members_show_on_the_page():
    """Names such as ``constructor`` or ``__proto__`` are plain keys in the page's tables."""
    names = ["constructor", "__proto__", "toString", "hasOwnProperty", "valueOf", "seat"]
    shape = shape_from_meshes({name: box_mesh((2.0 * i, 0, 0), (2.0 * i + 1, 1, 1)) for i, name in enumerate(names)},
                              name="hostile")
    assert sorted(shape.parts) == sorted(names)
    program = Program.from_text("translate(constructor, dir=(0, 1, 0), amount=x)\n"
                                "scale_1d('__proto__', origin=(2, 0, 0), dir=(1, 0, 0), amount=x)\n")
    results = assert_same(program, shape, [{"x": 0.0}, {"x": 0.5}])
    assert sorted(results[1]["vertices"]) == sorted(names)  # every part is drawn
    moved = np.array(results[1]["parts"]["constructor"]).reshape(8, 3)
    assert moved[:, 1].min() == pytest.approx(0.5)


def test_layered_programs_add_displacements_like_python(chair):
    first = Program.from_text("param x1 in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x1)\n"
                              "translate('leg.000', dir=(-1, 0, 0), amount=0.19 * x1)")
    second = Program.from_text("param x2 in [0, 1]\nscale_2d('leg.000', origin=(-0.19, 0.2075, 0.18), "
                               "normal=(0, 1, 0), amount=x2)\nrotate(seat, origin=(0, 0.43, 0), axis=(0, 1, 0), "
                               "amount=0.3 * x2)")
    layered = first.plus(second)
    page = build_page_data(layered, chair)
    assert page.scene["layers"] == [[0, 2], [2, 4]]
    assert_same(layered, chair, [{"x1": 0.0, "x2": 0.0}, {"x1": 0.7, "x2": 0.4}, {"x1": 1.0, "x2": 1.0}])


def test_the_page_finds_the_relations_python_finds_broken():
    """The page's relation check (linear residuals, sliding contacts, laid-out groups) against parsel_core.report."""
    from parsel_core.api import as_shape, edit, proxydural
    from parsel_core.report import relation_errors, sliding_members, tolerance_for

    chair = as_shape("chair")  # with its detected relations
    wider = edit(chair, seed="scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)").program
    thicker = edit(chair, seed="scale_2d('leg.000', origin=(-0.19, 0.2075, 0.18), normal=(0, 1, 0), "
                               "amount=x)").program.renamed("x", "x_2")
    sequential = wider.then(thicker)  # the old stacking: the legs thicken about their rest centres
    shelf = proxydural("shelf", 4)  # layers with a re-laid-out row of boards sliding along the panels
    values = [{"x": 0.0, "x_2": 0.0}, {"x": 1.0, "x_2": 0.0}, {"x": 1.0, "x_2": 1.0}, {"x": 0.3, "x_2": 0.8}]
    shelf_values = [{f"x{i}": v for i, v in enumerate(row, start=1)}
                    for row in ([0, 0, 0, 0], [1, 1, 1, 1], [1, 0, 1, 0.6], [0.2, 0.9, 0.4, 1])]
    cases = [(chair, sequential, values), (chair, stack_programs([wider, thicker.renamed("x_2", "x")]), values),
             (shelf.shape, shelf.program, shelf_values)]
    for shape, program, points in cases:
        tolerance = tolerance_for(shape)
        results = node_evaluate(build_page_data(program, shape), points)
        for value, result in zip(points, results):
            errors = relation_errors(shape, evaluate(program, shape, value).parts, sliding_members(shape, program))
            expected = sorted(r for r, e in errors.items() if not e < shape.relations[r].allowance(tolerance))
            assert result["broken"] == expected, value
    assert node_evaluate(build_page_data(sequential, chair), [values[2]])[0]["broken"]  # the old way breaks some


def test_outer_layers_with_followed_points_evaluate_like_python(chair):
    """An outer layer runs after the sum, its following ops carried by their point's shift."""
    from parsel_core.program import Follow

    first = Program.from_text("param x1 in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x1)\n"
                              "translate('leg.000', dir=(-1, 0, 0), amount=0.19 * x1)")
    second = Program.from_text("param x2 in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(0, 1, 0), amount=x2)")
    turn = Program.from_text("param x3 in [0, 1]\n"
                             "rotate(seat, origin=(0.2, 0.43, 0), axis=(0, 0, 1), amount=0.5 * x3)\n"
                             "rotate('leg.000', origin=(0.2, 0.43, 0), axis=(0, 0, 1), amount=0.5 * x3)")
    program = first.atop(turn, (Follow("seat", (0.2, 0.43, 0.0), (0, 1)),)).plus(second)  # outer layer in the middle
    page = build_page_data(program, chair)
    assert page.scene["outer"] == [1] and page.scene["follows"][0]["part"] == "seat"
    assert [op.get("follow") for op in page.scene["ops"]] == [None, None, 0, 0, None]
    assert_same(program, chair, [{"x1": 0.0, "x2": 0.0, "x3": 0.0}, {"x1": 0.7, "x2": 0.4, "x3": 0.5},
                                 {"x1": 1.0, "x2": 1.0, "x3": 1.0}])
