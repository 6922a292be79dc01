"""Majority voting over samples (paper 6.2.1: five samples lift reliability markedly).

Only valid samples vote; a sample whose reply was rejected is counted apart. Ties go to
the answer that appeared first (lowest sample index), so a vote is deterministic.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any


@dataclass
class Vote:
    """The outcome of one task's vote."""

    winner: Any = None
    winner_key: str | None = None
    counts: dict[str, int] = field(default_factory=dict)
    valid: int = 0
    total: int = 0

    @property
    def decided(self) -> bool:
        return self.winner_key is not None

    def to_dict(self) -> dict[str, Any]:
        return {"winner": self.winner_key, "counts": self.counts, "valid": self.valid, "total": self.total}


def majority(values: Sequence[tuple[bool, Any]], key: Callable[[Any], str]) -> Vote:
    """``values``: per sample in order, (valid, parsed value). The most frequent valid value wins."""
    vote = Vote(total=len(values))
    first: dict[str, int] = {}
    by_key: dict[str, Any] = {}
    counter: Counter[str] = Counter()
    for index, (ok, value) in enumerate(values):
        if not ok:
            continue
        k = key(value)
        counter[k] += 1
        first.setdefault(k, index)
        by_key.setdefault(k, value)
    vote.valid = sum(counter.values())
    vote.counts = dict(counter)
    if counter:
        best = max(counter, key=lambda k: (counter[k], -first[k]))
        vote.winner_key, vote.winner = best, by_key[best]
    return vote


def majority_per_key(values: Sequence[tuple[bool, dict[str, str]]]) -> tuple[dict[str, str], dict[str, Any]]:
    """Type hints voted part by part: a part gets a hint when most valid samples give it that hint.

    A sample that gives a part no hint votes "no hint" for it, so one sample alone cannot
    impose a hint the others left out.
    """
    valid = [value for ok, value in values if ok]
    parts = sorted({p for value in valid for p in value})
    out: dict[str, str] = {}
    detail: dict[str, Any] = {}
    for part in parts:
        choices = [value.get(part, "") for value in valid]
        counter = Counter(choices)
        first = {c: choices.index(c) for c in counter}
        best = max(counter, key=lambda c: (counter[c], -first[c]))
        detail[part] = dict(counter)
        if best:
            out[part] = best
    return out, detail
