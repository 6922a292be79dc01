"""Property: whatever the seed, every relation the report calls kept holds across the range.

Seeds are drawn at random (fixed seeds, so the test is deterministic) on the bundled assets
and on ShapeAssembly programs from the test fixtures; each program is re-checked at 50
fresh random parameter values, different from the ones the report used.
"""

from pathlib import Path

import numpy as np
import pytest

from parsel_core import Program, evaluate
from parsel_core.interfaces import SolveRequest
from parsel_core.loading import load_shape
from parsel_core.plugins import solvers
from parsel_core.report import check_program, relation_error, sliding_members

FIXTURES = Path(__file__).resolve().parents[2] / "parsel-shapeassembly" / "tests" / "fixtures"
SHAPES = ["tiny_table", "chair", "table", "cabinet", "shelf",
          *sorted(str(p) for p in FIXTURES.glob("*/*.txt"))[:4]]


def random_seed(shape, rng) -> str:
    part = shape.parts[sorted(shape.parts)[int(rng.integers(len(shape.parts)))]]
    centre = [float(v) for v in part.hexahedron.center]
    axis = tuple(int(v) for v in np.eye(3)[int(rng.integers(3))])
    kind = ("translate", "scale_1d", "rotate")[int(rng.integers(3))]
    amount = f"{rng.uniform(0.1, 0.6):.3f} * x"
    name = repr(part.id)
    origin = f"({centre[0]!r}, {centre[1]!r}, {centre[2]!r})"
    if kind == "translate":
        return f"translate({name}, dir={axis}, amount={amount})"
    if kind == "scale_1d":
        return f"scale_1d({name}, origin={origin}, dir={axis}, amount={amount})"
    return f"rotate({name}, origin={origin}, axis={axis}, amount={amount})"


@pytest.mark.parametrize("spec", SHAPES, ids=lambda s: Path(s).stem)
def test_kept_relations_hold_at_fresh_random_values(spec):
    shape = load_shape(spec)
    rng = np.random.default_rng(sum(map(ord, spec)))
    for _ in range(2):
        seed = random_seed(shape, rng)
        program = solvers()["aep"].run(SolveRequest(shape, Program.from_text(seed))).program
        report = check_program(shape, program)
        parameter = program.parameters[0]
        values = {parameter.name: rng.uniform(parameter.lo, parameter.hi, 50)}
        corners = evaluate(program, shape, values).parts
        sliding = sliding_members(shape, program)
        for state in report.relations:
            if state.state == "kept":
                error = relation_error(shape.relations[state.id], corners, sliding)
                assert error < report.tolerance, (seed, state.id, error)
