"""Frame rate of the slider page in headless Chromium while a slider sweeps.

Each frame is one slider step (the page evaluates the program, deforms the parts whose
corners changed and uploads them) and one draw, read back by one pixel so that it is
fully drawn before the next step. Measured on the bundled chair and on the chair
subdivided to 100k vertices (as in ``bench_deform.py``), at two window sizes, with
Chromium's 60 Hz frame pacing on ("paced", what a display does) and off ("unpaced",
what the page and the rasteriser sustain). Prints, per case, the median over sweeps of
the frame rate and of the page's own work per frame (without the read-back).

Needs Playwright for Python and a Chromium (Debian's ``chromium``, or PARSEL_CHROMIUM).

    python benchmarks/bench_viewer.py [--sweeps 3] [--seconds 2] [--vertices 100000]
"""

from __future__ import annotations

import argparse
import statistics

from bench_deform import PART_OPS, dense_chair

from parsel_core.graph import ShapeGraph
from parsel_core.loading import load_shape
from parsel_core.program import Program
from parsel_view.page import PageServer
from parsel_view.scene import build_page_data
from parsel_view.testing import browser_problem, chromium_page

SIZES = ((640, 480), (1280, 720))


def measure(shape: ShapeGraph, program: Program, size: tuple[int, int], paced: bool, sweeps: int,
            seconds: float) -> dict[str, float]:
    """Median frame rate (each frame drawn) and median page work per frame (not waiting on pixels)."""
    with PageServer(build_page_data(program, shape), port=0) as server, \
            chromium_page(*size, paced=paced) as page:
        page.goto(server.url)
        page.wait_for_function("window.parsel && (window.parsel.ready || window.parsel.error)", timeout=120_000)
        if page.evaluate("window.parsel.error || null"):
            raise RuntimeError(page.evaluate("window.parsel.error"))
        ms = int(seconds * 1000)
        drawn = [page.evaluate(f"parsel.measureFps({ms}, true)") for _ in range(sweeps)]
        work = [page.evaluate(f"parsel.measureFps({ms}, false)") for _ in range(sweeps)]
    return {"fps": statistics.median(r["fps"] for r in drawn),
            "frame_ms": statistics.median(r["medianIntervalMs"] for r in drawn),
            "work_ms": statistics.median(r["meanWorkMs"] for r in work),
            "work_p95_ms": statistics.median(r["p95WorkMs"] for r in work)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--vertices", type=int, default=100_000)
    args = parser.parse_args()
    problem = browser_problem()
    if problem:
        raise SystemExit(f"bench_viewer: {problem}")

    program = Program.from_text(PART_OPS)
    shapes = {"bundled chair": load_shape("chair"), f"chair >= {args.vertices:,} vertices": dense_chair(args.vertices)}
    print(f"{args.sweeps} sweeps of {args.seconds:g} s per case; medians over sweeps\n")
    print("| asset | vertices | window | pacing | fps | frame | page work mean | page work p95 |")
    print("|---|---|---|---|---|---|---|---|")
    for name, shape in shapes.items():
        vertices = sum(len(part.mesh.vertices) for part in shape.parts.values())
        for size in SIZES:
            for paced in (True, False):
                r = measure(shape, program, size, paced, args.sweeps, args.seconds)
                print(f"| {name} | {vertices:,} | {size[0]}x{size[1]} | {'paced' if paced else 'unpaced'} "
                      f"| {r['fps']:.1f} | {r['frame_ms']:.1f} ms | {r['work_ms']:.2f} ms "
                      f"| {r['work_p95_ms']:.2f} ms |",
                      flush=True)


if __name__ == "__main__":
    main()
