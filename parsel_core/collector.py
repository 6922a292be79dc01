"""Fewer cyclic garbage collections while a solve runs.

A solve allocates hundreds of thousands of short-lived containers (ops, dictionaries of
corners, small arrays) that reference counting frees as soon as they are dropped.
CPython's cyclic collector nevertheless runs after every 700 net allocations, and each
of its full passes walks every live object, the loaded shapes and the solver's caches
included. A larger first-generation threshold for the length of a solve cut AEP's CPU
time by 5-7% on the speed benchmark's requests (docs/aep.md, "Speed"); cycles are still
collected, in larger batches, and results do not depend on when that happens.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

#: First-generation threshold inside :func:`fewer_collections` (CPython's default: 700).
SOLVE_THRESHOLD = 10_000


@contextmanager
def fewer_collections(threshold: int = SOLVE_THRESHOLD) -> Iterator[None]:
    """Raise the collector's first-generation threshold to ``threshold`` inside the block;
    the previous thresholds are restored on leaving it. A collector that is disabled, or
    already as lenient (a caller's own setting, or an enclosing block), is left alone."""
    previous = gc.get_threshold()
    if not gc.isenabled() or previous[0] == 0 or previous[0] >= threshold:
        yield
        return
    gc.set_threshold(threshold, *previous[1:])
    try:
        yield
    finally:
        gc.set_threshold(*previous)
