"""ChangeCount and ChangeDelta: expected instance positions in both modes."""

import math

import numpy as np
import pytest

from parsel_core import Hexahedron, Part, Program, ShapeGraph, compile_program, evaluate
from parsel_core.relations import RotationSymmetry, TranslationSymmetry, rotation_matrix


def centres_x(evaluation, group="slat_row"):
    return evaluation.instances[group].mean(axis=1)[:, 0]


CASES = {
    # the slat row: centres -0.3, -0.1, 0.1, 0.3 (step 0.2), slats 0.06 wide
    "bottom_up count +2 appends at the same step": (
        'change_count(slat_row, amount=2, mode="bottom_up")', 0.0, [-0.3 + 0.2 * j for j in range(6)]),
    "top_down count +2 fills the parent's span": (
        'change_count(slat_row, amount=2, mode="top_down")', 0.0, [-0.3 + 0.12 * j for j in range(6)]),
    "count follows the amount, rounded": (
        'change_count(slat_row, amount=4 * x, mode="bottom_up")', 0.3, [-0.3 + 0.2 * j for j in range(5)]),
    "count never drops below one": (
        'change_count(slat_row, amount=-9, mode="top_down")', 0.0, [-0.3]),
    "bottom_up delta scales the step, keeps the count": (
        'change_delta(slat_row, amount=x, mode="bottom_up")', 0.5, [-0.3 + 0.3 * j for j in range(4)]),
    "top_down delta keeps the span, count is what fits": (
        'change_delta(slat_row, amount=x, mode="top_down")', 0.5, [-0.3, 0.0, 0.3]),
    "top_down: scaling the parent changes the spacing": (
        'scale_1d(slat_row, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)\n'
        'change_count(slat_row, amount=2, mode="top_down")', 0.5, [-0.45 + 0.18 * j for j in range(6)]),
    "top_down: scaling the parent changes the count": (
        'scale_1d(slat_row, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)\n'
        'change_delta(slat_row, amount=0, mode="top_down")', 1.0, [-0.6 + 0.2 * j for j in range(7)]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_translation_group_layouts(case, parsel_shape, parsel_backend):
    text, x, expected = CASES[case]
    program = Program.from_text("param x in [0, 1]\n" + text)
    numeric = evaluate(program, parsel_shape, {"x": x})
    assert np.allclose(centres_x(numeric), expected, atol=1e-12), case
    compiled = compile_program(program, parsel_shape, parsel_backend)({"x": x})
    assert np.allclose(centres_x(compiled), expected, atol=1e-9), case
    # every instance is a translated copy of the first member (as edited)
    instances = numeric.instances["slat_row"]
    shapes = instances - instances.mean(axis=1, keepdims=True)
    assert np.allclose(shapes, shapes[0])
    assert np.allclose(instances[:, :, 1:].mean(axis=1), [0.25, 0.0])


def spokes(count=6):
    base = Hexahedron.from_bounds((1, 0, -0.1), (2, 0.2, 0.1))
    parts = [Part(f"spoke{j}", "spoke", Hexahedron(base.corners @ rotation_matrix((0, 1, 0), 2 * math.pi * j
                                                                                         / count).T))
             for j in range(count)]
    relation = RotationSymmetry("ring", tuple(p.id for p in parts), (0, 0, 0), (0, 1, 0), 2 * math.pi / count,
                                tuple(tuple(range(8)) for _ in parts))
    return ShapeGraph(parts, [relation])


def angles(evaluation):
    centres = evaluation.instances["ring"].mean(axis=1)
    return np.sort(np.mod(np.round(np.degrees(np.arctan2(-centres[:, 2], centres[:, 0])), 6), 360))


@pytest.mark.parametrize("text, expected", [
    ('change_count(ring, amount=2, mode="bottom_up")', [45 * j for j in range(8)]),
    ('change_count(ring, amount=-2, mode="top_down")', [90 * j for j in range(4)]),
    ('change_delta(ring, amount=0.5, mode="bottom_up")', [0, 90, 180, 270, 0, 90]),
    ('change_delta(ring, amount=1, mode="top_down")', [0, 120, 240]),
])
def test_rotation_group_layouts(text, expected):
    evaluation = evaluate(Program.from_text(text), spokes(), {"x": 0})
    assert np.allclose(angles(evaluation), np.sort(np.mod(expected, 360)), atol=1e-9)
    radii = np.linalg.norm(evaluation.instances["ring"].mean(axis=1)[:, [0, 2]], axis=1)
    assert np.allclose(radii, 1.5)


def test_group_ops_need_a_group(parsel_shape):
    from parsel_core.errors import ProgramFormatError, UnknownPartError

    with pytest.raises(UnknownPartError, match="no symmetry group 'nope'"):
        Program.from_text('change_count(nope, amount=1)').validate(parsel_shape)
    with pytest.raises(ProgramFormatError, match="is a reflection"):
        Program.from_text('change_count(reflect_rails, amount=1)').validate(parsel_shape)
    with pytest.raises(ProgramFormatError, match="mode must be one of"):
        Program.from_text('change_count(slat_row, amount=1, mode="sideways")')


def test_sliding_contact_accepts_corners_of_different_batch_shapes(parsel_shape):
    from parsel_core.report import sliding_error

    relation = parsel_shape.relation("attach_slat_0_rail_back")
    rest = parsel_shape.rest_corners()
    moved = np.stack([rest["slat_0"] + (dx, 0, 0) for dx in (0.0, 0.2, 0.5)])
    corners = {"slat_0": moved, "rail_back": rest["rail_back"][None]}
    errors = sliding_error(relation, corners, "slat_0")
    assert errors.shape == (3,)
    assert errors[0] == pytest.approx(0) and errors[1] == pytest.approx(0)  # slid along the rail's top
    assert errors[2] > 0  # slid off its end (the rail stops at x = 0.425)


def imperfect_row():
    """Three boards one step of 0.5 apart, the middle one 0.01 deeper and 0.02 off its place,
    each resting on a back rail (a point contact at its back edge)."""
    from parsel_core.examples import attachment

    boards = [Part("board0", "shelf", Hexahedron.from_bounds((0, 0.0, 0), (1, 0.1, 1))),
              Part("board1", "shelf", Hexahedron.from_bounds((0, 0.52, 0), (1, 0.62, 1.01))),
              Part("board2", "shelf", Hexahedron.from_bounds((0, 1.0, 0), (1, 1.1, 1)))]
    rail = Part("rail", "frame", Hexahedron.from_bounds((0, -0.1, -0.1), (1, 1.2, 0)))
    row = TranslationSymmetry("row", ("board0", "board1", "board2"), (0.0, 0.52, 0.0),
                              tuple(tuple(range(8)) for _ in range(3)))
    contacts = [attachment(f"on_rail_{b.id}", b, rail) for b in boards]
    return ShapeGraph([*boards, rail], [row, *contacts])


def test_a_re_laid_out_member_keeps_its_own_deviation_from_the_perfect_row():
    from parsel_core.layout import translation_deviations

    shape = imperfect_row()
    rest = shape.rest_corners()
    deviations = translation_deviations([rest[m] for m in ("board0", "board1", "board2")])
    assert np.allclose(deviations[0], 0)
    # the step (0, 0.52, 0.005) is read off board1's centre, so board1 deviates by its extra
    # depth only and board2 by its place: 0.04 below and 0.01 behind two steps
    assert np.allclose(deviations[1].mean(axis=0), 0) and np.allclose(np.abs(deviations[1][:, 2]), 0.005)
    assert np.allclose(deviations[2], [0, -0.04, -0.01])
    # adding two boards at the end: the three members are where they were, the new ones at the step
    program = Program.from_text('param x in [0, 1]\nchange_count(row, amount=2*x, mode="bottom_up")')
    laid = evaluate(program, shape, {"x": 1.0}).instances["row"]
    assert len(laid) == 5
    for j, member in enumerate(("board0", "board1", "board2")):
        assert np.allclose(laid[j], rest[member], atol=1e-12)
    step = np.array([0, 0.52, 0.005])
    assert np.allclose(laid[3], rest["board0"] + 3 * step) and np.allclose(laid[4], rest["board0"] + 4 * step)


def test_members_a_layout_leaves_in_place_keep_their_contacts():
    from parsel_core.report import check_program

    shape = imperfect_row()
    program = Program.from_text('param x in [0, 1]\nchange_count(row, amount=2*x, mode="bottom_up")')
    states = check_program(shape, program).states()
    assert all(states[f"on_rail_board{j}"] == "kept" for j in range(3)), states


LAYOUT_PROGRAMS = [
    'scale_1d(slat_row, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)\n'
    'change_count(slat_row, amount=4 * x, mode="top_down")',
    'scale_1d(slat_row, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)\n'
    'change_delta(slat_row, amount=x - 0.5, mode="top_down")',
    'change_count(slat_row, amount=3 * x, mode="bottom_up")',
    'change_delta(slat_row, amount=x, mode="bottom_up")',
]


@pytest.mark.parametrize("text", LAYOUT_PROGRAMS)
def test_a_layout_from_the_rest_layout_made_once_is_the_same_to_the_last_bit(text, parsel_shape):
    """Evaluations lay a group out with its rest layout made once (every sample of a batch,
    every slider step): the instances are those made from scratch, bit for bit."""
    from parsel_core.layout import group_instances, rest_layout
    from parsel_core.ops import GroupOp
    from parsel_core.program import op_amount

    program = Program.from_text("param x in [0, 1]\n" + text)
    rest = parsel_shape.rest_corners()
    relation = parsel_shape.relations["slat_row"]
    members = [rest[m] for m in relation.members]
    made = rest_layout(relation, rest["slat_row"], members, "top_down" in text)
    assert (made.anchor_weights is not None) == ("top_down" in text)
    for array in (made.anchor_weights, made.rest_step, made.deviations):
        assert array is None or not array.flags.writeable
    for x in np.linspace(0.0, 1.0, 7):
        parent = evaluate(program, parsel_shape, {"x": x}).parts["slat_row"]  # (no op moves a member)
        ops = [(op, float(op_amount(op, {"x": x}))) for op in program.ops if isinstance(op, GroupOp)]
        args = (relation, rest["slat_row"], members, parent, members, ops)
        assert np.array_equal(group_instances(*args, made), group_instances(*args))
        assert np.array_equal(evaluate(program, parsel_shape, {"x": x}).instances["slat_row"], group_instances(*args))


def test_a_ring_laid_out_top_down_from_its_rest_layout_is_the_same_to_the_last_bit():
    from parsel_core.layout import group_instances, rest_layout

    shape = spokes()
    rest = shape.rest_corners()
    relation = shape.relations["ring"]
    members = [rest[m] for m in relation.members]
    made = rest_layout(relation, rest["ring"], members, True)
    assert made.anchor_weights.shape == (1, 8) and made.deviations is None
    program = Program.from_text('param x in [0, 1]\nscale_3d(ring, origin=(0, 0, 0), amount=x)\n'
                                'change_count(ring, amount=-2, mode="top_down")')
    for x in (0.0, 0.3, 1.0):
        parent = evaluate(program, shape, {"x": x}).parts["ring"]
        args = (relation, rest["ring"], members, parent, members, [(program.ops[1], -2.0)])
        assert np.array_equal(group_instances(*args, made), group_instances(*args))
        assert np.array_equal(evaluate(program, shape, {"x": x}).instances["ring"], group_instances(*args))


@pytest.mark.parametrize("text", LAYOUT_PROGRAMS)
def test_a_compiled_program_lays_out_every_slider_step_afresh(text, parsel_shape, parsel_backend):
    """A compiled program keeps its groups' rest layouts between calls and nothing else:
    each step's instances are those of a program compiled for that step alone, and the
    corners it returns are read-only (the rest shape's own arrays stay untouched)."""
    program = Program.from_text("param x in [0, 1]\n" + text)
    compiled = compile_program(program, parsel_shape, parsel_backend)
    for x in (0.9, 0.1, 0.55, 0.0, 1.0, 0.1):
        step = compiled({"x": x})
        fresh = compile_program(program, parsel_shape, parsel_backend)({"x": x})
        assert np.array_equal(step.instances["slat_row"], fresh.instances["slat_row"])
        assert step.removed == fresh.removed
        for pid, corners in step.parts.items():
            assert np.array_equal(corners, fresh.parts[pid], equal_nan=True)
            assert not corners.flags.writeable or pid in parsel_shape.relations["slat_row"].members
    assert all(not c.flags.writeable for c in parsel_shape.rest_corners().values())
    batch = compiled({"x": np.array([0.1, 0.9])})
    for j, x in enumerate((0.1, 0.9)):
        for pid, corners in batch.parts.items():
            assert np.array_equal(corners[j], compiled({"x": x}).parts[pid], equal_nan=True)
