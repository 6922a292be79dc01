"""benchmarks/bench_aep_speed.py: the side-by-side runner finds a changed program.

It solves requests in worker processes (the working tree's and a revision's
``plugins/parsel-aep``), saves each result, and compares them with the other side's or
a saved run's byte for byte; ``bench_aep.py --baseline`` reports through it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_aep_speed  # noqa: E402

SEED = "scale_1d('top', origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"


def requests() -> list[dict]:
    return [{"label": f"tiny-{i}", "spec": "tiny_table", "seed": seed, "breaks": [],
             "options": {"backend": "symengine"}}
            for i, seed in enumerate([SEED, SEED.replace("amount=x", "amount=0.5 * x")])]


def test_a_saved_run_compares_equal_and_a_changed_program_is_found(tmp_path):
    lines: list[str] = []
    first = bench_aep_speed.compare(requests(), save=tmp_path, echo=lines.append)
    assert not first.compared and len(first.times["new"]) == 2 and len(lines) == 2
    saved = sorted(tmp_path.glob("*.new.json"))
    assert len(saved) == 2 and all("program" in json.loads(p.read_text()) for p in saved)

    again = bench_aep_speed.compare(requests(), reference=tmp_path, echo=lines.append)
    assert again.compared and again.mismatches == [] and again.requests == 2

    result = json.loads(saved[1].read_text())
    program = json.loads(result["program"])
    program["ops"][0]["amount"] = "0.25*x"
    result["program"] = json.dumps(program, indent=2)
    saved[1].write_text(json.dumps(result))
    changed = bench_aep_speed.compare(requests(), reference=tmp_path, echo=lines.append)
    assert [label for label, _ in changed.mismatches] == ["tiny-1"]
    assert "DIFFERENT (program)" in changed.mismatches[0][1]


def test_a_baseline_revision_solves_beside_the_working_tree():
    if subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True).returncode:
        pytest.skip("not a git checkout")
    found = bench_aep_speed.compare(requests()[:1], baseline="HEAD", echo=lambda line: None)
    assert set(found.times) == {"old", "new"} and found.compared
    assert all(t > 0 for side in found.times.values() for t in side)


#: What each baseline scope imports from the revision: the rest comes from the working tree
#: (the modules probed are the ``tree`` scope's, every one of them).
FROM_REVISION = {
    "core": ("parsel_aep", "parsel_core.relations"),
    "tree": ("parsel_aep", "parsel_core.relations", "parsel_relations", "parsel_shapeassembly", "parsel_offline"),
}


@pytest.mark.parametrize("scope", sorted(FROM_REVISION))
def test_a_baseline_imports_what_its_scope_takes_from_the_revision(tmp_path, scope):
    if subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True).returncode:
        pytest.skip("not a git checkout")
    path = bench_aep_speed.baseline_tree("HEAD", tmp_path, scope)
    names = FROM_REVISION["tree"]
    code = f"import importlib; print(*(importlib.import_module(n).__file__ for n in {names!r}))"
    found = dict(zip(names, subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": path},
                                           cwd=tmp_path, capture_output=True, text=True, check=True).stdout.split()))
    taken = {name for name, file in found.items() if Path(file).is_relative_to(tmp_path)}
    assert taken == set(FROM_REVISION[scope]), found
    assert bench_aep_speed.compare(requests()[:1], baseline="HEAD", echo=lambda line: None, scope=scope).compared


def test_an_unknown_baseline_scope_is_refused(tmp_path):
    with pytest.raises(ValueError, match="baseline scope 'plugins'"):
        bench_aep_speed.baseline_tree("HEAD", tmp_path, "plugins")


def test_split_times_lapack_and_the_joint_pass_within_each_request():
    found = bench_aep_speed.compare(requests(), echo=lambda line: None, split=True)
    splits = found.splits["new"]
    assert len(splits) == 2
    for seconds, split in zip(found.times["new"], splits):
        assert 0 < split["lapack"] <= seconds and 0 < split["joint"] <= seconds
        assert 0 <= split["lapack_joint"] <= min(split["lapack"], split["joint"])
    assert bench_aep_speed.compare(requests()[:1], echo=lambda line: None).splits == {}


def test_what_if_takes_away_the_work_by_hand():
    # 20 requests of 1 s: 0.2 s in LAPACK, 0.5 s in the joint pass, 0.1 s of it LAPACK.
    # The p95 is the 19th smallest (bench_aep's rank), here 1 s whatever is taken away.
    split = {"lapack": 0.2, "joint": 0.5, "lapack_joint": 0.1}
    rows, factors = bench_aep_speed.what_if([1.0] * 20, [split] * 20, goal=0.5)
    assert [(case, round(m, 9), round(p, 9)) for case, m, p in rows] == [
        ("as measured", 1.0, 1.0), ("without the joint pass", 0.5, 0.5),
        ("joint pass: its LAPACK only", 0.6, 0.6), ("without LAPACK", 0.8, 0.8),
        ("LAPACK alone", 0.2, 0.2)]
    # 0.2 + 0.8 / k <= 0.5 from k = 8/3; the joint pass alone leaves 0.6 s > 0.5 s
    assert factors["all work outside LAPACK"] == pytest.approx(8 / 3, rel=1e-9)
    assert factors["the joint pass outside LAPACK"] == float("inf")
    # 0.6 + 0.4 / k <= 0.7 from k = 4; a goal already met needs nothing
    assert bench_aep_speed.what_if([1.0] * 20, [split] * 20, goal=0.7)[1]["the joint pass outside LAPACK"] == \
        pytest.approx(4.0, rel=1e-9)
    assert set(bench_aep_speed.what_if([1.0] * 20, [split] * 20, goal=2.0)[1].values()) == {1.0}


def test_what_if_reads_the_p95_at_bench_aeps_rank():
    # one slow request in 20 is above the p95 rank: the p95 is the fast ones' 0.1 s
    seconds = [0.1] * 19 + [3.0]
    splits = [{"lapack": 0.0, "joint": 0.0, "lapack_joint": 0.0}] * 20
    rows, factors = bench_aep_speed.what_if(seconds, splits, goal=0.5)
    assert rows[0][2] == 0.1 and set(factors.values()) == {1.0}


def test_random_requests_can_come_from_another_sample_of_shapes(tmp_path):
    """``--sample`` draws other val shapes for the random-seed requests (labelled with the
    sample), each with bench_aep's three seeds; sample 0 is bench_aep's own."""
    from bench_aep import seeds_for

    from parsel_core.loading import load_shape

    fixtures = ROOT / "plugins" / "parsel-shapeassembly" / "tests" / "fixtures"
    for category in ("chair", "table", "storage"):
        programs = sorted((fixtures / category).glob("*.txt"))[:3]
        (tmp_path / "splits" / category).mkdir(parents=True)
        (tmp_path / "splits" / category / "val.txt").write_text("\n".join(p.stem for p in programs))
        (tmp_path / category).mkdir()
        for program in programs:
            (tmp_path / category / program.name).write_text(program.read_text())
    drawn = {}
    for sample in range(6):
        found = bench_aep_speed.cases(9, 0, False, tmp_path, shapes=3, sample=sample)
        assert len(found) == 9
        assert all(c["label"].startswith("random-" if sample == 0 else f"random{sample}-") for c in found)
        specs = [c["spec"] for c in found]
        assert [c["seed"] for c in found] == [s for spec in dict.fromkeys(specs)
                                              for s in seeds_for(load_shape(spec))]
        drawn[sample] = tuple(dict.fromkeys(specs))
    assert len(set(drawn.values())) > 1  # (other samples, other shapes)


def test_a_crash_is_a_result_of_its_side_not_the_end_of_the_run():
    """A request the solver fails on (an exception other than its refusals) is answered
    as ``crashed``, so the run goes on and the crash is listed; a refusal stays an error."""
    import contextlib
    import io

    from parsel_core.errors import ParselError
    from parsel_core.plugins import solvers

    class Failing:
        def __init__(self, exc):
            self.exc = exc

        def run(self, request):
            raise self.exc

    case = requests()[0]
    shapes = {}
    _, out = bench_aep_speed.solve_case(Failing(ValueError("cannot reshape")), shapes, case)
    assert out == {"crashed": "ValueError: cannot reshape"}
    _, out = bench_aep_speed.solve_case(Failing(ParselError("no such part")), shapes, case)
    assert out == {"error": "ParselError: no such part"}
    seconds, out = bench_aep_speed.solve_case(solvers()["aep"], shapes, case)
    assert seconds > 0 and set(out) == {"program", "rejected", "stats"} and list(shapes) == ["tiny_table"]
    summary = bench_aep_speed.Comparison({"new": [0.1]}, [], {}, 1, False, crashed={"new": ["tiny-0"]})
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        summary.print_summary()
    assert "new: crashed on 1: tiny-0" in printed.getvalue().splitlines()
