"""BLAS on one thread, for the small or memory-bound products parsel runs.

OpenBLAS starts a thread per core for every product. The cage products of a slider step
(three columns wide) and the solver's systems (a few hundred rows) gain little from them
and lose much on a busy machine: a step of the 437k-vertex chair took a median 14 ms on
one thread against 190-310 ms on the default threads next to two busy processes
(``benchmarks/bench_deform.py``, docs/meshes.md). One thread also makes the rounding the
same whatever the number of cores, so AEP writes the same program on a machine of two
cores as on one of sixteen. It does not make it the same on every processor: OpenBLAS
picks its kernels by the CPU, and their products round differently (docs/aep.md).

A process that starts OpenBLAS with several threads also pays for them outside any
product: the ``parsel`` command sets the thread variables to one before numpy loads
(:func:`one_thread_unless_chosen`), unless the user chose a size. Its BLAS then has one
thread from the start, and :func:`one_blas_thread` does nothing (threadpoolctl, which
costs about 25 ms of CPU to import and to find the loaded libraries, is not imported).
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
from functools import cache

#: Thread-pool sizes of numeric libraries, read once when numpy (its BLAS) loads.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_unless_chosen(environ: MutableMapping[str, str]) -> list[str]:
    """Set every :data:`THREAD_VARIABLES` to one thread when the user set none of them;
    the names set (none when the user chose a size for any of them).

    Only effective before numpy is imported. Starting OpenBLAS's pool costs a process
    about 0.14 s of CPU on a two-core machine, and its idle threads keep spinning after
    each product; ``parsel edit chair "make the chair wider"`` took a median 0.93 s of
    CPU with the default pool and 0.79 s with one thread (benchmarks/bench_cli.py).
    """
    if any(name in environ for name in THREAD_VARIABLES):
        return []
    for name in THREAD_VARIABLES:
        environ[name] = "1"
    return list(THREAD_VARIABLES)


#: Whether this process's BLAS was started on one thread (:func:`start_on_one_thread`).
_started_single = False


def start_on_one_thread(environ: MutableMapping[str, str]) -> bool:
    """:func:`one_thread_unless_chosen` on the process's own ``environ`` before numpy loads
    (the ``parsel`` program's first step): when it set the variables, every BLAS product
    of the process runs on one thread, and :func:`one_blas_thread` has nothing to limit.
    Whether it did so."""
    global _started_single
    loaded = "numpy" in sys.modules
    _started_single = bool(one_thread_unless_chosen(environ)) and not loaded
    return _started_single


#: How deep this thread is in :func:`one_blas_thread` blocks.
_depth = threading.local()


@cache
def _reads_thread_variables() -> bool:
    """Whether numpy's BLAS sizes its pool from :data:`THREAD_VARIABLES` (OpenBLAS, MKL; not
    BLIS or Accelerate), by numpy's build configuration."""
    import numpy

    blas = getattr(numpy.__config__, "CONFIG", {}).get("Build Dependencies", {}).get("blas", {})
    name = str(blas.get("name", "")).lower()
    return "openblas" in name or "mkl" in name


@cache
def _controller():
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # finds the loaded BLAS libraries once per process


def started_on_one_thread() -> bool:
    """Whether this process's BLAS was started on one thread (:func:`start_on_one_thread`):
    then so is any BLAS library it loads later, which reads the same variables."""
    return _started_single


def forget_libraries() -> None:
    """Look for the loaded BLAS libraries again at the next outermost block: one loaded
    since (scipy's LAPACK wrappers bring their own OpenBLAS) is then limited too."""
    _controller.cache_clear()


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """A context in which BLAS runs on one thread; the pool is restored on leaving it.

    Entering costs about 30 microseconds (threadpoolctl reads and sets the pool), except
    inside another such block of the same thread, which already holds the limit: the
    solver's inner least-squares steps, called thousands of times per solve, then cost
    nothing extra. In a process whose BLAS started on one thread (the ``parsel`` program,
    :func:`start_on_one_thread`) there is nothing to limit and entering costs nothing; a
    plugin that raised the pool there (``threadpoolctl``, ``torch.set_num_threads``) would
    make the products run on its threads."""
    depth = getattr(_depth, "value", 0)
    _depth.value = depth + 1
    try:
        if depth or (_started_single and _reads_thread_variables()):
            yield
        else:
            with _controller().limit(limits=1, user_api="blas"):
                yield
    finally:
        _depth.value = depth
