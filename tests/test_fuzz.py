"""A fast subset of the hostile-input corpus (benchmarks/fuzz.py runs thousands).

Each case runs ``parsel`` in a forked process in a fresh folder, under a time and a memory
limit, and must exit 0 or 2 with one line, without a traceback, a hang, a partial output
or a lost user file.
"""

from __future__ import annotations

import importlib.util
import sys
from collections import Counter
from pathlib import Path

import pytest

FUZZ = Path(__file__).resolve().parents[1] / "benchmarks" / "fuzz.py"
pytestmark = pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="runs cases in forked processes")


@pytest.fixture(scope="module")
def fuzz():
    spec = importlib.util.spec_from_file_location("parsel_fuzz", FUZZ)
    module = importlib.util.module_from_spec(spec)
    sys.modules["parsel_fuzz"] = module
    spec.loader.exec_module(module)
    return module


def test_the_generator_is_reproducible_and_covers_every_family(fuzz):
    first, again = fuzz.generate(200, seed=3), fuzz.generate(200, seed=3)
    assert [c.argv for c in first] == [c.argv for c in again]
    assert [c.files for c in first] == [c.files for c in again]
    assert set(Counter(c.family for c in first)) == set(fuzz.FAMILIES)


def test_the_judge_sees_partial_and_lost_outputs(fuzz, tmp_path):
    """The checks themselves: a failure that leaves a file is partial; a changed user file is lost."""
    case = fuzz.Case("outputs", ["edit"], {"mydocs/thesis.txt": b"work"})
    (tmp_path / "mydocs").mkdir()
    (tmp_path / "mydocs" / "thesis.txt").write_bytes(b"work")
    before = fuzz._snapshot(tmp_path)
    assert fuzz._judge(case, tmp_path, before, 2, "parsel: error: no\n", False) == "clean"
    assert fuzz._judge(case, tmp_path, before, 2, "Traceback (most recent call last):\n", False) == "traceback"
    assert fuzz._judge(case, tmp_path, before, 2, "parsel: error: a\nsecond line\n", False) == "unclean-exit"
    (tmp_path / "out").mkdir()
    assert fuzz._judge(case, tmp_path, before, 2, "parsel: error: no\n", False) == "partial"
    (tmp_path / "mydocs" / "thesis.txt").write_bytes(b"")
    assert fuzz._judge(case, tmp_path, before, 0, "", False) == "lost"


def test_a_fast_subset_of_hostile_inputs_is_handled_cleanly(fuzz):
    cases = fuzz.generate(240, seed=7, cheap_only=True)
    assert len({c.family for c in cases}) == len(fuzz.FAMILIES)
    outcomes = fuzz.run_all(cases, seconds=30, memory_mib=3072)
    bad = [f"{o.status}: {o.case.argv[:8]!r}: {o.stderr.strip()[-300:]}" for o in outcomes if o.status != "clean"]
    assert not bad, "\n".join(bad[:10])
