"""An on-disk cache of model replies keyed by (provider, model, prompt, sample index).

Re-running an experiment with the same prompts then costs nothing, while different
samples of one prompt stay different answers (the sample index is part of the key).
Entries are small JSON files written to a temporary name and renamed, so concurrent
writers never leave a half-written entry.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from dataclasses import asdict
from pathlib import Path

from parsel_core.interfaces import Completion


def cache_key(provider: str, model: str | None, prompt: str, sample: int) -> str:
    payload = json.dumps([provider, model or "", prompt, int(sample)], ensure_ascii=False)
    return hashlib.sha256(payload.encode("utf-8")).hexdigest()


class ResponseCache:
    """Replies stored under ``directory/<2 hex>/<key>.json``."""

    def __init__(self, directory: str | os.PathLike) -> None:
        self.directory = Path(directory)

    def _path(self, key: str) -> Path:
        return self.directory / key[:2] / f"{key}.json"

    def get(self, key: str) -> Completion | None:
        path = self._path(key)
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            return Completion(str(data["text"]), int(data.get("prompt_tokens", 0)),
                              int(data.get("completion_tokens", 0)), float(data.get("cost", 0.0)),
                              dict(data.get("meta") or {}))
        except (OSError, ValueError, KeyError, TypeError):
            return None  # a missing or unreadable entry is a miss

    def put(self, key: str, completion: Completion) -> None:
        path = self._path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = asdict(completion)
        try:
            text = json.dumps(data, ensure_ascii=False)
        except TypeError:
            data["meta"] = {}
            text = json.dumps(data, ensure_ascii=False)
        fd, tmp = tempfile.mkstemp(prefix=".tmp.", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                handle.write(text)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
