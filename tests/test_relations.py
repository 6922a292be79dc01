"""Constraints vanish on a hand-built symmetric, attached shape and not after a breaking edit."""

import numpy as np
import pytest

from parsel_core import Program, compile_program, evaluate
from parsel_core.program import Parameter, symbolic_corners
from parsel_core.relations import Attachment, ReflectionSymmetry, RotationSymmetry, relation_from_dict

TOL = 1e-9


def test_every_relation_holds_at_rest(parsel_shape):
    corners = parsel_shape.rest_corners()
    kinds = {r.kind for r in parsel_shape.relations.values()}
    assert kinds == {"reflection", "translation", "attachment", "ground"}
    for relation in parsel_shape.relations.values():
        assert relation.error(corners) < TOL, relation.id


def test_attachment_kinds_follow_point_counts(parsel_shape):
    contacts = {r.id: r.contact for r in parsel_shape.relations.values() if isinstance(r, Attachment)}
    assert contacts["attach_top_leg_bl"] == "point"
    assert contacts["attach_slat_0_rail_back"] == "line"


def test_hand_computed_attachment_point(parsel_shape):
    relation = parsel_shape.relation("attach_top_leg_br")
    # the leg's top face centre touches the top's underside at (0.45, 0.7, -0.25)
    assert np.allclose(relation.points(parsel_shape.rest_corners()), [[0.45, 0.7, -0.25]])


def breaking_program():
    return Program.from_text("param x in [0, 0.5]\ntranslate(leg_br, dir=(1, 0, 0), amount=x)\n")


def test_breaking_edit_breaks_exactly_the_relations_it_should(parsel_shape):
    corners = evaluate(breaking_program(), parsel_shape, {"x": 0.3}).parts
    broken = {rid for rid, r in parsel_shape.relations.items() if r.error(corners) > TOL}
    assert broken == {"reflect_legs_back", "reflect_legs_right", "attach_top_leg_br", "attach_rail_back_leg_br"}
    assert parsel_shape.relation("reflect_legs_back").error(corners) == pytest.approx(0.3)
    # sliding along the floor keeps ground contact
    assert parsel_shape.relation("ground_leg_br").error(corners) < TOL


def test_mirrored_repair_restores_symmetry_and_translation_keeps_ground(parsel_shape):
    program = Program.from_text(
        "param x in [0, 0.5]\n"
        "translate(leg_br, dir=(1, 0, 0), amount=x)\n"
        "translate(leg_bl, dir=(-1, 0, 0), amount=x)\n")
    corners = evaluate(program, parsel_shape, {"x": 0.2}).parts
    assert parsel_shape.relation("reflect_legs_back").error(corners) < TOL
    assert parsel_shape.relation("reflect_legs_right").error(corners) > TOL


def test_symbolic_residuals_are_the_numeric_ones(parsel_shape, parsel_backend):
    program = breaking_program()
    corners = symbolic_corners(program, parsel_shape, parsel_backend)
    relation = parsel_shape.relation("reflect_legs_back")
    residual = relation.residual(corners)
    assert residual.dtype == object
    x = parsel_backend.symbol("x")
    assert any(x in getattr(r, "free_symbols", set()) for r in residual)
    for value in (0.0, 0.1, 0.4):
        numeric = [parsel_backend.to_float(parsel_backend.subs(r, {"x": value})) for r in residual]
        expected = relation.residual(evaluate(program, parsel_shape, {"x": value}).parts)
        assert np.allclose(numeric, expected, atol=1e-12)


def test_kept_relations_are_zero_over_the_whole_range(parsel_shape, parsel_backend):
    from parsel_core.examples import WIDEN_TINY_TABLE

    program = Program.from_text(WIDEN_TINY_TABLE)
    compiled = compile_program(program, parsel_shape, parsel_backend)
    corners = compiled({"x": np.linspace(0, 0.5, 51)}).parts
    for relation in parsel_shape.relations.values():
        assert np.all(relation.error(corners) < TOL), relation.id


def test_rotation_symmetry_constraint():
    from parsel_core import Hexahedron, Part, ShapeGraph
    from parsel_core.relations import rotation_matrix

    base = Hexahedron.from_bounds((1, 0, -0.1), (2, 0.2, 0.1))
    parts = []
    for j in range(5):
        r = rotation_matrix((0, 1, 0), 2 * np.pi * j / 5)
        parts.append(Part(f"spoke{j}", "spoke", Hexahedron(base.corners @ r.T)))
    relation = RotationSymmetry("spokes", tuple(p.id for p in parts), (0, 0, 0), (0, 1, 0), 2 * np.pi / 5,
                                tuple(tuple(range(8)) for _ in parts))
    shape = ShapeGraph(parts, [relation])
    assert relation.closed
    assert relation.error(shape.rest_corners()) < TOL
    program = Program.from_text("translate(spoke2, dir=(0, 1, 0), amount=x)")
    assert relation.error(evaluate(program, shape, {"x": 0.5}).parts) == pytest.approx(0.5)
    lifted = Program.from_text("translate(spokes, dir=(0, 1, 0), amount=x)")  # the virtual parent
    assert relation.error(evaluate(lifted, shape, {"x": 0.5}).parts) < TOL


def test_relations_round_trip_through_json(parsel_shape):
    for relation in parsel_shape.relations.values():
        assert relation_from_dict(relation.to_dict()) == relation
    with pytest.raises(ValueError, match="unknown relation kind"):
        relation_from_dict({"id": "r", "kind": "glue", "members": ["a"]})


def test_reflection_correspondence_is_a_mirror_permutation(parsel_shape):
    relation = parsel_shape.relation("reflect_legs_back")
    assert isinstance(relation, ReflectionSymmetry)
    assert relation.correspondence == tuple(k ^ 4 for k in range(8))


def test_shape_graph_structure(parsel_shape):
    graph = parsel_shape
    assert "slat_row" in graph.virtual_parents
    parent = graph.part("slat_row")
    assert parent.virtual
    lo, hi = parent.hexahedron.corners.min(axis=0), parent.hexahedron.corners.max(axis=0)
    assert np.allclose(lo, (-0.33, 0.24, -0.26)) and np.allclose(hi, (0.33, 0.26, 0.26))
    assert graph.neighbours("slat_0") == ["rail_back", "rail_front", "slat_row"]
    assert graph.groups_of("slat_2") == ["slat_row"]
    assert {r.id for r in graph.relations_of("leg_bl")} >= {"ground_leg_bl", "attach_top_leg_bl"}
    again = type(graph).from_dict(graph.to_dict())
    assert again.to_dict() == graph.to_dict()


def test_parameter_samples_cover_both_ends():
    samples = Parameter("x", 0, 0.5).samples(10)
    assert samples[0] == 0 and samples[1] == 0.5 and np.all((samples >= 0) & (samples <= 0.5))
