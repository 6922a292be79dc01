"""The offline provider: word handling, the interpreter's rules, and replies in every task's format."""

from __future__ import annotations

import importlib

import pytest

from parsel_core.errors import ParselError
from parsel_core.examples import tiny_table
from parsel_core.language import build_tasks, describe_shape, parse_hints, parse_seed_reply, parse_validity
from parsel_core.language.describe import read_description
from parsel_core.language.replies import parse_one_shot, parse_requests
from parsel_core.language.templates import render

# Imported by name, so the import block reads the same whether the linter counts the
# plugin as first- or third-party.
offline = importlib.import_module("parsel_offline")
lexicon = importlib.import_module("parsel_offline.lexicon")
NotUnderstood, OfflineProvider, answer, interpret = (offline.NotUnderstood, offline.OfflineProvider, offline.answer,
                                                     offline.interpret)
lemma, singular, tokens = lexicon.lemma, lexicon.singular, lexicon.tokens


@pytest.fixture(scope="module")
def table():
    return tiny_table()


@pytest.fixture(scope="module")
def summary(table):
    return read_description(describe_shape(table))


def test_words():
    assert tokens("Make the table's legs 20% longer, please!") == ["make", "the", "table", "legs", "20%", "longer",
                                                                   ",", "please", ","]
    assert tokens("don't move the top") == ["do", "not", "move", "the", "top"]
    assert [singular(w) for w in ("legs", "shelves", "feet", "boxes", "bodies", "its", "backwards")] == [
        "leg", "shelf", "foot", "box", "body", "its", "backwards"]
    assert [lemma(w) for w in ("tilting", "moved", "spinning", "tapered", "widens", "table")] == [
        "tilt", "move", "spin", "taper", "widen", "table"]


def test_reading_requests(summary):
    reading = interpret(summary, "make the table wider")
    assert [op.signature for op in reading.ops] == [("scale_1d", "top")]
    reading = interpret(summary, "make the front and back legs longer")
    assert [op.signature for op in reading.ops] == [("scale_1d", "leg_bl")]
    assert reading.breaks == [], "front and back together are all the legs"
    reading = interpret(summary, "make the front legs longer")
    assert reading.breaks == ["reflect_legs_left", "reflect_legs_right"]
    reading = interpret(summary, "make the slats wider and keep the rails fixed")
    assert reading.hints == {"rail_back": "keep", "rail_front": "keep"} and reading.hint_keys == {"rail": "keep"}
    reading = interpret(summary, "add two more slats")
    assert [(op.op, op.target, op.amount) for op in reading.ops] == [("change_count", "slat_row", "2 * x")]


def test_independent_clauses_join_the_seed_and_dependent_ones_give_hints(summary):
    reading = interpret(summary, "make the top thicker and taper the legs")
    assert [op.signature for op in reading.ops] == [("scale_1d", "top")]
    assert reading.hints == {p: "scale" for p in ("leg_bl", "leg_br", "leg_fl", "leg_fr")}, "legs hold the top"
    reading = interpret(summary, "raise the rails and make the top thicker")
    assert [op.signature for op in reading.ops] == [("translate", "rail_back"), ("scale_1d", "top")]


@pytest.mark.parametrize("request_text, reason", [
    ("make it sparkle", "'sparkle'"),
    ("make the drawers deeper", "the tiny_table has no drawers"),
    ("make the legs", "no edit I know"),
    ("slide the top", "which way"),
    ("add more legs", "not a repeated row or ring"),
    ("there is no verb here", "'there'"),
    ("", "empty"),
])
def test_it_says_when_it_does_not_understand(summary, request_text, reason):
    with pytest.raises(NotUnderstood, match=reason):
        interpret(summary, request_text)


def _prompt(table, name: str, request: str, index: int = 0) -> str:
    return build_tasks(table, request, "one-shot" if name == "one_shot" else "full")[index].prompt


def test_every_task_is_answered_in_its_reply_format(table):
    request = "make the table wider and tilt the legs"
    tasks = build_tasks(table, request, "full")
    seed = parse_seed_reply(answer(tasks[0].prompt, "seed_edit"), table)
    assert [(op.name, op.operand) for op in seed.ops] == [("scale_1d", "top")]
    assert set(parse_hints(answer(tasks[1].prompt, "type_hints"), table).values()) == {"rotate"}
    for task in tasks[2:]:
        assert parse_validity(answer(task.prompt, task.name)) is True
    program = parse_one_shot(answer(_prompt(table, "one_shot", request), "one_shot"), table)
    assert [op.operand for op in program.ops] == ["top"]
    proxy = render("proxydural", shape=describe_shape(table), count=3)
    assert len(parse_requests(answer(proxy, "proxydural"))) == 3
    variations = render("variations", shape=describe_shape(table), request="<request>make the table wider</request>",
                        count=2)
    assert len(parse_requests(answer(variations, "variations"))) == 2


def test_the_left_rail_relation_breaks_for_the_front_rail(table):
    tasks = build_tasks(table, "make the front rail thicker", "full")
    replies = {t.subject: parse_validity(answer(t.prompt, t.name)) for t in tasks[2:]}
    assert replies["reflect_rails"] is False
    assert all(replies[r] for r in replies if r != "reflect_rails")


def test_not_understood_replies_keep_each_format(table):
    tasks = build_tasks(table, "make it sparkle", "full")
    seed = parse_seed_reply(answer(tasks[0].prompt, "seed_edit"), table)
    assert seed.cannot and "sparkle" in seed.cannot
    assert parse_hints(answer(tasks[1].prompt, "type_hints"), table) == {}
    assert parse_validity(answer(tasks[2].prompt, tasks[2].name)) is True


def test_provider_is_deterministic_and_needs_a_shape(table):
    prompt = _prompt(table, "seed_edit", "make the legs longer")
    replies = OfflineProvider().complete(prompt, task="seed_edit", samples=3)
    assert len({r.text for r in replies}) == 1 and replies[0].cost == 0
    with pytest.raises(ParselError, match="<shape>"):
        answer("no shape", "seed_edit")
    with pytest.raises(ParselError, match="does not know task"):
        answer(prompt, "poetry")
