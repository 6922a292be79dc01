"""The proof that no edit of a part keeps its constraints (feasibility.py) must be sound:
never claimed for a system some displacement meets, and searches it skips find nothing."""

import copy
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linprog

from parsel_aep import feasibility


def random_system(rng, rows: int, rank: int):
    """``a`` (rows, 24) of the given rank, as constraint Jacobians scaled by allowances are."""
    a = rng.normal(size=(rows, rank)) @ rng.normal(size=(rank, 24)) * rng.choice([1.0, 1e3, 1e4])
    return a


@pytest.mark.parametrize("seed", range(40))
def test_a_system_some_displacement_meets_is_never_called_hopeless(seed):
    rng = np.random.default_rng(seed)
    rows = int(rng.integers(3, 80))
    a = random_system(rng, rows, int(rng.integers(1, 25)))
    d = rng.normal(size=24) * rng.choice([1e-3, 1.0, 10.0])
    slack = rng.uniform(-1.0, 1.0, rows) * rng.choice([0.0, 0.5, 0.999])
    assert not feasibility.no_displacement_keeps(a, a @ d + slack)


def test_contradictory_rows_are_hopeless():
    a = np.zeros((3, 24))
    a[0, 0] = a[1, 0] = 1.0           # the same displacement asked to be near 0 and near 5
    a[2, 1] = 1.0
    assert feasibility.no_displacement_keeps(a, np.array([0.0, 5.0, 0.0]))
    assert not feasibility.no_displacement_keeps(a, np.array([0.0, 1.5, 0.0]))  # (0.75 meets both)


@pytest.mark.parametrize("seed", range(30))
def test_hopeless_only_where_linear_programming_finds_no_displacement(seed):
    """Against scipy's linprog (HiGHS): every system called hopeless has no solution, and
    most systems without one are called hopeless (the certificate is not vacuous)."""
    rng = np.random.default_rng(100 + seed)
    claimed = infeasible = decided = 0
    for _ in range(20):
        rows = int(rng.integers(25, 90))
        a = rng.normal(size=(rows, 24))
        b = a @ rng.normal(size=24) + rng.normal(size=rows) * rng.choice([0.3, 1.0, 3.0])
        hopeless = feasibility.no_displacement_keeps(a, b)
        lp = linprog(np.zeros(24), A_ub=np.vstack([a, -a]), b_ub=np.concatenate([1 + b, 1 - b]),
                     bounds=[(None, None)] * 24, method="highs")
        if lp.status not in (0, 2):  # (HiGHS undecided)
            continue
        decided += 1
        if hopeless:
            assert lp.status == 2
        claimed += hopeless
        infeasible += lp.status == 2
    assert decided >= 15 and claimed >= 0.5 * infeasible


def test_searches_proved_hopeless_find_no_valid_edit(monkeypatch):
    """On the fixtures, every search the proof cuts short, run in full for valid edits
    only, screens no valid candidate; and the programs, rejections and counts (but the
    work counts) are those of solving without the proof."""
    from parsel_aep import propagate as propagate_module
    from parsel_aep.propagate import Propagation

    hopeless_of, search_of = Propagation.hopeless, Propagation.search
    checked = []

    def hopeless(self, part, constraints, corners, sliding):
        found = hopeless_of(self, part, constraints, corners, sliding)
        if found and not getattr(self, "_checking", False):
            state = propagate_module._State(list(self._state.ops), set(), stats=copy.deepcopy(self._state.stats))
            self._checking = True
            try:
                search_of(self, state, part, (part,), constraints, corners, breaking=False)
            finally:
                self._checking = False
            assert state.stats["candidates_valid"] == self._state.stats["candidates_valid"]
            checked.append(part)
        return found and not getattr(self, "_checking", False)

    def search(self, state, *args, **kwargs):
        self._state = state
        return search_of(self, state, *args, **kwargs)

    results = []
    monkeypatch.setattr(propagate_module, "propagate", _recording(propagate_module.propagate, results))
    monkeypatch.setattr(Propagation, "hopeless", hopeless)
    monkeypatch.setattr(Propagation, "search", search)
    solve_fixtures()
    assert len(checked) >= 5
    with_proof = results[:]
    results.clear()
    monkeypatch.setattr(Propagation, "hopeless", lambda self, *args: False)
    solve_fixtures()
    assert [_decided(r) for r in results] == [_decided(r) for r in with_proof]


def solve_fixtures():
    """test_speed.py's fixture requests, solved."""
    spec = importlib.util.spec_from_file_location("_aep_speed_tests", Path(__file__).with_name("test_speed.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.solve_fixtures()


def _recording(solve, results):
    def recorded(request):
        result = solve(request)
        results.append(result)
        return result
    return recorded


def _decided(result):
    work = ("candidates_screened", "hopeless_searches", "time_s")
    return (result.program.to_json(), result.rejected, {k: v for k, v in result.stats.items() if k not in work})


@pytest.mark.parametrize("seed", range(60))
def test_stopping_at_a_displacement_that_meets_every_bound_answers_as_every_pass(seed, monkeypatch):
    """Met and unmet systems, nearly met ones (slack up to 1.05), rank-deficient ones and
    huge displacements: the early answer is the answer of all the passes."""
    rng = np.random.default_rng(seed)
    rows = int(rng.integers(3, 80))
    a = random_system(rng, rows, int(rng.integers(1, 25)))
    d = rng.normal(size=24) * rng.choice([1e-3, 1.0, 10.0, 1e8])
    slack = rng.uniform(-1.0, 1.0, rows) * rng.choice([0.0, 0.5, 0.999, 1.05, 3.0])
    b = a @ d + slack
    if seed % 3 == 0:  # contradictory rows as well
        a = np.concatenate([a, a[:2]])
        b = np.concatenate([b, b[:2] + rng.choice([0.5, 2.5, 10.0])])
    early = feasibility.no_displacement_keeps(a, b)
    monkeypatch.setattr(feasibility, "_solves", lambda *args: False)  # every reweighted pass tried
    assert early == feasibility.no_displacement_keeps(a, b)
