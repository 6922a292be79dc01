"""Progress on stderr for work that takes more than a couple of seconds.

On a terminal it is a tqdm bar (redrawn in place with carriage returns); anywhere else
(a log file, CI, a pipe) it is plain lines, ``desc: n/total``, at most about every 10%
and at the end, so logs never fill with carriage returns. Either appears only once the
work has run for :data:`DELAY` seconds, so quick runs print nothing extra.
``enabled=False`` (``--quiet`` or ``--no-progress``) shows nothing. Work with nothing to
count (one solve) uses :func:`working`, which only says how long it has been running.
"""

from __future__ import annotations

import contextlib
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


#: Seconds between the lines :func:`working` writes off a terminal.
EVERY = 10.0


class _Working:
    """The display behind :func:`working`: a thread that wakes up while the work runs."""

    def __init__(self, desc: str, stream: TextIO, delay: float, every: float) -> None:
        import threading

        self.desc, self.stream, self.delay, self.every = desc, stream, delay, every
        self.started = time.monotonic()
        self.stop = threading.Event()
        self.shown = False
        self.terminal = bool(getattr(stream, "isatty", lambda: False)())
        self.thread = threading.Thread(target=self._run, name=f"parsel-progress-{desc}", daemon=True)

    def _elapsed(self) -> float:
        return time.monotonic() - self.started

    def _run(self) -> None:
        if self.stop.wait(self.delay):
            return
        self.shown = True
        if self.terminal:
            from tqdm import tqdm

            bar = tqdm(total=None, desc=self.desc, file=self.stream, leave=False, dynamic_ncols=True,
                       bar_format="{desc}: working ({elapsed})", delay=1e-9)  # drawn below, not yet
            bar.start_t -= self._elapsed()  # the time since the work started, not since the line appeared
            bar.refresh()
            while not self.stop.wait(0.5):
                bar.refresh()
            bar.close()
            return
        while True:
            self.stream.write(f"{self.desc}: working ({self._elapsed():.0f} s)\n")
            self.stream.flush()
            if self.stop.wait(self.every):
                return

    def __enter__(self) -> _Working:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()
        if self.shown and not self.terminal and exc[0] is None:
            self.stream.write(f"{self.desc}: done in {self._elapsed():.1f} s\n")
            self.stream.flush()


def working(desc: str, *, enabled: bool = True, stream: TextIO | None = None, delay: float | None = None,
            every: float | None = None) -> Any:
    """A context manager for work with nothing to count (one solve, one evaluation): once it has
    run for ``delay`` seconds (default :data:`DELAY`), says so on stderr, ``desc: working (12 s)``.

    On a terminal it is one tqdm line redrawn with the time so far and cleared at the end;
    anywhere else, whole lines every ``every`` seconds (default :data:`EVERY`) and
    ``desc: done in 12.3 s`` at the end; nothing when the work ends before ``delay``.
    """
    if not enabled:
        return contextlib.nullcontext()
    stream = stream if stream is not None else sys.stderr
    return _Working(desc, stream, DELAY if delay is None else delay, EVERY if every is None else every)
