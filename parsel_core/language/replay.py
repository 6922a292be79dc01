"""The replay provider: answers from a recorded file, for tests and for re-running experiments.

The file is JSON Lines (one entry per line) or JSON (a list of entries, an object with a
``record`` list, or an object mapping a task key to a list of replies). An entry is
``{"task": "seed_edit", "sample": 0, "reply": "..."}``; validity tasks carry their
relation in ``"key": "reflection_validity:reflection_2"``. The ``record`` that
:func:`parsel_core.language.infer` returns has exactly this shape, so a run's record
replays it. A reply the file lacks is an error naming the task and sample: replay never
makes anything up.

Entries that carry their prompt (``prompt`` or ``prompt_sha256``, as every record entry
does) are also keyed by it: replaying a record for another request, another shape or
another template is an error that names both requests, never the recorded answer to a
different question. Hand-written entries without a prompt answer any prompt.
"""

from __future__ import annotations

import hashlib
import json
import threading
from pathlib import Path
from typing import Any, NamedTuple

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.interfaces import Completion, LLMProvider


def _entries(data: Any, source: str) -> list[dict[str, Any]]:
    if isinstance(data, dict) and "record" in data:
        data = data["record"]
    if isinstance(data, dict):
        out = []
        for key, replies in data.items():
            if isinstance(replies, str):
                replies = [replies]
            if not isinstance(replies, list):
                raise ParselError(f"{source}: replies for {key!r} must be a list of strings")
            out.extend({"key": key, "sample": i, "reply": r} for i, r in enumerate(replies))
        return out
    if not isinstance(data, list):
        raise ParselError(f"{source}: expected a list of replies")
    return data


class ReplayMismatch(ParselError):
    """The file answers a different prompt: replaying it would answer another question."""

    stops_run = True


class Recorded(NamedTuple):
    """A recorded reply, with the SHA-256 of the prompt it answered (None when not recorded)
    and that prompt's request."""

    reply: str
    prompt_sha256: str | None = None
    request: str | None = None


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def load_replies(path: str | Path) -> dict[tuple[str, int], Recorded]:
    """(task key, sample index) -> the recorded reply."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ParselError(f"{path}: cannot read replay file: {exc.strerror}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None
    if data is not None:
        entries = [data] if isinstance(data, dict) and "reply" in data else _entries(data, str(path))
    else:
        entries = []
        for number, line in enumerate(text.splitlines(), start=1):
            if not line.strip():
                continue
            try:
                entries.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ParselError(f"{path}:{number}: not JSON or JSON Lines: {exc.msg}") from None
    replies: dict[tuple[str, int], Recorded] = {}
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise ParselError(f"{path}: entry {i} is not an object")
        if entry.get("reply") is None:
            continue  # a recorded provider error has no reply to replay
        key = entry.get("key") or entry.get("task")
        if not isinstance(key, str) or not isinstance(entry.get("reply"), str):
            raise ParselError(f"{path}: entry {i} needs \"task\" (or \"key\") and \"reply\" strings")
        try:
            sample = int(entry.get("sample", 0))
        except (TypeError, ValueError):
            raise ParselError(f"{path}: entry {i} has a bad sample index {entry.get('sample')!r}") from None
        prompt = entry.get("prompt")
        digest = entry.get("prompt_sha256")
        if isinstance(prompt, str):
            digest = _sha256(prompt)
        elif not isinstance(digest, str):
            digest = None
        request = _request(prompt) if isinstance(prompt, str) else None
        replies[(key, sample)] = Recorded(entry["reply"], digest, request)
    return replies


def _request(prompt: str) -> str | None:
    from parsel_core.language.describe import read_request

    try:
        return read_request(prompt)
    except ParselError:
        return None


class ReplayProvider(LLMProvider):
    """Replies looked up by task key and sample index in the file given as ``replay=``."""

    name = "replay"
    #: Replaying is already free and exact; caching it would only hide the file's content.
    cacheable = False

    def __init__(self) -> None:
        self._files: dict[tuple[str, float], dict[tuple[str, int], Recorded]] = {}
        self._lock = threading.Lock()

    def _replies(self, path: str) -> dict[tuple[str, int], Recorded]:
        p = Path(path)
        try:
            stamp = (str(p.resolve()), p.stat().st_mtime)
        except OSError as exc:
            raise ParselError(f"{path}: cannot read replay file: {exc.strerror}") from None
        with self._lock:
            if stamp not in self._files:
                self._files[stamp] = load_replies(p)
            return self._files[stamp]

    def complete(self, prompt: str, *, task: str, samples: int = 1, **options: Any) -> list[Completion]:
        path = options.get("replay")
        if not path:
            raise ParselError("the replay provider needs a file (--replay FILE)")
        replies = self._replies(str(path))
        key = options.get("key") or task
        start = int(options.get("sample", 0))
        out = []
        for sample in range(start, start + samples):
            reply = replies.get((key, sample))
            if reply is None:
                reply = replies.get((task, sample)) if key != task else None
            if reply is None:
                raise ParselError(f"{path}: no recorded reply for task {key!r} sample {sample}")
            if reply.prompt_sha256 is not None and reply.prompt_sha256 != _sha256(prompt):
                asked = _request(prompt)
                what = (f"request {reply.request!r}, not {asked!r}" if reply.request and asked
                        and reply.request != asked else "a different prompt (shape, request or template)")
                raise ReplayMismatch(f"{path}: the reply recorded for task {key!r} sample {sample} answers {what}")
            out.append(Completion(reply.reply, meta={"replayed": True}))
        return out


@hookimpl
def parsel_llm_providers():
    return [ReplayProvider()]
