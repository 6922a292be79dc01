"""Progress on stderr for work that takes more than a couple of seconds.

On a terminal it is a tqdm bar (redrawn in place with carriage returns); anywhere else
(a log file, CI, a pipe) it is plain lines, ``desc: n/total``, at most about every 10%
and at the end, so logs never fill with carriage returns. ``enabled=False`` (``--quiet``
or ``--no-progress``) shows nothing.
"""

from __future__ import annotations

import sys
from typing import Any, TextIO


class LineProgress:
    """Progress as whole lines, for streams that are not terminals."""

    def __init__(self, total: int, desc: str, stream: TextIO) -> None:
        self.total, self.desc, self.stream = total, desc, stream
        self.count, self.postfix = 0, ""
        self.every = max(1, total // 10)

    def update(self, n: int = 1) -> None:
        self.count += n
        if self.count % self.every == 0 or self.count >= self.total:
            extra = f" ({self.postfix})" if self.postfix else ""
            self.stream.write(f"{self.desc}: {self.count}/{self.total}{extra}\n")
            self.stream.flush()

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def close(self) -> None:
        pass


class NoProgress:
    """Shows nothing (progress turned off)."""

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass


def progress(total: int, desc: str, *, unit: str = "it", enabled: bool = True, stream: TextIO | None = None) -> Any:
    """A progress display with ``update(n)``, ``set_postfix_str(text)`` and ``close()``."""
    stream = stream if stream is not None else sys.stderr
    if not enabled or total <= 0:
        return NoProgress()
    if not getattr(stream, "isatty", lambda: False)():
        return LineProgress(total, desc, stream)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=stream, dynamic_ncols=True, leave=False)
