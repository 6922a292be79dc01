"""one_blas_thread limits the BLAS pool once per outermost block and restores it after."""

import threading

import numpy as np

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
