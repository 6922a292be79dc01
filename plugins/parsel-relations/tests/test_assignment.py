"""The corner assignment solver: optimal, and the same choice as scipy's on ties."""

import itertools

import numpy as np
import pytest

from parsel_relations.assignment import linear_sum_assignment


def brute_force_cost(cost: np.ndarray) -> float:
    n = len(cost)
    return min(sum(cost[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))


@pytest.mark.parametrize("seed", range(40))
def test_assignment_is_optimal(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    cost = rng.random((n, n)) if seed % 2 else rng.integers(0, 3, (n, n)).astype(float)
    rows, cols = linear_sum_assignment(cost)
    assert rows.tolist() == list(range(n)) and sorted(cols.tolist()) == list(range(n))
    assert cost[rows, cols].sum() == pytest.approx(brute_force_cost(cost))


def test_constant_matrix_gives_the_identity():
    assert linear_sum_assignment(np.ones((8, 8)))[1].tolist() == list(range(8))


def test_hand_computed_case():
    cost = np.array([[4.0, 1.0, 3.0], [2.0, 0.0, 5.0], [3.0, 2.0, 2.0]])  # optimum 1 + 2 + 2 = 5
    assert linear_sum_assignment(cost)[1].tolist() == [1, 0, 2]


def test_same_choice_as_scipy_on_random_and_tied_matrices():
    scipy_optimize = pytest.importorskip("scipy.optimize")
    rng = np.random.default_rng(7)
    for trial in range(3000):
        n = int(rng.integers(1, 9))
        if trial % 3 == 0:
            cost = rng.random((n, n))
        elif trial % 3 == 1:
            cost = rng.integers(0, 3, (n, n)).astype(float)  # many ties
        else:  # corner sets: distances between a box's corners and a shuffled, shifted copy
            a = rng.random((n, 3))
            b = a[rng.permutation(n)] + rng.integers(0, 2, (n, 3)) * 0.5
            cost = np.linalg.norm(a[:, None] - b[None], axis=2)
        assert linear_sum_assignment(cost)[1].tolist() == scipy_optimize.linear_sum_assignment(cost)[1].tolist()


def test_bad_matrices_are_refused():
    with pytest.raises(ValueError, match="square"):
        linear_sum_assignment(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        linear_sum_assignment(np.array([[np.inf]]))
