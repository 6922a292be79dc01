"""Progress on stderr for work that takes more than a couple of seconds.

On a terminal it is a tqdm bar (redrawn in place with carriage returns); anywhere else
(a log file, CI, a pipe) it is plain lines, ``desc: n/total``, at most about every 10%
and at the end, so logs never fill with carriage returns. Either appears only once the
work has run for :data:`DELAY` seconds, so quick runs print nothing extra.
``enabled=False`` (``--quiet`` or ``--no-progress``) shows nothing.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

#: Seconds of work before any progress shows.
DELAY = 2.0


class LineProgress:
    """Progress as whole lines, for streams that are not terminals."""

    def __init__(self, total: int, desc: str, stream: TextIO, delay: float = 0.0) -> None:
        self.total, self.desc, self.stream = total, desc, stream
        self.count, self.postfix = 0, ""
        self.every = max(1, total // 10)
        self.shows_from = time.monotonic() + delay

    def update(self, n: int = 1) -> None:
        self.count += n
        if time.monotonic() < self.shows_from:
            return
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


def progress(total: int, desc: str, *, unit: str = "it", enabled: bool = True, stream: TextIO | None = None,
             delay: float | None = None) -> Any:
    """A progress display with ``update(n)``, ``set_postfix_str(text)`` and ``close()``, shown
    after ``delay`` seconds (default :data:`DELAY`)."""
    stream = stream if stream is not None else sys.stderr
    delay = DELAY if delay is None else delay
    if not enabled or total <= 0:
        return NoProgress()
    if not getattr(stream, "isatty", lambda: False)():
        return LineProgress(total, desc, stream, delay)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=stream, dynamic_ncols=True, leave=False, delay=delay)
