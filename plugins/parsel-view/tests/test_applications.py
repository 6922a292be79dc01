"""The slider page of a composed (proxydural) program shows every slider."""

import re

from parsel_core.cli import main


def test_proxydural_page_has_one_slider_per_request(tmp_path):
    out = tmp_path / "proxy"
    assert main(["proxydural", "chair", "-n", "3", "-o", str(out)]) == 0
    page = tmp_path / "proxy.html"
    assert main(["view", str(out), "--html", str(page), "--no-browser"]) == 0
    html = page.read_text()
    for name in ("x1", "x2", "x3"):
        assert re.search(rf'"{name}"', html), name
