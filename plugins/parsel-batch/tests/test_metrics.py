"""The metrics of reference section 7 on hand-made program pairs with values worked out by hand."""

import numpy as np
import pytest

from parsel_batch.metrics import (
    all_match,
    control_values,
    corner_distance,
    edited_parts,
    geometric_distance,
    hint_jaccard,
    instance_distance,
    jaccard,
    language_metrics,
    program_jaccard,
    program_metrics,
    relation_agreement,
    seed_accuracy,
    signature,
    signatures,
    structural_agreement,
    summarise,
    validity_accuracy,
    validity_universe,
)
from parsel_core.examples import WIDEN_TINY_TABLE, tiny_table
from parsel_core.program import Program

LEGS = ("leg_bl", "leg_br", "leg_fl", "leg_fr")
DEMO_PROGRAM = WIDEN_TINY_TABLE  # widen the table by hand: every relation kept
RAISE_TOP = "translate(top, dir=(0, 1, 0), amount=x)"
# The top goes up by x; each leg stretches from the floor to meet it (its top is at 0.7).
RAISE_TOP_STRETCH_LEGS = RAISE_TOP + "\n" + "\n".join(
    f"scale_1d({leg}, origin=(0, 0, 0), dir=(0, 1, 0), amount=x / 0.7)" for leg in LEGS)


def program(text: str) -> Program:
    return Program.from_text(text)


@pytest.fixture(scope="module")
def shape():
    return tiny_table()


# -- identical programs ---------------------------------------------------------------------


@pytest.mark.parametrize("text", [DEMO_PROGRAM, RAISE_TOP, RAISE_TOP_STRETCH_LEGS])
def test_identical_programs_score_perfectly(shape, text):
    metrics = program_metrics(shape, program(text), program(text))
    assert metrics.j_prog == 1.0
    assert metrics.d_geo == 0.0
    assert metrics.rel.fraction == 1.0 and metrics.rel.percent == 100.0
    assert metrics.rel.considered > 0


def test_identical_language_outputs_match(shape):
    seed = program("scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)")
    result = language_metrics(shape, seed, {"leg_bl": "translate"}, ["reflect_rails"], program(DEMO_PROGRAM),
                              {"leg_bl": "translate"}, ["reflect_rails"])
    assert result.to_dict() == {"acc_se": True, "acc_r": 1.0, "J_T": 1.0, "match": True}


# -- J(prog) --------------------------------------------------------------------------------


def test_signature_is_type_and_operand_only():
    a, b = program("translate(face(top, 'v+'), dir=(0, 1, 0), amount=x)\ntranslate(top, dir=(1, 0, 0), amount=2*x)").ops
    assert signature(a) == signature(b) == "translate(top)"
    assert signatures(program(DEMO_PROGRAM)) >= {"scale_1d(top)", "translate(leg_br)", "scale_1d(rail_back)"}


def test_program_jaccard_hand_computed():
    truth = program("scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n"
                    "translate(leg_bl, dir=(-1, 0, 0), amount=0.45*x)\ntranslate(leg_br, dir=(1, 0, 0), amount=0.45*x)")
    inferred = program("scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n"
                       "translate(leg_bl, dir=(-1, 0, 0), amount=0.4*x)\n"
                       "translate(leg_bl, dir=(0, 1, 0), amount=0.1*x)\n"  # a repeated signature counts once
                       "scale_1d(leg_br, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)")
    # {scale_1d(top), translate(leg_bl)} shared; union adds translate(leg_br), scale_1d(leg_br)
    assert program_jaccard(inferred, truth) == pytest.approx(2 / 4)
    assert program_jaccard(program(RAISE_TOP), program(RAISE_TOP_STRETCH_LEGS)) == pytest.approx(1 / 5)
    assert jaccard(set(), set()) == 1.0 and jaccard({"a"}, set()) == 0.0


# -- D(geo) ---------------------------------------------------------------------------------


def test_geometric_distance_translation_hand_computed(shape):
    # the top is 0.35 higher in one program: 8 corners, 0.35 each
    assert geometric_distance(shape, program(RAISE_TOP), program("keep_fixed(top)")) == pytest.approx(8 * 0.35)
    moved = program(RAISE_TOP + "\ntranslate(leg_bl, dir=(1, 0, 0), amount=2*x)")
    assert geometric_distance(shape, moved, program(RAISE_TOP)) == pytest.approx(8 * 0.7)


def test_geometric_distance_scaling_and_stretching_hand_computed(shape):
    widen = program("scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)")
    # corners at x = +-0.5 move to +-0.5 * 1.35: 0.175 each
    assert geometric_distance(shape, widen, program("keep_fixed(top)")) == pytest.approx(8 * 0.175)
    # each leg's 4 upper corners are 0.35 higher in the stretched program, the lower 4 stay
    assert geometric_distance(shape, program(RAISE_TOP), program(RAISE_TOP_STRETCH_LEGS)) == pytest.approx(
        4 * 4 * 0.35)


def test_control_parameter_is_clamped_into_each_programs_range(shape):
    short = program("param x in [0, 0.2]\n" + RAISE_TOP)
    assert control_values(short) == {"x": 0.2}
    assert control_values(program("param x in [0.5, 1]\n" + RAISE_TOP)) == {"x": 0.5}
    assert control_values(program(RAISE_TOP)) == {"x": 0.35}
    # inferred evaluated at 0.2, ground truth at 0.35: the top is 0.15 apart
    assert geometric_distance(shape, short, program(RAISE_TOP)) == pytest.approx(8 * 0.15)


def test_layouts_with_different_counts_match_by_index_then_nearest():
    cube = np.array([[(k >> 0) & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)], dtype=float)

    def at(t):
        return cube + (t, 0, 0)

    assert corner_distance(at(0), at(0.1)) == pytest.approx(0.8)
    # index 0 equal, index 1 0.1 apart, the extra instance at 2 is nearest to the one at 1
    assert instance_distance([at(0), at(1)], [at(0), at(1.1), at(2)]) == pytest.approx(0.8 + 8.0)
    assert instance_distance([at(0), at(1.1), at(2)], [at(0), at(1)]) == pytest.approx(0.8 + 8.0)


def test_geometric_distance_with_a_group_layout_is_symmetric_and_zero_on_itself(shape):
    truth = program(DEMO_PROGRAM)
    relaid = program("scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)\n"
                     "scale_1d(slat_row, origin=(0, 0.25, 0), dir=(1, 0, 0), amount=x)\n"
                     "change_count(slat_row, mode='top_down', amount=3*x)")
    d = geometric_distance(shape, relaid, truth)
    assert d > 0 and np.isfinite(d)
    assert d == pytest.approx(geometric_distance(shape, truth, relaid))
    assert geometric_distance(shape, relaid, relaid) == 0.0


# -- %Rel -----------------------------------------------------------------------------------


def test_relation_agreement_on_states_hand_computed():
    members = {"r1": ("a", "b"), "r2": ("b", "c"), "r3": ("c", "d"), "r4": ("d",)}
    inferred = {"r1": "kept", "r2": "broken", "r3": "kept", "r4": "kept"}
    truth = {"r1": "kept", "r2": "kept", "r3": "broken", "r4": "broken"}
    result = relation_agreement(inferred, truth, members, {"b"})
    assert (result.agreeing, result.considered, result.fraction) == (1, 2, 0.5)
    assert result.disagreeing == ("r2",)
    # broken and broken on purpose are both "broken"
    assert relation_agreement({"r4": "broken_on_purpose"}, {"r4": "broken"}, {"r4": ("d",)}, {"d"}).fraction == 1.0
    # nothing edited: nothing to disagree on
    assert relation_agreement(inferred, truth, members, set()).fraction == 1.0


def test_structural_agreement_hand_computed(shape):
    # Edited parts: the top and the four legs. Relations touching them: 4 leg reflections
    # (kept in both), 4 grounds (kept in both), 4 top-leg attachments (broken when only
    # the top moves, kept when the legs stretch) and 4 rail-leg attachments (kept when
    # the legs stay, broken when they stretch past the rails' contacts): 8 of 16 agree.
    result = structural_agreement(shape, program(RAISE_TOP), program(RAISE_TOP_STRETCH_LEGS))
    assert (result.agreeing, result.considered) == (8, 16)
    assert result.percent == pytest.approx(50.0)
    assert set(result.disagreeing) == {f"attach_top_{leg}" for leg in LEGS} | {
        "attach_rail_back_leg_bl", "attach_rail_back_leg_br", "attach_rail_front_leg_fl", "attach_rail_front_leg_fr"}


def test_edited_parts_expand_groups_and_skip_keep_fixed(shape):
    text = "keep_fixed(top)\ntranslate(leg_bl, dir=(1, 0, 0), amount=x)\nchange_count(slat_row, amount=x)"
    assert edited_parts(shape, program(text)) == {"leg_bl", "slat_0", "slat_1", "slat_2", "slat_3"}


# -- language-model accuracy ----------------------------------------------------------------


def test_seed_accuracy():
    truth = program(DEMO_PROGRAM)
    assert seed_accuracy(program("scale_1d(top, origin=(0, 0, 0), dir=(0, 0, 1), amount=2*x)"), truth)
    assert not seed_accuracy(program(RAISE_TOP), truth)  # translate(top) is not in the demo program
    assert not seed_accuracy(program(RAISE_TOP + "\nscale_1d(top, amount=x)"), truth)  # every op must be
    assert not seed_accuracy([], truth)


def test_validity_accuracy_and_universe(shape):
    universe = validity_universe(shape)
    assert universe == sorted(["reflect_legs_back", "reflect_legs_front", "reflect_legs_left", "reflect_legs_right",
                               "reflect_rails", "slat_row"])
    assert validity_accuracy(["reflect_rails"], [], universe) == pytest.approx(5 / 6)
    assert validity_accuracy(["reflect_rails"], ["reflect_rails"], universe) == 1.0
    # a relation outside the universe that one side breaks is asked about too
    assert validity_accuracy(["attach_top_leg_bl"], [], universe) == pytest.approx(6 / 7)
    assert validity_accuracy([], [], []) == 1.0


def test_hint_jaccard_and_match():
    assert hint_jaccard({"leg_bl": "translate", "leg_br": "scale"},
                        {"leg_bl": "translate", "leg_br": "translate"}) == pytest.approx(1 / 3)
    assert hint_jaccard({}, {}) == 1.0
    assert hint_jaccard({"leg_bl": "translate"}, {}) == 0.0
    assert all_match(True, 1.0, 1.0)
    assert not all_match(False, 1.0, 1.0)
    assert not all_match(True, 5 / 6, 1.0)
    assert not all_match(True, 1.0, 0.5)


def test_summarise_means_over_defined_values():
    summary = summarise([{"J_prog": 1.0, "D_geo": 0.0, "match": True}, {"J_prog": 0.5, "D_geo": 2.0, "match": False},
                         {"J_prog": None}, None])
    assert summary["J_prog"] == {"mean": 0.75, "cases": 2}
    assert summary["D_geo"] == {"mean": 1.0, "cases": 2}
    assert summary["match"] == {"mean": 0.5, "cases": 2}
    assert summary["acc_r"] == {"mean": None, "cases": 0}
