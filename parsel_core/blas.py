"""BLAS on one thread, for the small or memory-bound products parsel runs.

OpenBLAS starts a thread per core for every product. The cage products of a slider step
(three columns wide) and the solver's systems (a few hundred rows) gain little from them
and lose much on a busy machine: a step of the 437k-vertex chair took a median 14 ms on
one thread against 190-310 ms on the default threads next to two busy processes
(``benchmarks/bench_deform.py``, docs/meshes.md). One thread also makes the rounding the
same on every machine, so AEP writes the same program bit for bit everywhere.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache

#: How deep this thread is in :func:`one_blas_thread` blocks.
_depth = threading.local()


@cache
def _controller():
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # finds the loaded BLAS libraries once per process


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """A context in which BLAS runs on one thread; the pool is restored on leaving it.

    Entering costs about 30 microseconds (threadpoolctl reads and sets the pool), except
    inside another such block of the same thread, which already holds the limit: the
    solver's inner least-squares steps, called thousands of times per solve, then cost
    nothing extra."""
    depth = getattr(_depth, "value", 0)
    _depth.value = depth + 1
    try:
        if depth:
            yield
        else:
            with _controller().limit(limits=1, user_api="blas"):
                yield
    finally:
        _depth.value = depth
