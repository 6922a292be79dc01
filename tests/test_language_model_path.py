"""The model path's safety: replays keyed by prompt, code blocks, plugin operators in the
prompt, amounts checked over the range, and a failed run that keeps a previous OUTDIR."""

from __future__ import annotations

import json
import math

import pytest

from parsel_core.cli import main
from parsel_core.examples import tiny_table
from parsel_core.language import InferenceError, build_tasks, infer, parse_seed_reply
from parsel_core.language.amounts import amount_values, check_ops
from parsel_core.language.api import ReplyError, code_blocks, radians_to_pi
from parsel_core.ops import Rotate, Translate


@pytest.fixture(scope="module")
def table():
    return tiny_table()


def _write_jsonl(path, entries):
    path.write_text("".join(json.dumps(e) + "\n" for e in entries), encoding="utf-8")
    return path


def test_a_record_replayed_for_another_request_fails_naming_both(table, tmp_path):
    record = infer(table, "make the legs longer", provider="offline", samples=2).record
    path = _write_jsonl(tmp_path / "record.jsonl", record)
    with pytest.raises(InferenceError, match="answers request 'make the legs longer', not 'make the table wider'"):
        infer(table, "make the table wider", provider="replay", samples=2, options={"replay": str(path)})
    # A hash alone (no prompt text) is enough to refuse; a different shape is another prompt too.
    hashed = [{k: v for k, v in e.items() if k != "prompt"} for e in record]
    path = _write_jsonl(tmp_path / "hashed.jsonl", hashed)
    with pytest.raises(InferenceError, match="answers a different prompt"):
        infer(table, "make the table wider", provider="replay", samples=2, options={"replay": str(path)})
    again = infer(table, "make the legs longer", provider="replay", samples=2, options={"replay": str(path)})
    assert [op.operand for op in again.seed.ops] == ["leg_bl"]


def test_the_record_keeps_each_prompts_hash(table):
    import hashlib

    result = infer(table, "make the legs longer", provider="offline", samples=1)
    assert all(e["prompt_sha256"] == hashlib.sha256(e["prompt"].encode()).hexdigest() for e in result.record)


def test_code_blocks_and_the_first_one_that_reads(table):
    reply = "```\nnot code at all\n```\ntext\n```python\ntop = part(\"top\")\n" \
            "scale_1d(top, origin=top.center(), dir=\"x\", amount=x)\n```\n"
    assert len(code_blocks(reply)) == 2
    assert parse_seed_reply(reply, table).ops[0].operand == "top"
    with pytest.raises(ReplyError, match="none of the 2 code blocks is an answer; block 1: malformed code"):
        parse_seed_reply("```\nnot (code\n```\n```\nalso not\n```", table)
    with pytest.raises(ReplyError, match="partial reply"):
        code_blocks("```python\nscale_1d(")


def test_radians_are_rewritten_with_pi():
    assert radians_to_pi("radians(15) * x") == "15 * pi / 180 * x"
    assert amount_values(radians_to_pi("radians(30) * x"), "x", 0, 1, 2)[1] == pytest.approx(math.pi / 6)


def test_amount_checks_over_the_range():
    check_ops([Rotate("top", "2 * pi * x", origin=(0, 0, 0), axis=(0, 1, 0))])  # a full turn is allowed
    with pytest.raises(ReplyError, match="reaches 15 radians"):
        check_ops([Rotate("top", "-15 * x", origin=(0, 0, 0), axis=(0, 1, 0))])
    check_ops([Translate("top", "15 * x", dir=(1, 0, 0))]), "only rotations are angles"
    with pytest.raises(ReplyError, match=r"at x = 0\.5"):
        check_ops([Translate("top", "1 / (x - 0.5)", dir=(1, 0, 0))])
    check_ops([Translate("top", "1 / (x - 0.5)", dir=(1, 0, 0))], lo=0.6, hi=2.0)


def test_plugin_operators_are_listed_in_the_seed_prompt_with_signature_and_docstring(table):
    from parsel_core.plugins import edit_operators

    registry = edit_operators()
    assert "twist" in registry, "the example plugin is installed in the development environment"
    [seed] = build_tasks(table, "twist the legs", "seed-only")
    assert "`twist(target, origin=..., axis=..., amount=...)` (from a plugin): Rotate points about axis" in seed.prompt
    assert "`axis` is a direction; `origin` is a point" in seed.prompt
    without = {k: v for k, v in registry.items() if k != "twist"}
    [plain] = build_tasks(table, "twist the legs", "seed-only", registry=without)
    assert "twist(" not in plain.prompt and "scale_1d(target" in plain.prompt


def test_a_model_may_answer_with_a_plugin_operator(table, tmp_path):
    reply = "```python\nleg = part(\"leg_bl\")\ntwist(leg, origin=leg.face(\"bottom\"), axis=\"y\", amount=x)\n```"
    path = tmp_path / "replies.json"
    path.write_text(json.dumps({"seed_edit": [reply]}), encoding="utf-8")
    result = infer(table, "twist the legs", provider="replay", mode="seed-only", samples=1,
                   options={"replay": str(path)})
    assert [op.name for op in result.seed.ops] == ["twist"]


def test_a_failed_run_keeps_the_previous_outdir(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["edit", "tiny_table", "make the legs longer", "-o", str(out), "--samples", "1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert "program.json" in before
    capsys.readouterr()
    assert main(["edit", "tiny_table", "paint the legs red", "-o", str(out), "--samples", "1"]) == 2
    err = capsys.readouterr().err
    assert f"{out} is kept as it was; the record of this run is in {out}.failed-record.jsonl" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    record = [json.loads(line) for line in (tmp_path / "out.failed-record.jsonl").read_text().splitlines()]
    assert "paint the legs red" in record[0]["prompt"]
    fresh = tmp_path / "fresh"
    assert main(["edit", "tiny_table", "paint the legs red", "-o", str(fresh), "--samples", "1"]) == 2
    assert not fresh.exists()  # a failed run leaves no partial OUTDIR
    assert f"no {fresh} is written; the record of this run is in {fresh}.failed-record.jsonl" in \
        capsys.readouterr().err
