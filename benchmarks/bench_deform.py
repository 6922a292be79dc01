"""One slider step on a 100k-vertex asset: program evaluation (compiled) plus cage deformation.

The asset is the bundled chair with every part's mesh subdivided until the chair has
at least 100,000 vertices. A slider step is what an interactive Python client does per
slider move: ``CompiledProgram(values)`` (the program lambdified once by the CAS
backend) and ``CageDeformer.vertices`` (one cached ``(m, 8) @ (8, 3)`` product per
part, on one BLAS thread). Prints the median over many steps of each piece and of the
whole step, for a program of part ops and, when the chair's relations are detected, the
same program with a re-laid-out symmetry group. The ``deform, BLAS threads`` column
runs the same products on OpenBLAS's default threads, side by side, which is why the
deformer limits them to one. Goal: a whole step <= 5 ms (<= 10 ms above 200k vertices).

``--load N`` starts N busy processes (pure-Python loops, one per core they get) for the
whole measurement, as other work on the machine would; the interactive case that matters.

    python benchmarks/bench_deform.py [--vertices 100000] [--steps 300] [--backend NAME] [--load N]
    python benchmarks/bench_deform.py --vertices 437000 --load 2
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import time

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.loading import load_shape
from parsel_core.part import Part
from parsel_core.plugins import deformers, get_cas_backend
from parsel_core.program import Program, compile_program, evaluate
from parsel_mesh import deform as deform_module
from parsel_mesh.examples import CHAIR_ALL_PART_OPS

#: Every part op, features and two parameters included.
PART_OPS = CHAIR_ALL_PART_OPS


def dense_chair(target: int) -> ShapeGraph:
    """The chair with part meshes subdivided (each triangle into 4) until >= ``target`` vertices."""
    import trimesh

    shape = load_shape("chair")
    meshes = {pid: part.mesh for pid, part in shape.parts.items()}
    while sum(len(m.vertices) for m in meshes.values()) < target:
        pid = min(meshes, key=lambda p: len(meshes[p].vertices))  # grow the smallest part first
        vertices, faces = trimesh.remesh.subdivide(meshes[pid].vertices, meshes[pid].faces)
        meshes[pid] = trimesh.Trimesh(vertices, faces, process=False)
    parts = [Part(p.id, p.label, p.hexahedron, p.name, meshes[p.id]) for p in shape.parts.values()]
    return ShapeGraph(parts, shape.relations.values(), shape.name, shape.source, shape.metadata)


@contextlib.contextmanager
def cpu_load(processes: int):
    """``processes`` busy Python loops for the duration of the block (other work on the machine)."""
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(processes)]
    try:
        time.sleep(0.5 if busy else 0)  # let them get going
        yield
    finally:
        for process in busy:
            process.kill()
            process.wait()


@contextlib.contextmanager
def default_blas_threads():
    """The deformer's products without its one-thread limit (for the side-by-side column)."""
    saved = deform_module.one_blas_thread
    deform_module.one_blas_thread = contextlib.nullcontext
    try:
        yield
    finally:
        deform_module.one_blas_thread = saved


def median_ms(step, values: list[dict[str, float]]) -> float:
    times = []
    for v in values:
        start = time.perf_counter()
        step(v)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000


def deform_ms(deformer, shape: ShapeGraph, evaluations) -> float:
    """Median over evaluations of the median of 5 deformations of each."""
    return statistics.median([median_ms(lambda _v, e=e: deformer.vertices(shape, e), [None] * 5)
                              for e in evaluations])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, default=100_000)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--backend", default=None, help="CAS backend for compile_program (default: configured)")
    parser.add_argument("--load", type=int, default=0, metavar="N", help="busy processes running meanwhile")
    args = parser.parse_args()
    goal = 5.0 if args.vertices <= 200_000 else 10.0
    shape = dense_chair(args.vertices)
    backend = get_cas_backend(args.backend)
    deformer = deformers()["cage"]
    vertices = sum(len(p.mesh.vertices) for p in shape.parts.values())
    programs = {"part ops (10 ops, 2 params)": Program.from_text(PART_OPS)}
    groups = [r for r in shape.relations.values() if r.kind == "translation"]
    if groups:
        g = groups[0]
        text = PART_OPS + (f"scale_1d({g.id}, origin=(0, 0.625, -0.19), dir=(1, 0, 0), amount=x)\n"
                           f"change_count({g.id}, mode='top_down', amount=4 * x)\n")
        programs[f"+ {g.id} re-laid out (change_count)"] = Program.from_text(text)
    rng = np.random.default_rng(0)
    print(f"asset: chair, {len(shape.parts)} parts, {vertices} vertices; CAS backend {backend.name}; "
          f"median of {args.steps} steps at random slider values; {args.load} busy processes meanwhile, "
          f"{os.cpu_count()} CPUs")
    print(f"\n{'program':<44}{'evaluate':>10}{'deform':>10}{'step':>10}{'numpy ref':>11}"
          f"{'deform, BLAS threads':>22}   goal <= {goal:g} ms")
    with cpu_load(args.load):
        for name, program in programs.items():
            compiled = compile_program(program, shape, backend)
            values = [{p.name: float(rng.uniform(p.lo, p.hi)) for p in program.parameters} for _ in range(args.steps)]
            deformer.vertices(shape, compiled(values[0]))  # cage weights are computed once, here
            evaluations = [compiled(v) for v in values[:20]]
            t_eval = median_ms(compiled, values)

            t_deform = deform_ms(deformer, shape, evaluations)
            with default_blas_threads():
                t_threads = deform_ms(deformer, shape, evaluations)
            t_step = median_ms(lambda v, c=compiled: deformer.vertices(shape, c(v)), values)
            t_ref = median_ms(lambda v, p=program: deformer.vertices(shape, evaluate(p, shape, v)), values[:50])
            verdict = "ok" if t_step <= goal else "over"
            print(f"{name:<44}{t_eval:>8.3f}ms{t_deform:>8.3f}ms{t_step:>8.3f}ms{t_ref:>9.3f}ms{t_threads:>20.3f}ms"
                  f"   {verdict}")
    print("\nevaluate: CompiledProgram(values); deform: CageDeformer.vertices (all parts, one BLAS thread); step:"
          "\nboth (wall time); numpy ref: parsel_core.program.evaluate + deform (the uncompiled reference);"
          "\ndeform, BLAS threads: the same products on OpenBLAS's default thread count")


if __name__ == "__main__":
    main()
