"""Programs: JSON and text forms round-trip; backends agree; parameters are range-checked."""

import json

import numpy as np
import pytest

from parsel_core import Program, compile_program, evaluate
from parsel_core.errors import ParameterRangeError, ProgramFormatError, UnknownPartError
from parsel_core.plugins import cas_backend_names, get_cas_backend

FIVE_OPS = """\
# five ops of every flavour, two parameters
param x in [0, 0.5] default 0.25
param y in [-0.2, 0.3]
scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)
translate(face(leg_br, "v-"), dir=(1, 0, 0), amount=0.45 * x + y)   # a taper
rotate(rail_back, origin=(0, 0.22, -0.25), axis=(1, 0, 0), amount=sin(x) * y)
shear("slat_0", origin=(0, 0.25, 0), normal=(0, 1, 0), dir=(0, 0, 1), amount=x**2)
scale_2d(edge(slat_1, "u+v+"), origin=(0.1, 0.26, 0), normal=(0, 1, 0), amount=-y / 3)
change_count(slat_row, amount=4 * x, mode="top_down")
"""


def test_text_round_trip_evaluates_identically(parsel_shape):
    program = Program.from_text(FIVE_OPS)
    again = Program.from_text(program.to_text())
    assert again == program
    values = {"x": 0.37, "y": -0.1}
    a, b = evaluate(program, parsel_shape, values), evaluate(again, parsel_shape, values)
    for pid in a.parts:
        assert np.array_equal(a.parts[pid], b.parts[pid])
    assert np.array_equal(a.instances["slat_row"], b.instances["slat_row"])


def test_json_round_trip_is_exact(parsel_shape):
    program = Program.from_text(FIVE_OPS)
    text = program.to_json()
    again = Program.from_json(text)
    assert again == program and again.to_json() == text
    data = json.loads(text)
    assert data["format"] == "parsel.program" and data["version"] == 1
    assert data["ops"][1] == {"op": "translate", "operand": "leg_br", "feature": "v-", "amount": "0.45 * x + y",
                              "dir": [1.0, 0.0, 0.0]}
    values = {"x": 0.1, "y": 0.3}
    a, b = evaluate(program, parsel_shape, values), evaluate(again, parsel_shape, values)
    assert all(np.array_equal(a.parts[p], b.parts[p]) for p in a.parts)


def test_text_to_json_to_text_keeps_odd_floats():
    program = Program.from_text("param x in [0, 0.3333333333333333] default 0.1\n"
                                "translate(a, dir=(0.1, 0.2, 0.30000000000000004), amount=x / 7)\n")
    assert Program.from_json(program.to_json()).to_text() == program.to_text()


def test_backends_agree_with_each_other_and_with_numpy(parsel_shape):
    program = Program.from_text(FIVE_OPS)
    rng = np.random.default_rng(7)
    values = {"x": rng.uniform(0, 0.5, 20), "y": rng.uniform(-0.2, 0.3, 20)}
    reference = evaluate(program, parsel_shape, values).parts
    assert len(cas_backend_names()) >= 2
    results = {name: compile_program(program, parsel_shape, get_cas_backend(name))(values).parts
               for name in cas_backend_names()}
    for name, parts in results.items():
        for pid in reference:
            assert np.allclose(parts[pid], reference[pid], atol=1e-9, rtol=0), (name, pid)
    first, second = list(results.values())[:2]
    assert max(np.abs(first[p] - second[p]).max() for p in reference) < 1e-9


def test_parameters_are_range_checked(parsel_shape):
    program = Program.from_text(FIVE_OPS)
    with pytest.raises(ParameterRangeError, match=r"'x'.*0.9.*\[0, 0.5\]"):
        evaluate(program, parsel_shape, {"x": 0.9})
    with pytest.raises(ParameterRangeError):
        compile_program(program, parsel_shape, get_cas_backend("sympy"))({"y": np.array([0.0, 1.0])})
    with pytest.raises(Exception, match="no parameter"):
        evaluate(program, parsel_shape, {"z": 0.1})


@pytest.mark.parametrize("value, ok", [
    (0.25, True), (0.0, True), (0.5, True), (0.5 + 1e-13, True), (-1e-13, True),
    (0.5 + 1e-9, False), (-1e-9, False), (float("nan"), False), (float("inf"), False), (-float("inf"), False),
])
def test_one_value_is_checked_as_a_batch_of_it_is(value, ok):
    """A slider step's float takes a shortcut past the array checks; it accepts and refuses
    what the array checks do, with the same message."""
    from parsel_core.program import Parameter

    parameter = Parameter("x", 0.0, 0.5)
    for given in (value, np.float64(value), np.array([value, 0.1])):
        if ok:
            parameter.check(given)
        else:
            with pytest.raises(ParameterRangeError) as error:
                parameter.check(given)
            assert "parameter 'x'" in str(error.value)
            if np.isfinite(value):
                assert f"value {value:g} is outside its range [0, 0.5]" in str(error.value)


def test_unknown_part_is_named(parsel_shape):
    program = Program.from_text("translate(chair_leg, dir=(1, 0, 0), amount=x)")
    with pytest.raises(UnknownPartError, match="op 0 \\(translate\\).*'chair_leg'"):
        evaluate(program, parsel_shape)


@pytest.mark.parametrize("text, message", [
    ("translate(top, dir=(1, 0, 0), amount=__import__('os'))", "not allowed"),
    ("translate(top, dir=(1, 0, 0), amount=x.real)", "Attribute is not allowed"),
    ("translate(top, dir=(1, 0), amount=x)", "must be 3 numbers"),
    ("translate(top, dir=(0, 0, 0), amount=x)", "non-zero direction"),
    ("explode(top, amount=x)", "unknown op 'explode'"),
    ("translate(top, speed=3, amount=x)", "no field"),
    ("translate(top, dir=(1, 0, 0), amount=z)", "undeclared parameter"),
    ("translate(face(top, 'q+'), dir=(1, 0, 0), amount=x)", "'q\\+' is not an axis"),
    ("translate(top, dir=(1, 0, 0), amount=x", "does not parse"),
    ("param x in [1, 0]", "empty"),
    ("param x from 0 to 1", "expected 'param NAME"),
    ("import os", "does not parse|expected an op call"),
])
def test_malformed_text_is_rejected_with_the_line(text, message):
    with pytest.raises(ProgramFormatError, match=message) as info:
        Program.from_text("# header\n" + text, source="p.txt")
    assert str(info.value).startswith("p.txt:2: ")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(format="other"), "not a parsel program"),
    (lambda d: d.update(version=99), "unsupported program version"),
    (lambda d: d["ops"][0].update(op="nope"), r"ops\[0\]: unknown op"),
    (lambda d: d["ops"][0].update(amount=3), r"amount must be a string"),
    (lambda d: d["ops"][0].pop("operand"), "needs an 'operand'"),
    (lambda d: d["parameters"][0].update(lo="a"), "finite number"),
    (lambda d: d.update(ops={}), "must be a list"),
])
def test_malformed_json_is_rejected_with_the_field(mutate, message):
    data = Program.from_text(FIVE_OPS).to_dict()
    mutate(data)
    with pytest.raises(ProgramFormatError, match=message):
        Program.from_dict(data, source="p.json")
    with pytest.raises(ProgramFormatError, match="invalid JSON at line 1"):
        Program.from_json("{nope", source="p.json")


def test_stacking_refuses_conflicting_parameters():
    a = Program.from_text("param x in [0, 1]\ntranslate(a, dir=(1,0,0), amount=x)")
    b = Program.from_text("param x in [0, 2]\ntranslate(b, dir=(1,0,0), amount=x)")
    with pytest.raises(ProgramFormatError, match="differs"):
        a.then(b)


# -- outer layers: a turn on top of the summed layers, its origin carried along --------------

def _outer_program():
    from parsel_core.program import Follow

    widen = Program.from_text("param x1 in [0, 1]\nscale_1d(seat, origin=(0, 0, 0), dir=(1, 0, 0), amount=x1)")
    turn = Program.from_text("param x2 in [0, 1]\nrotate(seat, origin=(0.21, 0.43, 0), axis=(0, 1, 0), "
                             "amount=pi / 2 * x2)")
    return widen.atop(turn, (Follow("seat", (0.21, 0.43, 0.0), (0,)),))


def test_an_outer_layer_turns_the_widened_part_about_its_carried_hinge():
    from parsel_core.loading import load_shape

    chair = load_shape("chair")
    program = _outer_program()
    rest = chair.rest_corners()["seat"]
    widened = rest * np.array([2.0, 1.0, 1.0])  # x1 = 1 doubles x about the origin
    hinge = np.array([0.42, 0.43, 0.0])  # the hinge (0.21, 0.43, 0) carried by the widening
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # pi/2 about +y
    expected = (widened - hinge) @ turn.T + hinge
    got = evaluate(program, chair, {"x1": 1.0, "x2": 1.0}).parts["seat"]
    np.testing.assert_allclose(got, expected, atol=1e-12)
    np.testing.assert_allclose(evaluate(program, chair, {"x1": 1.0, "x2": 0.0}).parts["seat"], widened, atol=1e-12)
    for name in cas_backend_names():
        compiled = compile_program(program, chair, get_cas_backend(name))
        np.testing.assert_allclose(compiled({"x1": 1.0, "x2": 1.0}).parts["seat"], expected, atol=1e-12)
    values = {"x1": np.array([0.0, 0.3, 1.0]), "x2": np.array([1.0, 0.5, 0.2])}  # batched like the scalar path
    batched = evaluate(program, chair, values).parts["seat"]
    for i in range(3):
        single = evaluate(program, chair, {k: float(v[i]) for k, v in values.items()}).parts["seat"]
        np.testing.assert_allclose(batched[i], single, atol=1e-12)


def test_outer_layers_round_trip_through_json_and_text():
    program = _outer_program()
    assert program.layers == (1, 1) and program.outer == (1,)
    assert Program.from_json(program.to_json()) == program
    text = program.to_text()
    assert "layer on top" in text and "follows=('seat', (0.21, 0.43, 0.0))" in text
    assert Program.from_text(text) == program


@pytest.mark.parametrize("change, message", [
    ({"outer": [2]}, "outer must list layers 0 to 1"),
    ({"outer": "1"}, "field 'outer' must be a list"),
    ({"follows": [{"part": "seat", "point": [0, 0, 0], "ops": [0]}]}, "op 0 is not in an outer layer"),
    ({"follows": [{"part": "seat", "point": [0, 0], "ops": [1]}]}, "follows.point"),
    ({"follows": [{"part": "seat", "ops": [1]}]}, "each entry must be an object with part, point and ops"),
    ({"follows": [{"part": "seat", "point": [0, 0, 1e300], "ops": [1]}]}, "max_magnitude"),
])
def test_bad_outer_layers_are_one_line_errors(change, message):
    data = {**_outer_program().to_dict(), **change}
    with pytest.raises(ProgramFormatError, match=message):
        Program.from_dict(data, source="p.json")


def test_a_follow_of_an_unknown_part_names_it():
    from parsel_core.loading import load_shape
    from parsel_core.program import Follow

    program = _outer_program()
    bad = Program(program.ops, program.parameters, {}, program.layers, program.outer,
                  (Follow("sofa", (0.0, 0.0, 0.0), (1,)),))
    with pytest.raises(UnknownPartError, match="no part 'sofa'"):
        evaluate(bad, load_shape("chair"), {})


def test_symbolic_corners_of_a_few_parts_are_those_of_all_parts(parsel_shape, parsel_backend):
    """``only`` leaves the other parts' ops unapplied and changes nothing for the parts asked
    for: ops on a group's virtual parent, a laid-out group and an outer layer following a
    point of another part."""
    from parsel_core.loading import load_shape
    from parsel_core.program import symbolic_corners

    grouped = Program.from_text(FIVE_OPS + "translate(slat_row, dir=(0, 1, 0), amount=x * y)\n")
    for shape, program in ((parsel_shape, Program.from_text(FIVE_OPS)), (parsel_shape, grouped),
                           (load_shape("chair"), _outer_program())):
        full = symbolic_corners(program, shape, parsel_backend)
        parts = sorted(full)
        for only in [[p] for p in parts] + [parts[:2], parts[-3:]]:
            some = symbolic_corners(program, shape, parsel_backend, only=only)
            assert sorted(some) == sorted(only)
            for pid in only:
                assert [str(v) for v in np.asarray(some[pid]).ravel()] == \
                       [str(v) for v in np.asarray(full[pid]).ravel()], pid
