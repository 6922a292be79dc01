"""The case format and single-case runs (expert, recorded and live language-model outputs)."""

import json
import sys

import pytest

from parsel_batch.cases import CaseFormatError, default_id, parse_case, read_cases
from parsel_batch.runner import deterministic, run_case
from parsel_core.program import Program

WIDEN = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"


def write_cases(path, *cases):
    path.write_text("".join(json.dumps(c) + "\n" for c in cases))
    return path


def test_read_cases_resolves_paths_and_defaults(tmp_path):
    (tmp_path / "gt.parsel").write_text(WIDEN + "\n")
    path = write_cases(tmp_path / "cases.jsonl",
                       {"id": "a", "shape": "tiny_table", "seed": WIDEN, "ground_truth": "gt.parsel"},
                       {"shape": "tiny_table", "request": "make the top wider"})
    path.write_text(path.read_text() + "\n# a comment\n")
    a, b = read_cases(path)
    assert a.mode == "expert" and a.expert.seed == WIDEN and a.ground_truth == str(tmp_path / "gt.parsel")
    assert a.shape == "tiny_table"  # an example name, not a file next to the cases
    assert b.mode == "language" and b.expert is None
    assert b.id == default_id({"shape": "tiny_table", "request": "make the top wider"})
    assert b.id.startswith("tiny_table-")
    # recorded outputs make a case a language-model case even with expert inputs
    c = parse_case({"shape": "tiny_table", "seed": WIDEN, "llm": {"seed": WIDEN}})
    assert c.mode == "language" and c.recorded.seed == WIDEN


@pytest.mark.parametrize("line, message", [
    ("{not json", "invalid JSON"),
    (json.dumps({"seed": WIDEN}), "'shape'"),
    (json.dumps({"shape": "tiny_table"}), "needs a 'request'"),
    (json.dumps({"shape": "tiny_table", "mode": "expert", "request": "r"}), "expert mode needs a 'seed'"),
    (json.dumps({"shape": "tiny_table", "seed": WIDEN, "hints": {"top": "wiggle"}}), "unknown type"),
    (json.dumps({"shape": "tiny_table", "seed": WIDEN, "colour": 1}), "unknown field(s) colour"),
    (json.dumps({"shape": "tiny_table", "seed": WIDEN, "id": "../x"}), "id '../x'"),
    (json.dumps({"shape": "tiny_table", "kind": "proxydural", "request": "r"}), "reserved"),
])
def test_bad_cases_are_one_line_errors_naming_the_line(tmp_path, line, message):
    path = tmp_path / "cases.jsonl"
    path.write_text(json.dumps({"id": "ok", "shape": "tiny_table", "seed": WIDEN}) + "\n" + line + "\n")
    with pytest.raises(CaseFormatError, match=rf"cases.jsonl:2: .*{message}".replace("(", r"\(").replace(")", r"\)")):
        read_cases(path)


def test_duplicate_ids_are_refused(tmp_path):
    path = write_cases(tmp_path / "cases.jsonl", {"id": "a", "shape": "tiny_table", "seed": WIDEN},
                       {"id": "a", "shape": "tiny_table", "seed": WIDEN})
    with pytest.raises(CaseFormatError, match="also on line 1"):
        read_cases(path)


def test_expert_case_runs_deterministically_and_scores_against_ground_truth(tmp_path):
    case = parse_case({"id": "w", "shape": "tiny_table", "seed": WIDEN, "ground_truth": {
        "format": "parsel.program", "version": 1, "parameters": [{"name": "x", "lo": 0, "hi": 1}],
        "ops": [{"op": "scale_1d", "operand": "top", "amount": "x", "origin": [0, 0.725, 0], "dir": [1, 0, 0]}]}})
    first, second = run_case(case), run_case(case)
    assert first.ok, first.record["error"]
    assert first.files == second.files
    assert deterministic(first.record) == deterministic(second.record)
    program = Program.from_json(first.files["program.json"])
    assert program.metadata["case"] == "w"
    assert Program.from_text(program.metadata["seed"]).ops == Program.from_text(WIDEN).ops
    report = json.loads(first.files["report.json"])
    assert report["counts"]["broken"] == 0 and "time_s" not in report["stats"]
    metrics = first.record["metrics"]
    # the propagated program has 9 ops on 9 operands, the ground truth only the seed's
    assert metrics["J_prog"] == pytest.approx(1 / 9)
    assert metrics["D_geo"] > 0 and 0 <= metrics["rel"] < 1
    assert metrics["acc_se"] is None  # no language-model outputs in an expert case


def test_failures_are_records_not_exceptions():
    outcome = run_case(parse_case({"id": "bad", "shape": "tiny_table", "seed": "translate(nope, amount=x)"}))
    assert not outcome.ok
    assert outcome.record["error"]["type"] == "UnknownPartError"
    assert "nope" in outcome.record["error"]["message"]
    assert outcome.record["error"]["traceback"] and "Traceback" in outcome.files["error.txt"]
    missing = run_case(parse_case({"id": "gone", "shape": "no/such/shape.json", "seed": WIDEN}))
    assert not missing.ok and "no such file" in missing.record["error"]["message"]


def test_recorded_language_outputs_are_scored_against_the_expert_inputs():
    case = parse_case({"id": "llm", "shape": "tiny_table", "request": "make the table wider", "seed": WIDEN,
                       "breaks": ["reflect_rails"],
                       "llm": {"seed": WIDEN, "hints": {"leg_bl": "translate"}}})
    outcome = run_case(case)
    assert outcome.ok, outcome.record["error"]
    metrics = outcome.record["metrics"]
    assert metrics["acc_se"] is True
    assert metrics["acc_r"] == pytest.approx(5 / 6)  # reflect_rails: expert breaks it, the model does not
    assert metrics["J_T"] == 0.0 and metrics["match"] is False
    assert outcome.record["inferred"]["hints"] == {"leg_bl": "translate"}
    assert metrics["J_prog"] is None  # no ground-truth program


def test_language_mode_without_the_language_layer_is_a_clear_case_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "parsel_core.language", None)
    outcome = run_case(parse_case({"id": "lang", "shape": "tiny_table", "request": "make the top wider"}))
    assert not outcome.ok
    assert "language mode needs parsel_core.language" in outcome.record["error"]["message"]


def test_language_mode_uses_the_language_layer(monkeypatch):
    import types

    calls = []

    def infer(shape, request, **kwargs):
        calls.append((shape.name, request, kwargs))
        # a stand-in for parsel_core.language.Inference: what parsel_core.api.edit reads of it
        return types.SimpleNamespace(seed=Program.from_text(WIDEN), hints={}, breaks=[], program=None,
                                     mode="full", votes={}, accounting={"calls": 1}, record=[],
                                     summary=lambda: {"mode": "full"})

    monkeypatch.setitem(sys.modules, "parsel_core.language", types.SimpleNamespace(infer=infer))
    outcome = run_case(parse_case({"id": "lang", "shape": "tiny_table", "request": "make the top wider",
                                   "seed": WIDEN, "mode": "language", "language": {"samples": 3}}))
    assert outcome.ok, outcome.record["error"]
    assert calls[0][:2] == ("tiny_table", "make the top wider") and calls[0][2]["samples"] == 3
    assert outcome.record["metrics"]["match"] is True
    assert outcome.record["accounting"] == {"calls": 1}
    assert "accounting" not in deterministic(outcome.record)
