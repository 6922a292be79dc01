"""one_blas_thread limits the BLAS pool once per outermost block and restores it after."""

import threading

import numpy as np
import pytest

from parsel_core import blas


def _threads():
    return [info["num_threads"] for info in blas._controller().select(user_api="blas").info()]


def test_nested_blocks_limit_the_pool_once(monkeypatch):
    np.ones((2, 2)) @ np.ones((2, 2))  # (BLAS loaded)
    controller = blas._controller()
    calls = []
    real = controller.limit
    monkeypatch.setattr(controller, "limit", lambda **kw: calls.append(kw) or real(**kw))
    before = _threads()
    with blas.one_blas_thread():
        assert all(t == 1 for t in _threads())
        for _ in range(3):
            with blas.one_blas_thread():
                assert all(t == 1 for t in _threads())
        assert all(t == 1 for t in _threads())
    assert len(calls) == 1 and _threads() == before
    with blas.one_blas_thread():  # a new outermost block limits again
        pass
    assert len(calls) == 2 and _threads() == before


def test_an_error_inside_leaves_no_block_open(monkeypatch):
    controller = blas._controller()
    calls = []
    real = controller.limit
    monkeypatch.setattr(controller, "limit", lambda **kw: calls.append(kw) or real(**kw))
    try:
        with blas.one_blas_thread(), blas.one_blas_thread():
            raise RuntimeError("a failed solve")
    except RuntimeError:
        pass
    with blas.one_blas_thread():
        pass
    assert len(calls) == 2


def test_another_thread_limits_on_its_own(monkeypatch):
    controller = blas._controller()
    calls = []
    real = controller.limit
    monkeypatch.setattr(controller, "limit", lambda **kw: calls.append(kw) or real(**kw))

    def inner():
        with blas.one_blas_thread():
            pass

    with blas.one_blas_thread():
        worker = threading.Thread(target=inner)
        worker.start()
        worker.join()
    assert len(calls) == 2


PROBE = """
import os, sys
from parsel_core import blas
for name in blas.THREAD_VARIABLES:
    os.environ.pop(name, None)
{before}
started = blas.start_on_one_thread(os.environ)
import numpy as np
with blas.one_blas_thread():
    np.ones((64, 64)) @ np.ones((64, 64))
    limited_by_threadpoolctl = "threadpoolctl" in sys.modules
from threadpoolctl import threadpool_info
sizes = sorted({{i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}})
print(started, limited_by_threadpoolctl, sizes)
"""


@pytest.mark.parametrize(("before", "expected"), [
    ("", "True False [1]"),                           # the parsel program: one thread from the start
    ("import numpy", "False True"),                   # too late: numpy's pool is already started
    ("os.environ['OMP_NUM_THREADS'] = '1'", "False True"),  # a size the user chose is theirs
])
@pytest.mark.skipif(not blas._reads_thread_variables(), reason="numpy's BLAS ignores the thread variables")
def test_a_process_started_on_one_thread_has_nothing_to_limit(parsel_fresh_python, before, expected):
    assert parsel_fresh_python(PROBE.format(before=before)).strip().startswith(expected)
