"""CAS backends head to head: build and evaluate the constraint system of a 50-part shape.

The shape is a synthetic tower: 25 levels of two mirrored blocks each (50 parts), each
block attached to the one below it and to the floor at the bottom, every level a
reflection pair. A 5-op program edits it (scale, translate, rotate, shear, a taper).
For each backend the script times, over several repeats:

* build:    symbolic corners of every part, then every relation's residual expressions
            (what edit propagation reasons about), expanded;
* compile:  lambdify all residuals into one numpy function;
* evaluate: that function at 1,000 parameter values (a slider sweep / a range check).

Run: ``python benchmarks/bench_cas.py [--repeats N]``. Prints medians and the ratio.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from parsel_core import Hexahedron, Part, Program, ShapeGraph
from parsel_core.examples import attachment, ground, reflection
from parsel_core.plugins import cas_backend_names, get_cas_backend
from parsel_core.program import symbolic_corners

PROGRAM = """\
param x in [0, 0.5]
scale_1d(left_0, origin=(-0.5, 0.05, 0), dir=(1, 0, 0), amount=x)
translate(right_3, dir=(0, 1, 0), amount=0.5 * x)
rotate(left_7, origin=(-0.5, 0.75, 0), axis=(0, 0, 1), amount=x / 4)
shear(right_12, origin=(0.5, 1.25, 0), normal=(0, 1, 0), dir=(1, 0, 0), amount=x)
scale_2d(face(left_20, "v+"), origin=(-0.5, 2.1, 0), normal=(0, 1, 0), amount=-x / 2)
"""


def tower(levels: int = 25) -> ShapeGraph:
    parts, relations = [], []
    for level in range(levels):
        y0, y1 = 0.1 * level, 0.1 * (level + 1)
        left = Part(f"left_{level}", "block", Hexahedron.from_bounds((-0.8, y0, -0.2), (-0.2, y1, 0.2)))
        right = Part(f"right_{level}", "block", Hexahedron.from_bounds((0.2, y0, -0.2), (0.8, y1, 0.2)))
        parts += [left, right]
        relations.append(reflection(f"mirror_{level}", left, right, (0, 0, 0), (1, 0, 0)))
        if level == 0:
            relations += [ground("ground_left", left), ground("ground_right", right)]
        else:
            below_left, below_right = parts[-4], parts[-3]
            relations += [attachment(f"stack_left_{level}", left, below_left, "face"),
                          attachment(f"stack_right_{level}", right, below_right, "face")]
    return ShapeGraph(parts, relations, name="tower")


def run(backend_name: str, shape: ShapeGraph, program: Program) -> dict[str, float]:
    backend = get_cas_backend(backend_name)
    start = time.perf_counter()
    corners = symbolic_corners(program, shape, backend)
    residuals = []
    for relation in shape.relations.values():
        for value in np.asarray(relation.residual(corners)).ravel():
            residuals.append(backend.expand(value) if not isinstance(value, float) else backend.number(value))
    built = time.perf_counter()
    function = backend.compile(["x"], residuals)
    compiled = time.perf_counter()
    values = np.linspace(0, 0.5, 1000)
    out = function(values)
    done = time.perf_counter()
    assert out.shape == (len(residuals), 1000)
    return {"build": built - start, "compile": compiled - built, "evaluate": done - compiled,
            "total": done - start, "residuals": len(residuals), "max_residual": float(np.abs(out).max())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    shape = tower()
    program = Program.from_text(PROGRAM)
    names = cas_backend_names()
    results: dict[str, list[dict[str, float]]] = {name: [] for name in names}
    for _ in range(args.repeats):  # interleave backends so drift hits both alike
        for name in names:
            results[name].append(run(name, shape, program))
    medians = {name: {k: statistics.median(r[k] for r in runs) for k in runs[0]} for name, runs in results.items()}
    print(f"shape: {len(shape.parts)} parts, {len(shape.relations)} relations; program: {len(program.ops)} ops; "
          f"{args.repeats} repeats, medians in ms")
    print(f"{'backend':<12}{'build':>10}{'compile':>10}{'evaluate':>10}{'total':>10}{'residuals':>11}")
    for name, m in medians.items():
        print(f"{name:<12}{m['build'] * 1e3:>10.1f}{m['compile'] * 1e3:>10.1f}{m['evaluate'] * 1e3:>10.2f}"
              f"{m['total'] * 1e3:>10.1f}{int(m['residuals']):>11}")
    if "sympy" in medians and "symengine" in medians:
        s, e = medians["sympy"], medians["symengine"]
        print("ratio sympy/symengine: " + ", ".join(
            f"{k} {s[k] / e[k]:.1f}x" for k in ("build", "compile", "evaluate", "total")))
    tops = {name: m["max_residual"] for name, m in medians.items()}
    print("largest residual over the sweep (the edits break relations on purpose): " +
          ", ".join(f"{k} {v:.4f}" for k, v in tops.items()))


if __name__ == "__main__":
    main()
