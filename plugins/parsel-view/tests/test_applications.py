"""The slider page of a composed (proxydural) program shows every slider."""

import json

import pytest

from parsel_core.cli import main
from parsel_view.testing import browser_problem, chromium_page


@pytest.fixture(scope="module")
def proxydural(tmp_path_factory):
    out = tmp_path_factory.mktemp("proxy") / "out"
    assert main(["proxydural", "chair", "-n", "3", "-o", str(out)]) == 0
    page = out.parent / "proxy.html"
    assert main(["view", str(out), "--html", str(page), "--no-browser"]) == 0
    return out, page


def test_proxydural_page_carries_one_parameter_per_request(proxydural):
    out, page = proxydural
    names = [p["name"] for p in json.loads((out / "program.json").read_text())["parameters"]]
    assert names == ["x1", "x2", "x3"]
    html = page.read_text()
    assert all(f'"{name}"' in html for name in names)


def test_proxydural_page_shows_every_slider_in_a_browser(proxydural):
    problem = browser_problem()
    if problem:
        pytest.skip(problem)
    _, page_file = proxydural
    with chromium_page(640, 480) as page:
        page.goto(page_file.as_uri())
        page.wait_for_function("window.parsel && (window.parsel.ready || window.parsel.error)", timeout=60_000)
        assert page.evaluate("window.parsel.error || null") is None
        ids = page.evaluate("Array.from(document.querySelectorAll('input[type=range]')).map(e => e.id)")
        assert ids == ["slider-x1", "slider-x2", "slider-x3"]
        before = page.evaluate("parsel.vertices('seat').slice(0, 3)")
        page.locator("#slider-x1").fill("1")
        page.wait_for_timeout(200)
        assert page.evaluate("parsel.vertices('seat').slice(0, 3)") != before
