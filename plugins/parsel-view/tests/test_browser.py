"""The slider page in headless Chromium: a slider moves the vertices as the program says, fast.

Needs Playwright for Python and Debian's ``chromium`` (``/usr/bin/chromium``; no browser
is downloaded). Where either is missing the tests skip and say which. Set
``PARSEL_SCREENSHOT_DIR`` to keep the screenshot (docs/screenshots/ holds one).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from parsel_core.program import Program, evaluate
from parsel_mesh.deform import deformed_vertices
from parsel_view.page import PageServer, write_html
from parsel_view.scene import build_page_data
from parsel_view.testing import browser_problem, chromium_page

from .conftest import CHAIR_PROGRAM

pytestmark = pytest.mark.skipif(browser_problem() is not None, reason=str(browser_problem()))

#: The frame rate a slider must keep: a common display's refresh.
REFRESH_HZ = 60.0


def open_page(page, url: str) -> None:
    page.goto(url)
    page.wait_for_function("window.parsel && (window.parsel.ready || window.parsel.error)", timeout=60_000)
    assert page.evaluate("window.parsel.error || null") is None
    assert page.evaluate("window.parsel.ready") is True
    assert page.parsel_errors == []


def page_vertices(page, name: str) -> np.ndarray:
    return np.array(page.evaluate("(n) => parsel.vertices(n)", name)).reshape(-1, 3)


def test_moving_a_slider_moves_the_vertices_as_the_program_says(chair, tmp_path):
    program = Program.from_text(CHAIR_PROGRAM)
    with PageServer(build_page_data(program, chair), port=0) as server, chromium_page(1000, 680) as page:
        open_page(page, server.url)
        assert page.locator("input[type=range]").count() == 2  # one slider per parameter
        before = {name: page_vertices(page, name) for name in ("seat", "leg.000", "leg.001")}
        page.locator("#slider-x").fill("0.8")  # a user moving the slider: input events, no server call
        page.locator("#slider-y").fill("-0.3")
        values = page.evaluate("parsel.values()")
        assert values == pytest.approx({"x": 0.8, "y": -0.3})
        assert page.locator("#values").text_content() == "x = 0.800, y = -0.300"
        expected = deformed_vertices(chair, evaluate(program, chair, values))
        assert sorted(page.evaluate("parsel.names()")) == sorted(expected)
        for name, vertices in expected.items():
            np.testing.assert_allclose(page_vertices(page, name), vertices, atol=2e-7, err_msg=name)
        for name, old in before.items():
            assert np.abs(page_vertices(page, name) - old).max() > 0.01, f"{name} did not move"
        # the seat got wider by the program's factor: scale_1d about x = 0 by 1 + x
        seat_x = page_vertices(page, "seat")[:, 0]
        rest_x = np.asarray(chair.parts["seat"].mesh.vertices)[:, 0]
        assert np.ptp(seat_x) == pytest.approx(np.ptp(rest_x) * 1.8, rel=1e-3)

        # hover: the part under the pointer is named in the tooltip
        hit = page.evaluate("""() => { for (let y = 100; y < 680; y += 10) for (let x = 300; x < 1000; x += 10) {
            const found = parsel.labelAt(x, y); if (found && found.label === 'seat') return [x, y]; } return null; }""")
        assert hit is not None
        page.mouse.move(hit[0], hit[1])
        page.wait_for_function("!document.getElementById('tooltip').hidden", timeout=10_000)
        assert page.locator("#tooltip").text_content() == "seat (seat)"
        shot = tmp_path / "chair_slider.png"
        page.screenshot(path=str(shot))
        if os.environ.get("PARSEL_SCREENSHOT_DIR"):
            shutil.copy(shot, Path(os.environ["PARSEL_SCREENSHOT_DIR"]) / "chair_slider.png")
        assert page.parsel_errors == []


def test_group_instances_follow_the_slider(row_shape, tmp_path):
    program = Program.from_text("param x in [0, 1] default 0\n"
                                "scale_1d(row, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)\n"
                                "change_count(row, mode='top_down', amount=4 * x)\n")
    html = write_html(build_page_data(program, row_shape), tmp_path / "row.html")
    with chromium_page() as page:
        open_page(page, html.as_uri())  # the self-contained file works from disk
        page.locator("#slider-x").fill("0.5")
        expected = deformed_vertices(row_shape, evaluate(program, row_shape, {"x": 0.5}))
        assert sorted(page.evaluate("parsel.names()")) == sorted(expected) == [f"slat_0#{i}" for i in range(6)]
        for name, vertices in expected.items():
            np.testing.assert_allclose(page_vertices(page, name), vertices, atol=2e-7)
        page.locator("#slider-x").fill("0")
        assert len(page.evaluate("parsel.names()")) == 4


CULLING = """() => { const gl = document.getElementById('view').getContext('webgl2');
    parsel.drawNow(); return gl.isEnabled(gl.CULL_FACE); }"""


def test_back_faces_are_culled_unless_an_edit_mirrors_a_part(chair):
    """The chair's closed meshes are drawn front faces only; a seat scaled inside out is drawn whole."""
    program = Program.from_text("param x in [-3, 1] default 0\n"
                                "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)\n")
    with PageServer(build_page_data(program, chair), port=0) as server, chromium_page(640, 480) as page:
        open_page(page, server.url)
        assert page.evaluate(CULLING) is True
        page.locator("#slider-x").fill("-2")
        assert page.evaluate(CULLING) is False
        seat_x = page_vertices(page, "seat")[:, 0]
        assert np.ptp(seat_x) == pytest.approx(np.ptp(np.asarray(chair.parts["seat"].mesh.vertices)[:, 0]), rel=1e-3)
        page.locator("#slider-x").fill("0.5")
        assert page.evaluate(CULLING) is True
        assert page.parsel_errors == []


def test_frame_rate_on_the_bundled_chair(chair):
    """Sweep the slider, one slider step and one frame per animation frame.

    The browser runs without frame pacing (see ``UNPACED_FLAGS``), so an animation
    frame comes as soon as the previous frame has been drawn and presented: the measured
    rate is the rate the page sustains on whatever WebGL the machine has (SwiftShader
    on a CPU box). It must be >= 60 fps: the median of three 2 s sweeps, so one window
    disturbed by another process does not decide. The page's own work per frame
    (evaluation, deformation, upload, draw calls) must fit a 60 Hz frame. A sweep that
    also reads a pixel back every frame (waiting until it is drawn) is reported.
    """
    program = Program.from_text(CHAIR_PROGRAM)
    with PageServer(build_page_data(program, chair), port=0) as server, chromium_page(640, 480) as page:
        open_page(page, server.url)
        renderer = page.evaluate("""() => { const gl = document.getElementById('view').getContext('webgl2');
            const info = gl.getExtension('WEBGL_debug_renderer_info');
            return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER); }""")
        updates = page.evaluate("parsel.updates()")
        sweeps = [page.evaluate("parsel.measureFps(2000, false)") for _ in range(3)]
        drawn = page.evaluate("parsel.measureFps(2000, true)")
        updates = page.evaluate("parsel.updates()") - updates
    rates = [sweep["fps"] for sweep in sweeps]
    median = sweeps[rates.index(sorted(rates)[1])]
    report = (f"chair slider: {median['fps']:.1f} fps, median of {', '.join(f'{r:.1f}' for r in rates)} "
              f"(median frame {median['medianIntervalMs']:.1f} ms; page work per frame mean "
              f"{median['meanWorkMs']:.2f} ms, p95 {median['p95WorkMs']:.2f} ms); {drawn['fps']:.1f} fps when each "
              f"frame is read back; WebGL: {renderer}")
    print(report)
    assert updates == sum(sweep["frames"] for sweep in sweeps) + drawn["frames"]  # every frame was a slider step
    assert median["p95WorkMs"] <= 1000 / REFRESH_HZ, report
    assert median["fps"] >= REFRESH_HZ, report


def test_a_plugin_operator_moves_on_the_slider_page(chair, tmp_path):
    """The twist example plugin's op: its generated point map moves the legs' vertices as Python does."""
    from .test_opjs import twist_program

    program = twist_program()
    html = write_html(build_page_data(program, chair), tmp_path / "twist.html")
    with chromium_page() as page:
        open_page(page, html.as_uri())
        before = page_vertices(page, "leg.000")
        page.locator("#slider-x").fill("0.7")
        values = page.evaluate("parsel.values()")
        expected = deformed_vertices(chair, evaluate(program, chair, values))
        for name in ("leg.000", "seat"):
            np.testing.assert_allclose(page_vertices(page, name), expected[name], atol=2e-7, err_msg=name)
        assert np.abs(page_vertices(page, "leg.000") - before).max() > 0.01
        assert page.parsel_errors == []


def test_the_page_opens_at_rest_and_arrow_keys_move_one_percent(chair, tmp_path):
    """Default 0.5 in the program, but the page opens where every amount is zero: the shape as loaded."""
    program = Program.from_text("param x in [-3, 1] default 0.5\n"
                                "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)\n")
    html = write_html(build_page_data(program, chair), tmp_path / "rest.html")
    with chromium_page() as page:
        open_page(page, html.as_uri())
        assert page.evaluate("parsel.values()") == {"x": 0.0}
        np.testing.assert_allclose(page_vertices(page, "seat"), np.asarray(chair.parts["seat"].mesh.vertices),
                                   atol=2e-7)
        slider = page.locator("#slider-x")
        slider.focus()
        page.keyboard.press("ArrowRight")
        assert page.evaluate("parsel.values()")["x"] == pytest.approx(0.04)  # 1% of [-3, 1]
        page.keyboard.press("ArrowLeft")
        page.keyboard.press("ArrowLeft")
        assert page.evaluate("parsel.values()")["x"] == pytest.approx(-0.04)
        page.keyboard.press("End")
        assert page.evaluate("parsel.values()")["x"] == 1.0
        expected = deformed_vertices(chair, evaluate(program, chair, {"x": 1.0}))
        np.testing.assert_allclose(page_vertices(page, "seat"), expected["seat"], atol=2e-7)
        assert page.parsel_errors == []


def test_on_a_narrow_window_the_panel_sits_below_the_model(chair, tmp_path):
    program = Program.from_text(CHAIR_PROGRAM)
    html = write_html(build_page_data(program, chair), tmp_path / "narrow.html")
    with chromium_page(420, 760) as page:
        open_page(page, html.as_uri())
        boxes = page.evaluate("""() => { const r = (id) => document.getElementById(id).getBoundingClientRect();
            const v = r('view'), p = r('panel'); return {viewBottom: v.bottom, panelTop: p.top, panelBottom: p.bottom,
            width: window.innerWidth, height: window.innerHeight}; }""")
        assert boxes["panelTop"] >= boxes["viewBottom"] and boxes["panelBottom"] <= boxes["height"]
        assert boxes["viewBottom"] >= 0.6 * boxes["height"]  # the model keeps most of the window
        page.locator("summary").click()  # the program text wraps instead of being clipped
        assert page.evaluate("(() => { const pre = document.getElementById('program'); "
                             "return pre.scrollWidth <= pre.clientWidth + 1; })()")
        assert page.parsel_errors == []
