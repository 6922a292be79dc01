"""BLAS on one thread, for the small or memory-bound products parsel runs.

OpenBLAS starts a thread per core for every product. The cage products of a slider step
(three columns wide) and the solver's systems (a few hundred rows) gain little from them
and lose much on a busy machine: a step of the 437k-vertex chair took a median 14 ms on
one thread against 190-310 ms on the default threads next to two busy processes
(``benchmarks/bench_deform.py``, docs/meshes.md). One thread also makes the rounding the
same on every machine, so AEP writes the same program bit for bit everywhere.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from functools import cache


@cache
def _controller():
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # finds the loaded BLAS libraries once per process


def one_blas_thread() -> AbstractContextManager:
    """A context in which BLAS runs on one thread; the pool is restored on leaving it
    (entering costs about 10 microseconds)."""
    return _controller().limit(limits=1, user_api="blas")
