"""parsel view / parsel render: inputs, bad input as one-line errors, atomic output, the server."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.ops import Translate
from parsel_core.program import Program
from parsel_view import page as page_module
from parsel_view.inputs import read_inputs
from parsel_view.page import PageServer, render_html, write_html
from parsel_view.scene import build_page_data

from .conftest import CHAIR_PROGRAM


@pytest.fixture
def outdir(tmp_path: Path) -> Path:
    """What parsel edit writes: program.json with the shape's name in its metadata."""
    program = Program.from_text(CHAIR_PROGRAM)
    program = Program(program.ops, program.parameters, {"shape": "chair", "seed": "scale_1d(seat, ...)"})
    folder = tmp_path / "wide"
    folder.mkdir()
    (folder / "program.json").write_text(program.to_json(), encoding="utf-8")
    return folder


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(argv: list[str], capsys, pattern: str) -> str:
    code, out, err = run(argv, capsys)
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("parsel: error: "), err
    assert re.search(pattern, lines[0]), lines[0]
    return lines[0]


def test_html_page_is_self_contained(outdir, tmp_path, capsys):
    target = tmp_path / "page.html"
    code, out, _ = run(["view", str(outdir), "--html", str(target)], capsys)
    assert code == 0 and out.strip() == str(target)
    text = target.read_text(encoding="utf-8")
    assert "<script src=" not in text and "<link" not in text and "http://" not in text and "https://" not in text
    assert 'id="parsel-scene"' in text and "PARSEL_AMOUNTS" in text and "MiniGL" in text
    scene = json.loads(re.search(r'<script id="parsel-scene" type="application/json">(.*?)</script>', text,
                                 re.S).group(1))
    assert [p["name"] for p in scene["parameters"]] == ["x", "y"]
    assert {m["label"] for m in scene["meshes"]} == {"back_rail", "back_slat", "back_upright", "leg", "seat"}


def test_bad_inputs_give_one_line_errors_and_no_files(outdir, tmp_path, capsys):
    before = sorted(p.name for p in tmp_path.iterdir())
    one_line_error(["view", str(tmp_path / "missing"), "--html", str(tmp_path / "a.html")], capsys,
                   r"missing: no such file or directory")
    empty = tmp_path / "empty"
    empty.mkdir()
    before.append("empty")
    one_line_error(["view", str(empty), "--html", str(tmp_path / "a.html")], capsys, r"empty: directory has no program")
    one_line_error(["view", str(outdir), "--html", str(tmp_path / "a.png")], capsys, r"a\.png: the page is HTML")
    one_line_error(["view", str(outdir), "--html", str(tmp_path / "nodir" / "a.html")], capsys,
                   r"output directory .*nodir does not exist")
    one_line_error(["view", str(outdir), "--html", str(outdir / "program.json" / "a.html")], capsys,
                   r"does not exist")
    one_line_error(["view", str(outdir), "--shape", "table", "--html", str(tmp_path / "a.html")], capsys,
                   r"program\.json: does not match shape 'table': op 0 \(scale_1d\): shape 'table' has no part 'seat'")
    one_line_error(["view", str(outdir), "--shape", "nosuchshape", "--html", str(tmp_path / "a.html")], capsys,
                   r"nosuchshape")
    one_line_error(["render", "chair", str(outdir), "-o", str(tmp_path / "strip.bmp")], capsys,
                   r"strip\.bmp: unknown picture format '\.bmp'")
    one_line_error(["render", "chair", str(outdir), "-o", str(tmp_path / "nodir" / "strip.png")], capsys,
                   r"nodir does not exist")
    one_line_error(["render", "table", str(outdir), "-o", str(tmp_path / "strip.png")], capsys,
                   r"program\.json: does not match shape 'table'.*'seat'")
    one_line_error(["render", "chair", str(outdir), "-o", str(tmp_path / "strip.png"), "--frames", "0"], capsys,
                   r"--frames must be an integer from 1 to 24, got '0'")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(before)
    assert list(outdir.iterdir()) == [outdir / "program.json"]


def test_program_without_shape_metadata_needs_shape(tmp_path, capsys):
    path = tmp_path / "p.parsel"
    path.write_text("translate(seat, dir=(0, 1, 0), amount=x)\n", encoding="utf-8")
    one_line_error(["view", str(path), "--html", str(tmp_path / "a.html")], capsys, r"names no shape; pass --shape")
    code, _, _ = run(["view", str(path), "--shape", "chair", "--html", str(tmp_path / "a.html")], capsys)
    assert code == 0


@dataclass(frozen=True)
class Clamp(Translate):
    """An op of a plugin whose point map branches on the amount: no closed form to write in JavaScript."""

    name: ClassVar[str] = "clamp"

    def transform(self, points, amount, math):
        return points + (amount if amount > 0 else 0)


def test_programs_for_an_op_the_page_cannot_draw_are_named(chair):
    program = Program((Clamp("seat"),))
    with pytest.raises(ParselError, match=r"op 0 \(clamp on 'seat'\): clamp: transform cannot run on symbols "
                                          r"\(TypeError: .*\), so it has no JavaScript form; the slider page cannot"):
        build_page_data(program, chair)


def test_a_failed_write_leaves_no_file(outdir, tmp_path, monkeypatch):
    inputs = read_inputs([str(outdir)])
    page = build_page_data(inputs.program, inputs.shape)
    target = tmp_path / "page.html"
    target.write_text("old page", encoding="utf-8")

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(ParselError, match="page.html: cannot write: No space left on device"):
        write_html(page, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html", "wide"]
    assert target.read_text(encoding="utf-8") == "old page"


def test_server_serves_the_page_and_its_pieces_on_loopback(outdir):
    inputs = read_inputs([str(outdir)])
    page = build_page_data(inputs.program, inputs.shape)
    with PageServer(page, port=0) as server:
        assert server.url.startswith("http://127.0.0.1:")
        index = urllib.request.urlopen(server.url, timeout=10).read().decode()
        assert index == render_html(page, inline=False)
        for path in ("scene.json", "program.js", "static/minigl.js", "static/parsel_eval.js", "static/viewer.js",
                     "static/viewer.css"):
            assert urllib.request.urlopen(server.url + path, timeout=10).status == 200
        assert json.loads(urllib.request.urlopen(server.url + "scene.json", timeout=10).read())["shape"] == "chair"
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(server.url + "../etc/passwd", timeout=10)


def test_view_command_serves_until_stopped(outdir):
    process = subprocess.Popen([sys.executable, "-m", "parsel_core.cli", "view", str(outdir), "--port", "0",
                                "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        url = re.search(r"http://127\.0\.0\.1:\d+/", line).group(0)
        assert "2 slider(s)" in line
        assert "PARSEL_AMOUNTS" in urllib.request.urlopen(url + "program.js", timeout=10).read().decode()
    finally:
        process.terminate()
        process.wait(timeout=10)


def test_busy_port_is_a_one_line_error(outdir):
    inputs = read_inputs([str(outdir)])
    page = build_page_data(inputs.program, inputs.shape)
    with PageServer(page, port=0) as first:
        port = int(first.url.rsplit(":", 1)[1].strip("/"))
        with pytest.raises(ParselError, match=f"cannot serve on 127.0.0.1:{port}"):
            PageServer(page, port=port).start()


def test_static_files_cannot_end_an_inline_script():
    for name in page_module.STATIC_FILES:
        assert "</script" not in page_module.static_text(name).lower()


def test_server_answers_only_to_its_own_host_names(outdir):
    """A page of another site reaching 127.0.0.1 under its own name (DNS rebinding) gets nothing."""
    import http.client

    inputs = read_inputs([str(outdir)])
    with PageServer(build_page_data(inputs.program, inputs.shape), port=0) as server:
        port = int(server.url.rsplit(":", 1)[1].strip("/"))
        for host, status in ((f"127.0.0.1:{port}", 200), (f"localhost:{port}", 200), (f"LOCALHOST:{port}", 200),
                             (f"evil.example:{port}", 421), ("127.0.0.1", 421), ("", 421)):
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
            connection.putrequest("GET", "/scene.json", skip_host=True)
            if host:
                connection.putheader("Host", host)
            connection.endheaders()
            response = connection.getresponse()
            body = response.read()
            connection.close()
            assert response.status == status, host
            assert (b'"shape"' in body) == (status == 200)


@pytest.mark.parametrize("port", ["-1", "70000", "80", "1023"])
def test_ports_outside_1024_65535_are_one_line_errors(port, outdir, capsys):
    from parsel_core.cli import main

    assert main(["view", str(outdir), "--port", port, "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "choose a port from 1024 to 65535" in err
