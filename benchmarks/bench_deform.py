"""One slider step on a dense asset, on an idle machine and next to a CPU load generator.

The asset is the bundled chair with every part's mesh subdivided until the chair has at
least ``--vertices`` vertices (several sizes may be given). A slider step is what an
interactive Python client does per slider move: ``CompiledProgram(values)`` (the program
lambdified once by the CAS backend) and the deformation of the part meshes. Each step
draws new random values for every parameter, so every edited part moves every step.
Steps are paced at ``--pace`` Hz (default 60, a display's frame rate): an interactive
client idles between slider events, and the scheduler lets a task that wakes from idle
run before CPU-bound ones. ``--pace 0`` runs the steps back to back, a CPU-bound loop
that the scheduler shares out with the load like any busy process (slower under load).

The first three methods take turns, 50 steps at a time, so that they see the same machine:

* new: ``CageDeformer.live(shape)`` (``LiveDeformation``): float32 weights, vertex
  buffers reused every step, only parts whose corners moved recomputed, one BLAS thread;
* old: ``CageDeformer.vertices`` (fresh float64 arrays for every part, one BLAS thread);
* old, BLAS threads: the same on OpenBLAS's default thread count, the product as it was
  before the deformer limited the threads (at every 10th value only, slow under load, and
  after the others, since OpenBLAS's threads keep spinning for a while after a product).

The load generator: ``--load N`` busy processes (``python -c "while True: pass"``, default
N = the number of CPUs), started before and killed after the loaded half of the run; the
first half of each table runs without them. They compete for the cores as other programs
on the machine would, which is the interactive case that matters: each runs in a session
of its own (``setsid``), as a program started from another terminal or by another user
does. Linux's scheduler (with ``kernel.sched_autogroup_enabled``, the default on desktops,
or per-application cgroups) first shares the CPUs among sessions, then among a session's
processes; ``--same-session`` keeps the busy processes in the benchmark's session, where
they take their CPU from its own share, a harsher case that a slider client meets only
when it starts busy work itself. Reported per method: median
and 95th percentile of the step's wall time and the median of its CPU time (the process's,
BLAS threads included), and old / new ratios. Goal: the new step's median <= 5 ms up to
200k vertices and <= 10 ms above, under load.

    python benchmarks/bench_deform.py [--vertices 100000 ...] [--steps 300] [--backend NAME] [--load N]
                                      [--same-session] [--pace HZ]
    python benchmarks/bench_deform.py --vertices 437000
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.loading import load_shape
from parsel_core.part import Part
from parsel_core.plugins import deformers, get_cas_backend
from parsel_core.program import Program, compile_program
from parsel_mesh import deform as deform_module
from parsel_mesh.examples import CHAIR_ALL_PART_OPS

#: Every part op, features and two parameters included.
PART_OPS = CHAIR_ALL_PART_OPS
#: The load generator's busy loop, one process per unit of load.
BUSY_LOOP = "while True: pass"
#: Steps of one method in a row before the next method's turn.
BLOCK = 50


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
def cpu_load(processes: int, same_session: bool = False) -> Iterator[None]:
    """``processes`` busy Python loops for the duration of the block: other programs on the
    machine, each in a session of its own, or the benchmark's own children (``same_session``)."""
    busy = [subprocess.Popen([sys.executable, "-c", BUSY_LOOP], start_new_session=not same_session)
            for _ in range(processes)]
    try:
        time.sleep(0.5 if busy else 0)  # let them get going
        yield
    finally:
        for process in busy:
            process.kill()
            process.wait()


@contextlib.contextmanager
def default_blas_threads() -> Iterator[None]:
    """The deformer's products without its one-thread limit (the ``old, BLAS threads`` row)."""
    saved = deform_module.one_blas_thread
    deform_module.one_blas_thread = contextlib.nullcontext
    try:
        yield
    finally:
        deform_module.one_blas_thread = saved


class Timings:
    """Wall and CPU seconds of each step of one method."""

    def __init__(self) -> None:
        self.wall: list[float] = []
        self.cpu: list[float] = []

    def time(self, step: Callable[[], Any]) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        step()
        self.cpu.append(time.process_time() - cpu)
        self.wall.append(time.perf_counter() - wall)

    def median(self) -> float:
        return statistics.median(self.wall) * 1000

    def p95(self) -> float:
        return float(np.percentile(self.wall, 95)) * 1000

    def cpu_median(self) -> float:
        return statistics.median(self.cpu) * 1000


class Pacer:
    """Waits for the next frame of a ``hz`` clock before each step (``hz = 0``: no waiting)."""

    def __init__(self, hz: float) -> None:
        self.period = 1.0 / hz if hz > 0 else 0.0
        self.next = time.perf_counter()

    def wait(self) -> None:
        if self.period:
            now = time.perf_counter()
            self.next += self.period
            if self.next <= now:  # frames missed: wait for the next one, as a display does
                self.next = now + self.period
            time.sleep(self.next - now)


def run_phase(shape: ShapeGraph, program: Program, backend: Any, steps: int, seed: int,
              pace: float) -> dict[str, Timings]:
    """Time ``steps`` slider steps of each method, interleaved, at the same random values."""
    deformer = deformers()["cage"]
    compiled = compile_program(program, shape, backend)
    live = deformer.live(shape)
    rng = np.random.default_rng(seed)
    values = [{p.name: float(rng.uniform(p.lo, p.hi)) for p in program.parameters} for _ in range(steps)]
    live(compiled(values[-1]))  # weights cast and buffers allocated once, here
    deformer.vertices(shape, compiled(values[-1]))
    timings = {name: Timings() for name in ("evaluate", "new", "old", "old, BLAS threads")}
    pacer = Pacer(pace)
    def old(v: dict[str, float]) -> Any:
        return deformer.vertices(shape, compiled(v))

    def old_threads(v: dict[str, float]) -> Any:
        with default_blas_threads():
            return old(v)

    methods: dict[str, Callable[[dict[str, float]], Any]] = {
        "evaluate": compiled, "new": lambda v: live(compiled(v)), "old": old, "old, BLAS threads": old_threads}
    # Blocks of BLOCK steps per method in turn: the methods see the same machine, and each
    # block's scheduling reflects that method's own CPU use, as a client using only it would
    # see. OpenBLAS's own threads spin for a while after each product and would take CPU
    # from the others: their steps run last, at every 10th value.
    runs = [(name, v) for start in range(0, len(values), BLOCK) for name in ("evaluate", "new", "old")
            for v in values[start:start + BLOCK]]
    runs += [("old, BLAS threads", v) for v in values[::10]]
    for name, v in runs:
        pacer.wait()
        timings[name].time(lambda step=methods[name], v=v: step(v))
    return timings


def programs_for(shape: ShapeGraph) -> dict[str, Program]:
    """The part-op program and, when the chair's relations are detected, one that re-lays out a group."""
    programs = {"part ops (10 ops, 2 params)": Program.from_text(PART_OPS)}
    groups = [r for r in shape.relations.values() if r.kind == "translation"]
    if groups:
        g = groups[0]
        text = PART_OPS + (f"scale_1d({g.id}, origin=(0, 0.625, -0.19), dir=(1, 0, 0), amount=x)\n"
                           f"change_count({g.id}, mode='top_down', amount=4 * x)\n")
        programs[f"+ {g.id} re-laid out (change_count)"] = Program.from_text(text)
    return programs


def print_table(name: str, phases: dict[str, dict[str, Timings]], goal: float) -> None:
    header = "".join(f"{phase:>30}" for phase in phases)
    print(f"\n{name}\n{'method':<22}{header}")
    print(f"{'':<22}" + f"{'median':>10}{'p95':>10}{'cpu':>10}" * len(phases))
    for method in ("evaluate", "new", "old", "old, BLAS threads"):
        cells = "".join(f"{t[method].median():>8.2f}ms{t[method].p95():>8.2f}ms{t[method].cpu_median():>8.2f}ms"
                        for t in phases.values())
        print(f"{method:<22}{cells}")
    for method in ("old", "old, BLAS threads"):
        cells = "".join(f"{t[method].median() / t['new'].median():>9.1f}x{t[method].p95() / t['new'].p95():>9.1f}x"
                        f"{t[method].cpu_median() / t['new'].cpu_median():>9.1f}x" for t in phases.values())
        print(f"{method + ' / new':<22}{cells}")
    loaded = list(phases.values())[-1]["new"].median()
    print(f"goal: new step median <= {goal:g} ms under load: {loaded:.2f} ms, {'ok' if loaded <= goal else 'over'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[100_000])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--backend", default=None, help="CAS backend for compile_program (default: configured)")
    parser.add_argument("--load", type=int, default=os.cpu_count() or 1, metavar="N",
                        help="busy processes in the loaded half (default: one per CPU; 0: no loaded half)")
    parser.add_argument("--same-session", action="store_true",
                        help="run the busy processes in the benchmark's session (default: each in its own)")
    parser.add_argument("--pace", type=float, default=60.0, metavar="HZ",
                        help="steps per second, the process idle in between (default 60; 0: back to back)")
    args = parser.parse_args()
    backend = get_cas_backend(args.backend)
    pace = f"paced at {args.pace:g} Hz" if args.pace > 0 else "back to back"
    where = "in the benchmark's session" if args.same_session else "each in its own session"
    print(f"CAS backend {backend.name}; {args.steps} steps per method and phase at random slider values "
          f"({args.steps // 10} for 'old, BLAS threads'), {pace}; {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f} before the run; load generator: {args.load} x `python -c {BUSY_LOOP!r}`, "
          f"{where}")
    for target in args.vertices:
        shape = dense_chair(target)
        vertices = sum(len(p.mesh.vertices) for p in shape.parts.values())
        goal = 5.0 if vertices <= 200_000 else 10.0
        print(f"\n== chair, {len(shape.parts)} parts, {vertices:,} vertices")
        for seed, (name, program) in enumerate(programs_for(shape).items()):
            phases = {"no load": run_phase(shape, program, backend, args.steps, seed, args.pace)}
            if args.load:
                with cpu_load(args.load, args.same_session):
                    phases[f"{args.load} busy processes"] = run_phase(shape, program, backend, args.steps, seed,
                                                                         args.pace)
            print_table(name, phases, goal)
    print("\nevaluate: CompiledProgram(values) alone; new, old: evaluate + deform (the step); cpu: the process's "
          "CPU time\nper step; ratios: old / new of median, p95 and cpu")


if __name__ == "__main__":
    main()
