"""The example operator: hand-computed corners, symbolic = numeric, found through its entry point."""

import math

import numpy as np

from parsel_core import Hexahedron, Part, Program, ShapeGraph, compile_program, evaluate
from parsel_core.plugins import edit_operators


def column() -> ShapeGraph:
    return ShapeGraph([Part("post", "post", Hexahedron.from_bounds((-1, 0, -1), (1, 2, 1)))])


def test_twist_is_registered_through_its_entry_point():
    assert edit_operators()["twist"].__module__ == "parsel_example_twist"


def test_twist_turns_each_corner_by_amount_times_height():
    program = Program.from_text("param x in [0, 1]\ntwist(post, origin=(0, 0, 0), axis=(0, 1, 0), amount=x)")
    corners = evaluate(program, column(), {"x": 0.5}).parts["post"]
    rest = column().part("post").hexahedron.corners
    for k in range(8):
        angle = 0.5 * rest[k, 1]  # bottom corners (y = 0) stay, top ones (y = 2) turn by 1 rad
        x, z = rest[k, 0], rest[k, 2]
        expected = (x * math.cos(angle) + z * math.sin(angle), rest[k, 1], -x * math.sin(angle) + z * math.cos(angle))
        assert np.allclose(corners[k], expected)


def test_twist_symbolic_path_matches_numeric(parsel_backend):
    program = Program.from_text("param x in [0, 1]\ntwist(face(post, 'v+'), origin=(0, 0, 0), axis=(0, 1, 0), "
                                "amount=x * x)")
    compiled = compile_program(program, column(), parsel_backend)
    values = np.linspace(0, 1, 7)
    assert np.allclose(compiled({"x": values}).parts["post"], evaluate(program, column(), {"x": values}).parts["post"])


def test_twist_round_trips_through_both_program_forms():
    program = Program.from_text("twist(post, origin=(0, 0.5, 0), axis=(0, 2, 0), amount=x)")
    assert Program.from_json(program.to_json()) == program
    assert Program.from_text(program.to_text()) == program
    assert program.ops[0].axis == (0.0, 1.0, 0.0)


def test_the_mirror_image_of_a_twist_turns_the_other_way():
    """Mirrored in the plane x = 0, a twist about y maps (-x, y, z) to the mirror of the image of (x, y, z)."""
    from parsel_core.program import NUMPY_MATH

    twist = Program.from_text("twist(post, origin=(0.5, 0, 0), axis=(0, 1, 0), amount=x)").ops[0]
    mirrored = twist.mirrored((0, 0, 0), (1, 0, 0), "post")
    assert mirrored.origin == (-0.5, 0.0, 0.0) and mirrored.amount == "-(x)"
    points = np.array([[1.0, 2.0, 0.3], [0.2, 0.5, -0.7]])
    flip = np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(mirrored.transform(points * flip, -0.4, NUMPY_MATH),
                               twist.transform(points, 0.4, NUMPY_MATH) * flip, atol=1e-12)
