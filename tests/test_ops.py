"""Every op against hand-computed corners, on the numeric path and on every CAS backend."""

import math

import numpy as np
import pytest

from parsel_core import Hexahedron, Part, Program, ShapeGraph, compile_program, evaluate
from parsel_core.ops import KeepFixed, Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate

BOX = Hexahedron.from_bounds((0, 0, 0), (1, 2, 3))
C = BOX.corners  # rows: (u, v, w) bits of k -> (x, y, z) = (u, 2v, 3w)
VALUES = (0.0, 0.25, 0.5, 1.0, -0.3)


def single_box_shape() -> ShapeGraph:
    return ShapeGraph([Part("box", "box", BOX)], name="box")


def with_rows(rows, update):
    out = C.copy()
    out[list(rows)] = update(C[list(rows)])
    return out


CASES = {
    "translate": (Translate("box", "x", dir=(0, 0, 2)), lambda x: C + (0, 0, x)),
    "translate_scaled_amount": (Translate("box", "2*x", dir=(1, 0, 0)), lambda x: C + (2 * x, 0, 0)),
    "scale_1d_about_origin": (Scale1D("box", "x", origin=(0, 0, 0), dir=(1, 0, 0)),
                              lambda x: C * (1 + x, 1, 1)),
    "scale_1d_about_far_face": (Scale1D("box", "x", origin=(1, 0, 0), dir=(-1, 0, 0)),
                                lambda x: np.column_stack([1 + (C[:, 0] - 1) * (1 + x), C[:, 1], C[:, 2]])),
    "scale_2d": (Scale2D("box", "x", origin=(0, 0, 0), normal=(0, 1, 0)), lambda x: C * (1 + x, 1, 1 + x)),
    "scale_3d": (Scale3D("box", "x", origin=(0.5, 1, 1.5)),
                 lambda x: (0.5, 1, 1.5) + (C - (0.5, 1, 1.5)) * (1 + x)),
    "shear": (Shear("box", "x", origin=(0, 0, 0), normal=(0, 1, 0), dir=(1, 0, 0)),
              lambda x: np.column_stack([C[:, 0] + x * C[:, 1], C[:, 1], C[:, 2]])),
    "rotate_z": (Rotate("box", "x", origin=(0, 0, 0), axis=(0, 0, 1)),
                 lambda x: np.column_stack([C[:, 0] * math.cos(x) - C[:, 1] * math.sin(x),
                                            C[:, 0] * math.sin(x) + C[:, 1] * math.cos(x), C[:, 2]])),
    "rotate_quarter_turn_about_y_through_centre": (
        Rotate("box", "pi/2 * x", origin=(0.5, 1, 1.5), axis=(0, 1, 0)),
        lambda x: np.column_stack([0.5 + math.cos(math.pi / 2 * x) * (C[:, 0] - 0.5)
                                   + math.sin(math.pi / 2 * x) * (C[:, 2] - 1.5),
                                   C[:, 1],
                                   1.5 - math.sin(math.pi / 2 * x) * (C[:, 0] - 0.5)
                                   + math.cos(math.pi / 2 * x) * (C[:, 2] - 1.5)])),
    "keep_fixed": (KeepFixed("box"), lambda x: C),
    # Feature ops: only the feature's corners move.
    "taper_top_face_scale_1d": (
        Scale1D("box", "x", feature="v+", origin=(0.5, 2, 1.5), dir=(1, 0, 0)),
        lambda x: with_rows((2, 3, 6, 7), lambda r: np.column_stack([0.5 + (r[:, 0] - 0.5) * (1 + x),
                                                                     r[:, 1], r[:, 2]]))),
    "edge_translate": (Translate("box", "x", feature="u+v+", dir=(0, 1, 0)),
                       lambda x: with_rows((6, 7), lambda r: r + (0, x, 0))),
    "corner_translate": (Translate("box", "x", feature="u+v+w+", dir=(0, 0, 1)),
                         lambda x: with_rows((7,), lambda r: r + (0, 0, x))),
    "face_rotate_about_its_edge": (
        Rotate("box", "x", feature="w+", origin=(0, 0, 3), axis=(0, 1, 0)),
        lambda x: with_rows((1, 3, 5, 7), lambda r: np.column_stack([r[:, 0] * math.cos(x), r[:, 1],
                                                                     3 - r[:, 0] * math.sin(x)]))),
}


def program_of(op) -> Program:
    from parsel_core.program import Parameter

    return Program((op,), (Parameter("x", -1.0, 2.0),))


@pytest.mark.parametrize("case", sorted(CASES))
def test_op_matches_hand_computed_corners_numerically(case):
    op, expected = CASES[case]
    shape = single_box_shape()
    for x in VALUES:
        got = evaluate(program_of(op), shape, {"x": x}).parts["box"]
        assert np.allclose(got, expected(x), atol=1e-12), (case, x)


@pytest.mark.parametrize("case", sorted(CASES))
def test_op_matches_hand_computed_corners_on_every_backend(case, parsel_backend):
    op, expected = CASES[case]
    compiled = compile_program(program_of(op), single_box_shape(), parsel_backend)
    for x in VALUES:
        assert np.allclose(compiled({"x": x}).parts["box"], expected(x), atol=1e-9), (case, x)
    batch = np.array(VALUES)
    stacked = compiled({"x": batch}).parts["box"]
    assert stacked.shape == (len(VALUES), 8, 3)
    assert np.allclose(stacked, np.stack([expected(x) for x in VALUES]), atol=1e-9)


def test_batched_numeric_evaluation_matches_scalar():
    op, expected = CASES["rotate_z"]
    got = evaluate(program_of(op), single_box_shape(), {"x": np.array(VALUES)}).parts["box"]
    assert np.allclose(got, np.stack([expected(x) for x in VALUES]))


def test_face_scale_gives_a_taper():
    op, _ = CASES["taper_top_face_scale_1d"]
    corners = evaluate(program_of(op), single_box_shape(), {"x": 0.5}).parts["box"]
    top = corners[[2, 3, 6, 7]]
    bottom = corners[[0, 1, 4, 5]]
    assert np.ptp(top[:, 0]) == pytest.approx(1.5) and np.ptp(bottom[:, 0]) == pytest.approx(1.0)
    planes = Hexahedron(corners).intrinsic_symmetry_planes()
    assert len(planes) == 2  # the u (x) and w (z) mid-planes survive; the v one does not


def test_rotate_keeps_edge_lengths():
    rng = np.random.default_rng(3)
    edges = [(k, k ^ bit) for k in range(8) for bit in (1, 2, 4) if k < k ^ bit]
    rest = [np.linalg.norm(C[a] - C[b]) for a, b in edges]
    for _ in range(10):
        axis = rng.normal(size=3)
        op = Rotate("box", "x", origin=tuple(rng.normal(size=3)), axis=tuple(axis))
        for x in rng.uniform(-3, 3, size=5):
            corners = evaluate(program_of(op), single_box_shape(), {"x": float(np.clip(x, -1, 2))}).parts["box"]
            assert np.allclose([np.linalg.norm(corners[a] - corners[b]) for a, b in edges], rest)


def test_ops_compose_in_order():
    """Scale then translate differs from translate then scale, each as hand-computed."""
    from parsel_core.program import Parameter

    scale = Scale1D("box", "x", origin=(0, 0, 0), dir=(1, 0, 0))
    move = Translate("box", "1", dir=(1, 0, 0))
    shape = single_box_shape()
    p1 = Program((scale, move), (Parameter("x"),))
    p2 = Program((move, scale), (Parameter("x"),))
    x = 0.5
    assert np.allclose(evaluate(p1, shape, {"x": x}).parts["box"][:, 0], C[:, 0] * 1.5 + 1)
    assert np.allclose(evaluate(p2, shape, {"x": x}).parts["box"][:, 0], (C[:, 0] + 1) * 1.5)


def test_programs_stack_output_of_one_is_input_of_next():
    from parsel_core.program import Parameter

    first = Program((Scale1D("box", "x", origin=(0, 0, 0), dir=(1, 0, 0)),), (Parameter("x"),))
    second = Program((Translate("box", "y", dir=(0, 1, 0)),), (Parameter("y"),))
    stacked = first.then(second)
    assert stacked.parameter_names == ("x", "y")
    got = evaluate(stacked, single_box_shape(), {"x": 0.5, "y": 0.25}).parts["box"]
    assert np.allclose(got, C * (1.5, 1, 1) + (0, 0.25, 0))


def test_mirrored_op_is_the_reflected_edit():
    """E* = T(E): mirroring a translation and a rotation about x = 0 gives the mirror image."""
    from parsel_core.relations import ReflectionSymmetry

    left = Hexahedron.from_bounds((-2, 0, 0), (-1, 1, 1))
    right = Hexahedron.from_bounds((1, 0, 0), (2, 1, 1))
    shape = ShapeGraph([Part("l", "leg", left), Part("r", "leg", right)])
    relation = ReflectionSymmetry("m", ("l", "r"), (0, 0, 0), (1, 0, 0), tuple(k ^ 4 for k in range(8)))
    for op in (Translate("l", "x", dir=(1, 1, 0)), Rotate("l", "x", origin=(-1.5, 0, 0), axis=(0.3, 1, 0.2)),
               Scale1D("l", "x", feature="v+", origin=(-1.5, 1, 0.5), dir=(1, 0, 0))):
        mirrored = op.mirrored((0, 0, 0), (1, 0, 0), "r", feature_map={"v+": "v+"})
        from parsel_core.program import Parameter

        program = Program((op, mirrored), (Parameter("x"),))
        for x in (0.1, 0.7):
            corners = evaluate(program, shape, {"x": x}).parts
            assert relation.error(corners) < 1e-12, op.name


def test_vector_fields_of_float_tuples_are_read_as_any_other_sequence():
    """A tuple of three floats takes a path without numpy; it must give what a list gives:
    unit directions normalised unless already of length 1, points as they are."""
    from parsel_core.errors import ProgramFormatError
    from parsel_core.ops import as_vector

    rng = np.random.default_rng(7)
    directions = [tuple(float(v) for v in d) for d in rng.normal(size=(200, 3))]
    directions += [tuple(float(v) for v in d / np.linalg.norm(d)) for d in rng.normal(size=(200, 3))]
    directions += [(0.0, 1.0, 0.0), (-0.0, 0.0, -1.0), (0.6, 0.8, 0.0), (0.0, 1.0 + 2e-13, 0.0),
                   (0.0, 1.0 + 1e-15, 0.0), (0.0, 1.0 + 4e-12, 0.0), (3.0, 4.0, 0.0)]
    for d in directions:
        for unit in (False, True):
            assert as_vector(d, "dir", unit=unit) == as_vector(list(d), "dir", unit=unit)
    assert as_vector((0.0, 2.0, 0.0), "dir", unit=True) == (0.0, 1.0, 0.0)
    assert as_vector((0.0, 1.0 + 4e-12, 0.0), "dir", unit=True) == (0.0, 1.0, 0.0)
    assert as_vector((0.0, 1.0 + 2e-13, 0.0), "dir", unit=True) == (0.0, 1.0 + 2e-13, 0.0)
    assert Translate("box", dir=(3.0, 4.0, 0.0)).dir == pytest.approx((0.6, 0.8, 0.0), abs=1e-15)
    for bad in ((0.0, float("nan"), 1.0), (float("inf"), 0.0, 0.0)):
        with pytest.raises(ProgramFormatError, match="must be finite"):
            as_vector(bad, "dir", unit=True)
    with pytest.raises(ProgramFormatError, match="non-zero direction"):
        as_vector((0.0, 0.0, 0.0), "dir", unit=True)
