"""The language layer's core: shape descriptions, templates, the reply API, replay, votes, cache, modes."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest

from parsel_core import hookimpl
from parsel_core.errors import ParselError, UnknownPluginError
from parsel_core.examples import tiny_table
from parsel_core.interfaces import Completion, LLMProvider
from parsel_core.language import (
    InferenceError,
    ReplyError,
    build_tasks,
    describe_shape,
    infer,
    parse_hints,
    parse_one_shot,
    parse_seed_reply,
    parse_validity,
    read_description,
)
from parsel_core.language import replay as replay_module
from parsel_core.language.api import extract_code
from parsel_core.language.templates import SECTIONS, TEMPLATE_FIELDS, default_templates, get_template, render
from parsel_core.language.voting import majority, majority_per_key

SEED = """The top gets wider: stretch it along x about its centre.

```python
top = part("top")
scale_1d(top, origin=top.center(), dir="x", amount=x)
```
"""
OTHER_SEED = """```python
leg = part("leg_bl")
scale_1d(leg, origin=leg.face("bottom"), dir="y", amount=x)
```"""


@pytest.fixture(scope="module")
def table():
    return tiny_table()


# -- shape descriptions ---------------------------------------------------------------------


def test_description_names_every_part_and_relation_and_reads_back(table):
    text = describe_shape(table)
    assert text == describe_shape(table), "descriptions are deterministic"
    for pid in table.parts:
        assert f"- {pid}: " in text
    for rid in table.relations:
        assert f"- {rid}: " in text
    summary = read_description("prompt before\n" + text + "\nprompt after")
    assert set(summary.parts) == set(table.parts)
    assert {rid: (r.kind, frozenset(r.members)) for rid, r in summary.relations.items()} == {
        rid: (r.kind, frozenset(r.members)) for rid, r in table.relations.items()}
    leg = summary.parts["leg_fl"]
    assert leg.position == "front-left" and leg.size == (0.05, 0.7, 0.05) and leg.centre == (-0.45, 0.35, 0.25)
    assert summary.relations["reflect_legs_back"].normal_axis == 0
    assert "slat_row: translation symmetry: slat_0, slat_1, slat_2, slat_3 repeat in a row" in text


def test_description_words_positions_by_label(table):
    summary = read_description(describe_shape(table))
    assert [summary.parts[f"slat_{i}"].position for i in range(4)] == ["left", "left-center", "right-center",
                                                                       "right"]
    assert summary.parts["top"].position == ""
    assert summary.parts["rail_front"].position == "front"


def test_description_reads_the_last_shape_block(table):
    other = describe_shape(table).replace('name="tiny_table"', 'name="example"')
    summary = read_description(other + "\n\n" + describe_shape(table))
    assert summary.name == "tiny_table"
    with pytest.raises(ParselError, match="no <shape>"):
        read_description("no shape here")


# -- templates ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(TEMPLATE_FIELDS))
def test_templates_have_the_six_sections_in_order(name):
    text = get_template(name)
    positions = [text.find(f"## {section}\n") for section in SECTIONS]
    assert all(p >= 0 for p in positions), f"{name} lacks a section"
    assert positions == sorted(positions)
    assert "Reminder:" in text.split("## Guidelines")[1], "guidelines end with a task reminder"
    examples = text.split("## Examples")[1].split("## Shape and request")[0]
    assert examples.count("Example ") >= 2 and "Reasoning:" in examples, "in-context examples with reasoning"
    for field in TEMPLATE_FIELDS[name]:
        assert "{{" + field + "}}" in text


def test_templates_are_registered_through_the_hook(parsel_register):
    from parsel_core.language import templates
    from parsel_core.plugins import get_plugin_manager, prompt_templates

    if not get_plugin_manager().is_registered(templates):
        parsel_register(templates)
    registered = prompt_templates()
    for name, path in default_templates().items():
        assert registered[name] == path.read_text(encoding="utf-8")


def test_a_plugin_overrides_one_template(parsel_register, table):
    class Custom:
        @hookimpl
        def parsel_prompt_templates(self):
            return {"seed_edit": "CUSTOM\n{{shape}}\n{{request}}\n"}

    parsel_register(Custom())
    tasks = build_tasks(table, "make it wider", "full")
    assert tasks[0].prompt.startswith("CUSTOM\n<shape ")
    assert tasks[1].prompt.startswith("## Overview"), "the other templates stay"


def test_a_template_with_an_unknown_placeholder_fails_loudly(parsel_register):
    class Broken:
        @hookimpl
        def parsel_prompt_templates(self):
            return {"type_hints": "{{shape}} {{request}} {{colour}}"}

    parsel_register(Broken())
    with pytest.raises(ParselError, match="needs colour"):
        render("type_hints", shape="s", request="r")


def test_tasks_per_mode(table):
    full = build_tasks(table, "make the table wider", "full")
    symmetric = [r for r in table.relations.values() if r.kind in ("reflection", "translation", "rotation")]
    assert [t.name for t in full[:2]] == ["seed_edit", "type_hints"]
    assert len(full) == 2 + len(symmetric)
    assert {t.subject for t in full[2:]} == {r.id for r in symmetric}
    assert full[-1].key == "group_validity:slat_row" and '<relation id="slat_row">' in full[-1].prompt
    assert [t.name for t in build_tasks(table, "r", "seed-only")] == ["seed_edit"]
    assert [t.name for t in build_tasks(table, "r", "one_shot")] == ["one_shot"]
    with pytest.raises(ParselError, match="unknown mode"):
        build_tasks(table, "r", "two-shot")


# -- the reply API ---------------------------------------------------------------------------


ACCEPTED = [
    (SEED, [("scale_1d", "top", None, {"origin": (0.0, 0.725, 0.0), "dir": (1.0, 0.0, 0.0)})]),
    ('scale_1d(part("top"), origin=part("top").face("bottom"), dir="up", amount="0.5 * x")',
     [("scale_1d", "top", None, {"origin": (0.0, 0.7, 0.0), "dir": (0.0, 1.0, 0.0)})]),
    ('leg = part("leg_fr")\nscale_2d(leg.face("bottom"), origin=leg.face("bottom"), normal="y", amount=-0.5 * x)',
     [("scale_2d", "leg_fr", "v-", {"origin": (0.45, 0.0, 0.25), "normal": (0.0, 1.0, 0.0)})]),
    ('leg = part("leg_fl")\nrotate(leg, origin=leg.edge("top", "left"), axis=-leg.axis("w"), amount=pi / 4 * x)',
     [("rotate", "leg_fl", None, {"origin": (-0.475, 0.7, 0.25), "axis": (0.0, 0.0, -1.0)})]),
    ('translate(part("slat_row"), dir=(0, 0, 2), amount=x)  # the whole row',
     [("translate", "slat_row", None, {"dir": (0.0, 0.0, 1.0)})]),
    ('change_count(group("slat_row"), amount=4 * x, mode="top_down")',
     [("change_count", "slat_row", None, {"mode": "top_down"})]),
    ('scale_3d(part("top"), amount=x)', [("scale_3d", "top", None, {"origin": (0.0, 0.725, 0.0)})]),
    ('keep_fixed(part("rail_back"))\ntranslate(part("top"), dir="up", amount=x)',
     [("keep_fixed", "rail_back", None, {}), ("translate", "top", None, {"dir": (0.0, 1.0, 0.0)})]),
    ('translate(part("top").corner("top", "front", "right"), dir="front", amount=0.1 * x)',
     [("translate", "top", "u+v+w+", {"dir": (0.0, 0.0, 1.0)})]),
]


@pytest.mark.parametrize("reply, expected", ACCEPTED, ids=[str(i) for i in range(len(ACCEPTED))])
def test_the_reply_api_builds_ops(table, reply, expected):
    ops = parse_seed_reply(reply, table).ops
    assert len(ops) == len(expected)
    for op, (name, operand, feature, fields) in zip(ops, expected):
        assert (op.name, op.operand, op.feature) == (name, operand, feature)
        for key, value in fields.items():
            got = getattr(op, key)
            assert got == pytest.approx(value) if isinstance(value, tuple) else got == value, key


REJECTED = [
    ("scale_1d(part('top'), origin=part('top').center(), dir='x', amount=", "malformed code"),
    ("```python\nscale_1d(part('top'),\n", "partial reply"),
    ("```python\n```", "empty code block"),
    ("", "empty reply"),
    ("scale_1d(part('stool'), dir='x', amount=x)", "unknown part 'stool'"),
    ("change_count(group('legs'), amount=x)", "unknown group 'legs'"),
    ("explode(part('top'), amount=x)", "call to 'explode' is outside the API"),
    ("print('hi')", "call to 'print' is outside the API"),
    ("eval('1')", "call to 'eval' is outside the API"),
    ("import os\nscale_1d(part('top'), dir='x', amount=x)", "imports are not allowed"),
    ("from os import system", "imports are not allowed"),
    ("__import__('os').system('true')", "name '__import__' is not allowed"),
    ("part('top').__class__", "attribute access to '__class__' is not allowed"),
    ("t = part('top')\nt.__init__.__globals__", "attribute access to '__init__' is not allowed"),
    ("part('top').__getattribute__('x')", "attribute access to '__getattribute__' is not allowed"),
    ("part('top').explode()", "unknown method .explode()"),
    ("for i in range(3):\n    pass", "For statements are not allowed"),
    ("def f():\n    pass", "FunctionDef statements are not allowed"),
    ("t = [p for p in (1, 2, 3)]", "ListComp is not allowed"),
    ("t = lambda: 0", "Lambda is not allowed"),
    ("part = 3", "cannot assign to the reserved name 'part'"),
    ("_t = part('top')", "names starting with '_' are not allowed"),
    ("scale_1d(part('top'), dir='x', amount=y)", "unknown name(s) y"),
    ("scale_1d(part('top'), dir='x', amount=0.5)", "must depend on 'x'"),
    ("scale_1d(part('top'), dir='x', amount=__import__('os'))", "name '__import__' is not allowed"),
    ("scale_1d(part('top'), dir='x', amount=open('f'))", "call to 'open' is not allowed"),
    ("scale_1d(part('top'), dir='sideways', amount=x)", "unknown direction 'sideways'"),
    ("scale_1d(part('top'), amount=x)", "needs dir="),
    ("scale_1d(part('top'), dir='x')", "needs amount="),
    ("scale_1d(part('top'), dir='x', amount=x, colour='red')", "has no argument 'colour'"),
    ("scale_1d(part('top'), **{'dir': 'x'}, amount=x)", "** arguments are not allowed"),
    ("scale_1d(part('top').face('top', 'bottom'), dir='x', amount=x)", "takes 1 face word(s)"),
    ("scale_1d(part('top').edge('top', 'bottom'), dir='x', amount=x)", "do not name one edge"),
    ("x = part('top')", "reserved name 'x'"),
    ("part('top')[0]", "Subscript is not allowed"),
    ("f'{part}'", "JoinedStr is not allowed"),
    ("t = part('top')", "no edit"),
    ("cannot_edit('no') \nscale_1d(part('top'), dir='x', amount=x)", "both edits and calls cannot_edit"),
]


@pytest.mark.parametrize("reply, reason", REJECTED, ids=[r for _, r in REJECTED])
def test_the_reply_api_rejects_with_a_reason(table, reply, reason):
    with pytest.raises(ReplyError) as info:
        parse_seed_reply(reply, table)
    assert reason in str(info.value)


def test_model_text_is_never_executed(table, tmp_path, monkeypatch):
    import builtins

    def forbidden(*args, **kwargs):
        raise AssertionError("model text reached eval/exec")

    monkeypatch.setattr(builtins, "eval", forbidden)
    monkeypatch.setattr(builtins, "exec", forbidden)
    marker = tmp_path / "executed"
    attempts = [
        f"open({str(marker)!r}, 'w').write('x')",
        f"__import__('pathlib').Path({str(marker)!r}).touch()",
        f"scale_1d(part('top'), dir='x', amount=open({str(marker)!r}, 'w'))",
        f"t = part('top')\nt.center.__globals__['__builtins__']['open']({str(marker)!r}, 'w')",
    ]
    for reply in attempts:
        with pytest.raises(ReplyError):
            parse_seed_reply(reply, table)
    assert not marker.exists()


def test_cannot_edit_is_a_valid_answer(table):
    reply = parse_seed_reply('cannot_edit("the table has no drawers")', table)
    assert reply.cannot == "the table has no drawers" and reply.ops == ()


def test_code_block_extraction():
    assert extract_code("think\n```python\na = 1\n```\nmore\n```\nb = 2\n```\n") == "b = 2\n"
    assert extract_code("a = 1") == "a = 1"
    with pytest.raises(ReplyError, match="partial"):
        extract_code("```python\na = 1")


def test_hints_validity_and_one_shot_replies(table):
    assert parse_hints('```python\nhints = {"leg": "rotate", "top": "keep"}\n```', table) == {
        "leg_bl": "rotate", "leg_br": "rotate", "leg_fl": "rotate", "leg_fr": "rotate", "top": "keep"}
    assert parse_hints("hints = {}", table) == {}
    for reply, reason in [("hints = {'seat': 'scale'}", "unknown part 'seat'"),
                          ("hints = {'top': 'melt'}", "not one of"),
                          ("hints = dict(top='keep')", "dict literal"),
                          ("import os\nhints = {}", "imports are not allowed"),
                          ("hints = {}\nhints2 = {}", "single statement")]:
        with pytest.raises(ReplyError, match=reason):
            parse_hints(reply, table)
    assert parse_validity("I think so.\n```python\nvalid = False\n```") is False
    for reply in ("valid = 'no'", "valid = 0", "valid = True\nvalid = False", "ok = True"):
        with pytest.raises(ReplyError):
            parse_validity(reply)
    program = parse_one_shot("```\nparam x in [0, 1]\nscale_1d(top, origin=(0, 0.7, 0), dir=(1, 0, 0), "
                             "amount=x)\ntranslate(leg_fr, dir=(1, 0, 0), amount=0.45 * x)\n```", table)
    assert [op.operand for op in program.ops] == ["top", "leg_fr"]
    with pytest.raises(ReplyError, match="no part 'seat'"):
        parse_one_shot("translate(seat, dir=(1, 0, 0), amount=x)", table)


# -- voting ----------------------------------------------------------------------------------


def test_majority_ignores_invalid_samples_and_breaks_ties_by_order():
    vote = majority([(False, None), (True, "b"), (True, "a"), (True, "a"), (False, None)], key=str)
    assert (vote.winner, vote.valid, vote.total, vote.counts) == ("a", 3, 5, {"b": 1, "a": 2})
    assert majority([(True, "b"), (True, "a")], key=str).winner == "b"
    assert not majority([(False, None)], key=str).decided


def test_hints_are_voted_part_by_part():
    hints, detail = majority_per_key([(True, {"leg": "rotate", "top": "keep"}), (True, {"leg": "rotate"}),
                                      (True, {"leg": "translate"}), (False, None)])
    assert hints == {"leg": "rotate"}, "a hint one sample of three gives is outvoted by 'no hint'"
    assert detail["top"] == {"keep": 1, "": 2}


# -- replay, voting through infer, records ------------------------------------------------------


def _write_jsonl(path: Path, entries: list[dict]) -> Path:
    path.write_text("".join(json.dumps(e) + "\n" for e in entries), encoding="utf-8")
    return path


def test_replayed_bad_replies_are_rejected_and_the_valid_majority_wins(table, tmp_path, monkeypatch):
    import builtins

    monkeypatch.setattr(builtins, "exec", lambda *a, **k: pytest.fail("exec called"))
    marker = tmp_path / "smuggled"
    replies = [
        "scale_1d(part('top'), origin=part('top').center(), dir='x', amount=",  # malformed
        "```python\ntop = part('top')\nscale_1d(top, origin=top.center(), dir='x'",  # partial
        SEED,
        "```python\nscale_1d(part('seat'), dir='x', amount=x)\n```",  # unknown part
        "```python\nexplode(part('top'), amount=x)\n```",  # unknown call
        f"```python\nimport os\nos.system('touch {marker}')\n```",  # import
        f"```python\npart('top').__class__.__init__.__globals__['open']('{marker}', 'w')\n```",  # dunder
        f"```python\nopen('{marker}', 'w')\n```",  # call outside the API
        OTHER_SEED,
        SEED,
    ]
    path = _write_jsonl(tmp_path / "replies.jsonl",
                        [{"task": "seed_edit", "sample": i, "reply": r} for i, r in enumerate(replies)])
    result = infer(table, "make the table wider", provider="replay", mode="seed-only", samples=len(replies),
                   options={"replay": str(path)})
    [op] = result.seed.ops
    assert (op.name, op.operand, op.dir) == ("scale_1d", "top", (1.0, 0.0, 0.0))
    reasons = [e["rejected"] for e in result.record]
    assert reasons[2] is None and reasons[8] is None and reasons[9] is None
    expected = ["malformed code", "partial reply", "unknown part 'seat'", "call to 'explode' is outside the API",
                "imports are not allowed", "attribute access to '__class__' is not allowed",
                "call to 'open' is outside the API"]
    for got, want in zip([reasons[i] for i in (0, 1, 3, 4, 5, 6, 7)], expected):
        assert want in got
    assert result.votes["seed_edit"]["valid"] == 3 and sorted(result.votes["seed_edit"]["counts"].values()) == [1, 2]
    assert result.accounting["rejected"] == 7
    assert not marker.exists()


def test_no_valid_seed_is_an_error_with_the_reasons_and_record(table, tmp_path):
    path = _write_jsonl(tmp_path / "bad.jsonl", [
        {"task": "seed_edit", "sample": 0, "reply": "import os"},
        {"task": "seed_edit", "sample": 1, "reply": "```python\nscale_1d(part('nope'), dir='x', amount=x)\n```"},
    ])
    with pytest.raises(InferenceError) as info:
        infer(table, "make it wider", provider="replay", mode="seed-only", samples=2, options={"replay": str(path)})
    message = str(info.value)
    assert "no valid seed edit among 2 replies" in message and "imports are not allowed" in message
    assert "unknown part 'nope'" in message and len(info.value.record) == 2


def test_a_missing_replay_entry_is_reported(table, tmp_path):
    path = _write_jsonl(tmp_path / "short.jsonl", [{"task": "seed_edit", "sample": 0, "reply": SEED}])
    result = infer(table, "wider", provider="replay", mode="seed-only", samples=2, options={"replay": str(path)})
    assert result.record[1]["error"] and "no recorded reply for task 'seed_edit' sample 1" in result.record[1]["error"]
    assert result.votes["seed_edit"]["valid"] == 1


def test_full_mode_votes_hints_and_validity_from_replay(table, tmp_path):
    entries = [{"task": "seed_edit", "sample": i, "reply": SEED} for i in range(3)]
    entries += [{"task": "type_hints", "sample": i, "reply": r} for i, r in enumerate(
        ["hints = {'leg': 'rotate'}", "hints = {'leg': 'rotate', 'rail_back': 'keep'}", "hints = {'leg': 42}"])]
    for rid, relation in table.relations.items():
        if relation.kind == "reflection":
            key = f"reflection_validity:{rid}"
            split = rid == "reflect_rails"
            votes = ["valid = False", "valid = False", "valid = True"] if split else ["valid = True"] * 3
        elif relation.kind == "translation":
            key, votes = f"group_validity:{rid}", ["valid = True", "garbage(", "valid = False"]
        else:
            continue
        entries += [{"key": key, "sample": i, "reply": v} for i, v in enumerate(votes)]
    path = _write_jsonl(tmp_path / "full.jsonl", entries)
    result = infer(table, "make the table wider and tilt the legs", provider="replay", samples=3,
                   options={"replay": str(path)})
    assert result.hints == {"leg_bl": "rotate", "leg_br": "rotate", "leg_fl": "rotate", "leg_fr": "rotate"}
    assert result.breaks == ["reflect_rails"], "a tie on slat_row keeps it (the first valid sample said valid)"
    assert result.votes["group_validity:slat_row"]["valid"] == 2


def test_a_record_replays_to_the_same_inference(table, tmp_path):
    from parsel_core.language.replay import load_replies

    first = infer(table, "make the front legs longer", provider="offline", samples=3)
    path = _write_jsonl(tmp_path / "record.jsonl", first.record)
    assert len(load_replies(path)) == len(first.record)
    again = infer(table, "make the front legs longer", provider="replay", samples=3, options={"replay": str(path)})
    assert (again.seed.ops, again.hints, again.breaks) == (first.seed.ops, first.hints, first.breaks)
    assert again.breaks == ["reflect_legs_left", "reflect_legs_right"]


def test_replay_reads_json_forms(table, tmp_path):
    as_dict = tmp_path / "replies.json"
    as_dict.write_text(json.dumps({"seed_edit": [SEED, SEED]}), encoding="utf-8")
    as_record = tmp_path / "record.json"
    as_record.write_text(json.dumps({"record": [{"task": "seed_edit", "sample": 0, "reply": SEED}]}))
    assert infer(table, "w", provider="replay", mode="seed-only", samples=2,
                 options={"replay": str(as_dict)}).seed.ops[0].operand == "top"
    assert infer(table, "w", provider="replay", mode="seed-only", samples=1,
                 options={"replay": str(as_record)}).seed.ops[0].operand == "top"
    broken = tmp_path / "broken.jsonl"
    broken.write_text('{"task": "seed_edit"\n', encoding="utf-8")
    with pytest.raises(InferenceError, match="broken.jsonl:1: not JSON"):
        infer(table, "w", provider="replay", mode="seed-only", samples=1, options={"replay": str(broken)})


def test_replay_module_is_a_plugin(parsel_register, table, tmp_path):
    from parsel_core.plugins import get_plugin_manager, llm_providers

    [provider] = replay_module.parsel_llm_providers()
    assert provider.name == "replay" and isinstance(provider, LLMProvider)
    if not get_plugin_manager().is_registered(replay_module):
        parsel_register(replay_module)
    assert "replay" in llm_providers()


# -- providers, cache, concurrency, modes -------------------------------------------------------


class Scripted(LLMProvider):
    """Answers by task and sample; counts calls; optionally slow."""

    name = "scripted"

    def __init__(self, delay: float = 0.0) -> None:
        self.calls: list[tuple[str, int]] = []
        self.threads: set[str] = set()
        self.delay = delay
        self.lock = threading.Lock()

    def complete(self, prompt, *, task, samples=1, **options):
        with self.lock:
            self.calls.append((options.get("key", task), options.get("sample", 0)))
            self.threads.add(threading.current_thread().name)
        time.sleep(self.delay)
        sample = options.get("sample", 0)
        text = {"seed_edit": SEED, "type_hints": "hints = {}", "one_shot": "translate(top, dir=(0, 1, 0), amount=x)"
                }.get(task, "valid = True")
        return [Completion(text + f"\n# sample {sample}", prompt_tokens=100, completion_tokens=10, cost=0.001)]


def _register(parsel_register, provider):
    class Plugin:
        @hookimpl
        def parsel_llm_providers(self):
            return [provider]

    parsel_register(Plugin())
    return provider


def test_response_cache_keyed_by_prompt_model_and_sample(parsel_register, table, tmp_path):
    provider = _register(parsel_register, Scripted())
    options = {"cache_dir": str(tmp_path / "cache")}
    first = infer(table, "make the table wider", provider="scripted", model="m1", samples=3, options=options)
    calls = len(provider.calls)
    assert first.accounting["calls"] == calls and first.accounting["cache_hits"] == 0
    assert first.accounting["cost"] == pytest.approx(0.001 * calls)
    assert first.accounting["prompt_tokens"] == 100 * calls
    again = infer(table, "make the table wider", provider="scripted", model="m1", samples=3, options=options)
    assert len(provider.calls) == calls, "every reply came from the cache"
    assert again.accounting["cache_hits"] == calls and again.accounting["calls"] == 0 and again.accounting["cost"] == 0
    assert [e["reply"] for e in again.record] == [e["reply"] for e in first.record]
    infer(table, "make the table wider", provider="scripted", model="m2", samples=3, options=options)
    assert len(provider.calls) == 2 * calls, "another model misses the cache"
    infer(table, "make the table wider", provider="scripted", model="m1", samples=4, options=options)
    assert len(provider.calls) == 2 * calls + calls // 3, "only the new sample index misses"


def test_no_cache_unless_asked(parsel_register, table):
    provider = _register(parsel_register, Scripted())
    infer(table, "wider", provider="scripted", mode="seed-only", samples=2)
    infer(table, "wider", provider="scripted", mode="seed-only", samples=2)
    assert len(provider.calls) == 4


def test_prompts_are_issued_concurrently(parsel_register, table):
    provider = _register(parsel_register, Scripted(delay=0.2))
    started = time.perf_counter()
    result = infer(table, "make the table wider", provider="scripted", samples=5)
    elapsed = time.perf_counter() - started
    assert len(provider.calls) == 5 * len(build_tasks(table, "x", "full")) == 40
    assert elapsed < 0.2 * 40 / 4, f"{elapsed:.2f}s: calls did not overlap"
    assert len(provider.threads) > 1
    assert sorted(provider.calls) == sorted((t.key, s) for t in build_tasks(table, "x", "full") for s in range(5))
    assert [(e["key"], e["sample"]) for e in result.record] == [
        (t.key, s) for t in build_tasks(table, "x", "full") for s in range(5)], "the record is in task order"


def test_replies_are_read_in_the_calling_thread(parsel_register, table, monkeypatch):
    """Calls run on worker threads; their code is parsed on the calling one: CPython 3.11's
    ``ast`` keeps its recursion depth in module state, and replies parsed by several
    threads at once can fail with "AST constructor recursion depth mismatch"."""
    from parsel_core.language import api

    provider = _register(parsel_register, Scripted(delay=0.05))
    parsed_on = set()
    parse = api.parse_code

    def recorded(code):
        parsed_on.add(threading.current_thread().name)
        return parse(code)

    monkeypatch.setattr(api, "parse_code", recorded)
    result = infer(table, "make the table wider", provider="scripted", samples=3)
    assert len(provider.threads) > 1
    assert parsed_on == {threading.current_thread().name}
    assert all(e["parsed"] is not None and e["seconds"] > 0 and "_unread" not in e for e in result.record)


def test_provider_errors_are_per_sample(parsel_register, table):
    class Flaky(Scripted):
        name = "flaky"

        def complete(self, prompt, *, task, samples=1, **options):
            if options.get("sample") == 1:
                raise RuntimeError("connection reset")
            return super().complete(prompt, task=task, samples=samples, **options)

    _register(parsel_register, Flaky())
    result = infer(table, "wider", provider="flaky", mode="seed-only", samples=3)
    assert result.seed.ops[0].operand == "top"
    assert result.record[1]["error"] == "RuntimeError: connection reset"
    assert result.accounting["errors"] == 1


def test_one_shot_mode_returns_the_models_program(parsel_register, table):
    _register(parsel_register, Scripted())
    result = infer(table, "raise the top", provider="scripted", mode="one-shot", samples=2)
    assert result.program is not None and [op.name for op in result.program.ops] == ["translate"]
    assert result.seed.ops == result.program.ops and result.hints == {} and result.breaks == []


def test_one_shot_with_the_offline_provider(table):
    result = infer(table, "make the legs longer", mode="one-shot", samples=2)
    [op] = result.program.ops
    assert (op.name, op.operand, op.dir) == ("scale_1d", "leg_bl", (0.0, 1.0, 0.0))


def test_bad_arguments(table):
    with pytest.raises(UnknownPluginError, match="unknown LLM provider 'nobody'"):
        infer(table, "wider", provider="nobody")
    with pytest.raises(ParselError, match="samples must be"):
        infer(table, "wider", samples=0)
    with pytest.raises(ParselError, match="request is empty"):
        infer(table, "  ")
    with pytest.raises(ParselError, match="unknown mode"):
        infer(table, "wider", mode="zero-shot")


def test_inference_summary_is_json(table):
    result = infer(table, "make the table wider", samples=2)
    summary = json.loads(json.dumps(result.summary()))
    assert summary["seed"][0]["op"] == "scale_1d" and summary["mode"] == "full"
    json.dumps(result.record)


# -- applications ---------------------------------------------------------------------------


def test_proxydural_and_variation_requests_are_readable_requests():
    from parsel_core.language import proxydural_requests, variation_requests

    table = tiny_table()
    proposal = proxydural_requests(table, count=4)
    assert 1 <= len(proposal.requests) <= 4 and proposal.record[0]["task"] == "proxydural"
    variants = variation_requests(table, "make the table wider", count=3).requests
    assert variants and all(v.startswith("make the table wider") for v in variants)
    for request in proposal.requests + variants:
        infer(table, request, samples=1)  # each is a request the pipeline understands


def test_a_seed_that_edits_a_group_in_two_modes_is_rejected(table):
    from parsel_core.language.engine import _parser
    from parsel_core.plugins import edit_operators

    reply = ('change_count(group("slat_row"), amount=x, mode="top_down")\n'
             'change_delta(group("slat_row"), amount=x, mode="bottom_up")')
    with pytest.raises(ReplyError, match="both top_down and bottom_up"):
        _parser("seed_edit", table, edit_operators())(reply)
