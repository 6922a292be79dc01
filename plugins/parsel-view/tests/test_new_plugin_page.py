"""The plugin guide's path for a new operator, in one process: `parsel new-plugin taper` writes the
package, its operator registers, passes the conformance kit, propagates with AEP, renders, and moves
on the slider page (Node and headless Chromium) as Python says."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from parsel_core import api
from parsel_core.cli import main
from parsel_core.plugins import solvers
from parsel_core.program import evaluate
from parsel_core.scaffold import write_plugin
from parsel_core.testing import check_plugin
from parsel_mesh.deform import deformed_vertices
from parsel_view.page import write_html
from parsel_view.scene import build_page_data
from parsel_view.testing import browser_problem, chromium_page, node_path

SEED = "taper('leg.000', origin=(-0.19, 0, 0.18), axis=(0, 1, 0), amount=x)"


@pytest.fixture
def taper(tmp_path, parsel_register):
    write_plugin("taper", tmp_path / "parsel-taper")
    spec = importlib.util.spec_from_file_location("parsel_taper", tmp_path / "parsel-taper" / "parsel_taper" /
                                                  "__init__.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["parsel_taper"] = module
    spec.loader.exec_module(module)
    parsel_register(module, name="taper")
    yield module
    sys.modules.pop("parsel_taper", None)


@pytest.mark.skipif("aep" not in solvers(), reason="needs the AEP solver (plugins/parsel-aep)")
def test_a_new_taper_operator_everywhere(taper, chair, tmp_path, capsys):
    passed, failed, skipped = check_plugin("taper")
    assert failed == [] and skipped == []

    # AEP tapers the other three legs to keep the symmetries; nothing breaks
    result = api.edit("chair", seed=SEED)
    program = result.program
    assert [op.operand for op in program.ops] == ["leg.000", "leg.001", "leg.002", "leg.003"]
    assert {op.name for op in program.ops} == {"taper"} and result.report.counts()["broken"] == 0
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "program.json").write_text(program.to_json(), encoding="utf-8")
    assert main(["render", "chair", str(tmp_path / "out" / "program.json"), "-o", str(tmp_path / "t.png")]) == 0
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    page = build_page_data(program, chair)
    assert [op["generated"] for op in page.scene["ops"]] == [True] * 4
    if node_path() is not None:
        from .test_page_eval import assert_same

        assert_same(program, chair, [{"x": 0.0}, {"x": 0.5}, {"x": 1.0}])
    if browser_problem() is not None:
        pytest.skip(str(browser_problem()))
    html = write_html(page, tmp_path / "taper.html")
    with chromium_page() as browser:
        browser.goto(html.as_uri())
        browser.wait_for_function("window.parsel && (window.parsel.ready || window.parsel.error)", timeout=60_000)
        assert browser.evaluate("window.parsel.error || null") is None
        browser.locator("#slider-x").fill("1")
        expected = deformed_vertices(chair, evaluate(program, chair, {"x": 1.0}))
        for name, vertices in expected.items():
            got = np.array(browser.evaluate("(n) => parsel.vertices(n)", name)).reshape(-1, 3)
            np.testing.assert_allclose(got, vertices, atol=2e-7, err_msg=name)
        top = expected["leg.000"][:, 1] > 0.4  # the top of the leg is narrower than its foot
        rest = np.asarray(chair.parts["leg.000"].mesh.vertices)
        assert np.ptp(expected["leg.000"][top, 0]) < 0.7 * np.ptp(rest[rest[:, 1] > 0.4, 0])
        assert browser.parsel_errors == []
