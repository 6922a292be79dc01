"""The collector runs less often inside a solve and exactly as before after it."""

import gc

import pytest

from parsel_core.collector import SOLVE_THRESHOLD, fewer_collections


@pytest.fixture
def thresholds():
    previous, enabled = gc.get_threshold(), gc.isenabled()
    gc.set_threshold(700, 10, 10)
    gc.enable()
    yield
    gc.set_threshold(*previous)
    (gc.enable if enabled else gc.disable)()


def test_threshold_raised_inside_and_restored_after(thresholds):
    with fewer_collections():
        assert gc.get_threshold() == (SOLVE_THRESHOLD, 10, 10)
        with fewer_collections():  # nested: the outer block's setting stays
            assert gc.get_threshold() == (SOLVE_THRESHOLD, 10, 10)
        assert gc.get_threshold() == (SOLVE_THRESHOLD, 10, 10)
    assert gc.get_threshold() == (700, 10, 10)


def test_restored_when_the_solve_raises(thresholds):
    with pytest.raises(ValueError), fewer_collections():
        raise ValueError("a failed solve")
    assert gc.get_threshold() == (700, 10, 10)


def test_a_callers_own_setting_is_left_alone(thresholds):
    gc.set_threshold(50_000, 5, 5)
    with fewer_collections():
        assert gc.get_threshold() == (50_000, 5, 5)
    assert gc.get_threshold() == (50_000, 5, 5)
    gc.set_threshold(700, 10, 10)
    gc.disable()
    with fewer_collections():
        assert not gc.isenabled() and gc.get_threshold() == (700, 10, 10)
    assert not gc.isenabled()

