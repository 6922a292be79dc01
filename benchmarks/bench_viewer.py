"""Frame rate of the slider page in headless Chromium while a slider sweeps.

Each frame is one slider step (the page evaluates the program, deforms the parts whose
corners changed and uploads them) and one draw. Measured on the bundled chair and on
the chair subdivided to 100k vertices (as in ``bench_deform.py``), at two window sizes,
with Chromium's 60 Hz frame pacing on ("paced", what a display does) and off
("unpaced", what the page and the rasteriser sustain). Prints, per case, the median
over sweeps of the frame rate, of the median frame interval and of the page's own work
per frame, and the frame rate when every frame is also read back by one pixel (so that
it is finished before the next step).

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
    """Medians over sweeps: frame rate, frame interval, page work per frame; frame rate with read-back."""
    with PageServer(build_page_data(program, shape), port=0) as server, \
            chromium_page(*size, paced=paced) as page:
        page.goto(server.url)
        page.wait_for_function("window.parsel && (window.parsel.ready || window.parsel.error)", timeout=120_000)
        if page.evaluate("window.parsel.error || null"):
            raise RuntimeError(page.evaluate("window.parsel.error"))
        ms = int(seconds * 1000)
        plain = [page.evaluate(f"parsel.measureFps({ms}, false)") for _ in range(sweeps)]
        drawn = [page.evaluate(f"parsel.measureFps({ms}, true)") for _ in range(sweeps)]
    return {"fps": statistics.median(r["fps"] for r in plain),
            "frame_ms": statistics.median(r["medianIntervalMs"] for r in plain),
            "work_ms": statistics.median(r["meanWorkMs"] for r in plain),
            "work_p95_ms": statistics.median(r["p95WorkMs"] for r in plain),
            "fps_read_back": statistics.median(r["fps"] for r in drawn)}


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
    print("| asset | vertices | window | pacing | fps | frame | page work mean | page work p95 | fps, read back |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, shape in shapes.items():
        vertices = sum(len(part.mesh.vertices) for part in shape.parts.values())
        for size in SIZES:
            for paced in (True, False):
                r = measure(shape, program, size, paced, args.sweeps, args.seconds)
                print(f"| {name} | {vertices:,} | {size[0]}x{size[1]} | {'paced' if paced else 'unpaced'} "
                      f"| {r['fps']:.1f} | {r['frame_ms']:.1f} ms | {r['work_ms']:.2f} ms "
                      f"| {r['work_p95_ms']:.2f} ms | {r['fps_read_back']:.1f} |",
                      flush=True)


if __name__ == "__main__":
    main()
