"""The offline provider: a deterministic rule-based stand-in for a language model.

It is the default provider, so ``parsel edit SHAPE "request"`` works without network or
keys. It answers each prompt in the reply format a model would use (reasoning, then a
code block), reading the shape and the request from the prompt itself, so the same
parsing and voting path runs as for a hosted model. Requests it cannot read get a
``cannot_edit("...")`` answer that says why, never a guess.
"""

from __future__ import annotations

import importlib
import re
from functools import lru_cache
from typing import Any

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.interfaces import Completion, LLMProvider

__all__ = ["Interpretation", "Interpreter", "NotUnderstood", "OfflineProvider", "answer", "interpret"]


def __getattr__(name: str) -> Any:
    """The interpreter's names, imported on first use (registering the plugin stays cheap)."""
    if name not in ("Interpretation", "Interpreter", "NotUnderstood", "interpret"):
        raise AttributeError(f"module 'parsel_offline' has no attribute {name!r}")
    return getattr(importlib.import_module("parsel_offline.interpreter"), name)
TASKS = ("seed_edit", "type_hints", "reflection_validity", "group_validity", "one_shot", "proxydural", "variations")


@lru_cache(maxsize=64)
def _summary(block: str):
    from parsel_core.language.describe import read_description

    return read_description(block)


@lru_cache(maxsize=256)
def _reading(block: str, request: str):
    """The interpreter's reading of a request, or why it has none."""
    from parsel_offline.interpreter import NotUnderstood, interpret

    try:
        return interpret(_summary(block), request)
    except NotUnderstood as exc:
        return str(exc)


def _shape_block(prompt: str) -> str:
    start = prompt.rfind("<shape ")
    end = prompt.find("</shape>", start)
    if start < 0 or end < 0:
        raise ParselError("the offline provider needs a prompt with a <shape> description")
    return prompt[start:end + len("</shape>")]


def answer(prompt: str, task: str) -> str:
    """The reply to one prompt of ``task``."""
    from parsel_core.language.describe import read_relation_id, read_request
    from parsel_offline.writer import (
        cannot_reply,
        hints_reply,
        one_shot_reply,
        proxydural_requests,
        requests_reply,
        seed_reply,
        validity_reply,
        variation_requests,
    )

    if task not in TASKS:
        raise ParselError(f"the offline provider does not know task {task!r} (known: {', '.join(TASKS)})")
    block = _shape_block(prompt)
    shape = _summary(block)
    if task == "proxydural":
        match = re.search(r"Write (\d+) edit requests", prompt)
        requests = proxydural_requests(shape, int(match.group(1)) if match else 5)
        return requests_reply(requests, "These are common, independent ways such an object varies.")
    request = read_request(prompt)
    if task == "variations":
        match = re.search(r"Write (\d+) variants", prompt)
        variants = variation_requests(shape, request, int(match.group(1)) if match else 3)
        return requests_reply(variants, "Each variant keeps the request and adds one way the other parts follow.")
    reading = _reading(block, request)
    if isinstance(reading, str):
        return cannot_reply(task, reading)
    if task == "seed_edit":
        return seed_reply(reading)
    if task == "type_hints":
        return hints_reply(reading)
    if task == "one_shot":
        return one_shot_reply(reading, shape)
    return validity_reply(reading, read_relation_id(prompt))


class OfflineProvider(LLMProvider):
    """Rule-based answers; every sample is the same (the interpreter is deterministic)."""

    name = "offline"
    #: Answers cost nothing and never change for a prompt; caching them would only use disk.
    cacheable = False

    def complete(self, prompt: str, *, task: str, samples: int = 1, **options: Any) -> list[Completion]:
        text = answer(prompt, task)
        return [Completion(text, meta={"offline": True}) for _ in range(samples)]


@hookimpl
def parsel_llm_providers():
    return [OfflineProvider()]
