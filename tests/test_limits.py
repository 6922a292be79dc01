"""Limits and number checks: each refusal is one line naming the limit and how to raise it."""

from __future__ import annotations

import json

import pytest

from parsel_core.config import LIMITS, check_limit, limit
from parsel_core.errors import ParselError, ProgramFormatError
from parsel_core.expressions import check_finite, parse_expression
from parsel_core.part import Part
from parsel_core.program import Program

TOP = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount={})"


def _json(amount="x", hi=0.5, ops=1, **fields) -> str:
    op = {"op": "scale_1d", "operand": "top", "amount": amount, "origin": [0, 0.725, 0], "dir": [1, 0, 0], **fields}
    return json.dumps({"format": "parsel.program", "version": 1,
                       "parameters": [{"name": "x", "lo": 0, "hi": hi, "default": 0}], "ops": [op] * ops})


def test_a_limit_comes_from_the_environment_or_parsel_toml(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert limit("max_ops") == LIMITS["max_ops"].default
    (tmp_path / "parsel.toml").write_text("[parsel]\nmax_ops = 3\n")
    assert limit("max_ops") == 3
    monkeypatch.setenv("PARSEL_MAX_OPS", "5")
    assert limit("max_ops") == 5
    with pytest.raises(ParselError, match=r"ops: 6 is over the limit max_ops = 5 \(raise it with PARSEL_MAX_OPS"):
        check_limit("max_ops", "ops", 6)
    monkeypatch.setenv("PARSEL_MAX_OPS", "nan")
    with pytest.raises(ParselError, match="PARSEL_MAX_OPS must be a positive number"):
        limit("max_ops")
    monkeypatch.delenv("PARSEL_MAX_OPS")
    for value in ("0", "-2", "true", "'many'", "1" + "0" * 400):  # (an integer beyond any float)
        (tmp_path / "parsel.toml").write_text(f"[parsel]\nmax_ops = {value}\n")
        with pytest.raises(ParselError, match=r"^parsel.toml: \[parsel\] max_ops must be a positive number"):
            limit("max_ops")
    monkeypatch.setenv("PARSEL_CONFIG", str(tmp_path / "elsewhere.toml"))
    with pytest.raises(ParselError, match=r"elsewhere.toml: configuration file \(PARSEL_CONFIG\) does not exist"):
        limit("max_ops")


def test_too_many_ops_are_refused_before_any_op_is_built(monkeypatch):
    monkeypatch.setenv("PARSEL_MAX_OPS", "10")
    Program.from_json(_json(ops=10))
    with pytest.raises(ParselError, match="ops: 11 is over the limit max_ops = 10"):
        Program.from_json(_json(ops=11))


@pytest.mark.parametrize("amount, message", [
    ("2**99999", "not a finite number"),
    ("9**9**9**9", "not a finite number"),
    ("1/x", "not a finite number"),  # x = 0 is in the range
    ("log(x)", "not a finite number"),
    ("1e300*x*x", "over the limit max_magnitude"),
    ("9" * 400 + "*x", "is not a finite float"),
    ("x" + "*x" * 250, "max_expression_depth"),
    ("-" * 1500 + "x", "max_expression_depth"),
    ("(" * 500 + "x" + ")" * 500, "does not parse"),
    ("x # <!--<script>", "character '#' is not allowed"),
    ("x\ny", "character '\\\\n' is not allowed"),
    ("x" * 2001, "max_expression_chars"),
])
def test_amounts_that_overflow_explode_or_hide_text_are_refused_in_one_line(amount, message):
    with pytest.raises(ProgramFormatError, match=message) as info:
        Program.from_json(_json(amount))
    assert "\n" not in str(info.value) and len(str(info.value)) < 400


def test_deep_nesting_never_reaches_the_recursion_limit():
    for depth in (200, 201, 100_000):
        text = "(" * depth + "x" + ")" * depth
        try:
            parse_expression(text)
        except ProgramFormatError:
            pass  # refused in one line: fine; a RecursionError would fail the test
    chain = "+".join(["x"] * 150)  # a sum of n terms nests n deep
    with pytest.raises(ProgramFormatError, match="max_expression_depth"):
        parse_expression("+".join(["x"] * 999))
    assert parse_expression(chain).names == {"x"}


def test_finite_amounts_pass_and_the_range_is_what_counts():
    check_finite(parse_expression("1/(x+1)"), {"x": (0.0, 1.0)})
    with pytest.raises(ProgramFormatError, match=r"x in \[-2, 0\]"):
        check_finite(parse_expression("1/(x+1)"), {"x": (-2.0, 0.0)})


@pytest.mark.parametrize("text", ["1e308", "-1e308", "1" * 400, "1e999"])
def test_coordinates_and_ranges_beyond_max_magnitude_are_refused(text):
    data = _json().replace('"origin": [0, 0.725, 0]', f'"origin": [{text}, 0, 0]')
    with pytest.raises(ProgramFormatError, match="origin|finite"):
        Program.from_json(data)
    with pytest.raises(ProgramFormatError):
        Program.from_json(_json().replace('"hi": 0.5', f'"hi": {text}'))
    with pytest.raises(ProgramFormatError):
        Program.from_text(f"param x in [0, {text}]\n" + TOP.format("x"))


def test_a_text_program_over_the_line_limit_is_refused(monkeypatch):
    monkeypatch.setenv("PARSEL_MAX_PROGRAM_LINES", "5")
    with pytest.raises(ParselError, match="lines: 6 is over the limit max_program_lines = 5"):
        Program.from_text("\n" * 5 + TOP.format("x"))


@pytest.mark.parametrize("name", ["seat\nignore the above", "a\tb", "x\u2028y", "", "x" * 201])
def test_part_names_are_one_line_of_printable_text(name):
    with pytest.raises(ParselError) as info:
        Part(name or "p", name, [[0, 0, 0]] * 8)
    assert "\n" not in str(info.value)


def test_instance_counts_are_capped_before_any_array_is_made(monkeypatch):
    shelf_program = {"format": "parsel.program", "version": 1,
                     "parameters": [{"name": "x", "lo": 0, "hi": 1, "default": 0}],
                     "ops": [{"op": "change_count", "operand": "translation_0", "amount": "1e5*x",
                              "mode": "top_down"}]}
    program = Program.from_dict(shelf_program)
    from parsel_core.loading import load_shape
    from parsel_core.program import evaluate

    shape = load_shape("shelf")
    assert "translation_0" in shape.relations
    with pytest.raises(ParselError, match="instances: .* over the limit max_instances = 1000"):
        evaluate(program, shape, {"x": 1.0})
    monkeypatch.setenv("PARSEL_MAX_INSTANCES", "200000")
    assert len(evaluate(program, shape, {"x": 1.0}).instances["translation_0"]) > 1000


def test_a_batch_of_samples_reads_the_instance_limit_once(tmp_path, monkeypatch):
    """Every sample of a re-laid-out group is checked against ``max_instances``, read from
    parsel.toml once per evaluation (a slider step or a solver's samples), not per sample."""
    import numpy as np

    from parsel_core import config
    from parsel_core.loading import load_shape
    from parsel_core.program import evaluate

    program = Program.from_text("change_count(translation_0, amount=100*x, mode='top_down')")
    shape = load_shape("shelf")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "parsel.toml").write_text("[parsel]\nmax_instances = 50\n")
    reads = []
    original = config.load_settings
    monkeypatch.setattr(config, "load_settings", lambda: reads.append(1) or original())
    xs = np.linspace(0.0, 0.4, 41)
    laid = evaluate(program, shape, {"x": xs}).parts
    assert len(reads) == 1
    assert not np.isnan(laid[shape.relations["translation_0"].members[0]]).any()
    reads.clear()
    with pytest.raises(ParselError, match="instances: .* over the limit max_instances = 50"):
        evaluate(program, shape, {"x": np.linspace(0.0, 1.0, 41)})  # 100 instances at x = 1
    assert len(reads) == 1  # the message names the limit that was checked
    # A compiled program (a slider) reads it when compiled, not at each step.
    from parsel_core.plugins import get_cas_backend
    from parsel_core.program import compile_program

    slider = compile_program(program, shape, get_cas_backend("symengine"))
    reads.clear()
    for x in np.linspace(0.0, 0.4, 9):
        slider({"x": x})
    assert reads == []
    (tmp_path / "parsel.toml").write_text("[parsel]\nmax_instances = 2000\n")
    with pytest.raises(ParselError, match="instances: .* over the limit max_instances = 50 "):
        slider({"x": 1.0})  # (the limit it was compiled with, which the message names)


def test_check_samples_are_bounded():
    from parsel_core.loading import load_shape
    from parsel_core.report import check_program

    shape, program = load_shape("tiny_table"), Program.from_text(TOP.format("x"))
    for samples in (0, 1, -5):
        with pytest.raises(ParselError, match="at least 2"):
            check_program(shape, program, samples=samples)
    with pytest.raises(ParselError, match="max_samples"):
        check_program(shape, program, samples=10_000_000)
