"""parsel render: filmstrips of deformed meshes and of hexahedra, written atomically."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.program import Program
from parsel_view.render import draw_filmstrip, frame_geometry

from .conftest import CHAIR_PROGRAM, TABLE_PROGRAM


def test_chair_filmstrip(chair, tmp_path):
    path = draw_filmstrip(chair, Program.from_text(CHAIR_PROGRAM), tmp_path / "strip.png", frames=3)
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape[1] > 3 * image.shape[0] / 2  # a strip, wider than tall
    # the seat's green (tab20 index 4, "seat" is 5th of the sorted labels) is drawn
    assert np.any((image[..., 1] > 120) & (image[..., 0] < 90) & (image[..., 2] < 90))
    assert [p.name for p in tmp_path.iterdir()] == ["strip.png"]


def test_frames_sweep_the_chosen_parameter(chair):
    from parsel_core.program import evaluate

    program = Program.from_text(CHAIR_PROGRAM)
    seat = [frame_geometry(chair, evaluate(program, chair, {"x": x})).triangles for x in (0.0, 1.0)]
    width = [np.ptp(t.reshape(-1, 3)[:, 0]) for t in seat]
    assert width[1] > width[0]


def test_shapes_without_meshes_draw_hexahedra(parsel_shape, tmp_path, capsys):
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM + "change_count(slat_row, mode='top_down', amount=4 * x)\n",
                            encoding="utf-8")
    assert main(["render", "tiny_table", str(program_path), "-o", str(tmp_path / "table.svg"), "--frames", "2"]) == 0
    assert (tmp_path / "table.svg").read_text(encoding="utf-8").lstrip().startswith("<?xml")
    from parsel_core.program import evaluate

    program = Program.from_text(program_path.read_text(encoding="utf-8"))
    geometry = frame_geometry(parsel_shape, evaluate(program, parsel_shape, {"x": 0.5}))
    slats = geometry.labels.count("slat")
    assert slats == 12 * 6  # 4 slats + round(4 * 0.5) = 6 instances, 12 triangles each


@pytest.mark.parametrize("frames", [1, 2])
def test_single_and_few_frames(chair, tmp_path, frames):
    draw_filmstrip(chair, Program.from_text(CHAIR_PROGRAM), tmp_path / "s.pdf", frames=frames,
                   parameter="y", values={"x": 0.2})
    assert (tmp_path / "s.pdf").read_bytes().startswith(b"%PDF")


def test_remeshed_filmstrip(tmp_path):
    pytest.importorskip("parsel_remesh")
    from parsel_mesh.loaders import shape_from_meshes
    from parsel_mesh.testing import box_mesh

    shape = shape_from_meshes({"top": box_mesh((0, 0.3, 0), (0.4, 0.35, 0.4)),
                               "post": box_mesh((0.15, 0, 0.15), (0.25, 0.3, 0.25))}, name="stool")
    program = Program.from_text("translate(top, dir=(0, 1, 0), amount=0.2 * x)")
    draw_filmstrip(shape, program, tmp_path / "s.png", frames=2, remesh=True, remesh_options={"resolution": 40})
    assert (tmp_path / "s.png").read_bytes().startswith(b"\x89PNG")


def test_a_program_without_parameters_has_no_filmstrip(chair, tmp_path):
    program = Program((replace(Program.from_text(CHAIR_PROGRAM).ops[0], amount="0.2"),), ())
    with pytest.raises(ParselError, match="no parameter to draw a filmstrip across"):
        draw_filmstrip(chair, program, tmp_path / "strip.png")
    assert list(tmp_path.iterdir()) == []


def test_frames_fill_their_cells_and_labels_do_not_collide(chair, tmp_path):
    """Each of the 5 frames spans at least half of its fifth of the picture; the title sits alone in the top-left."""
    from matplotlib import image

    program = Program.from_text("param x in [0, 1]\nscale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)")
    path = draw_filmstrip(chair, program, tmp_path / "strip.png", frames=5)
    pixels = image.imread(str(path))[..., :3]
    height, width = pixels.shape[:2]
    ink = np.any(pixels < 0.9, axis=-1)
    cell = width // 5
    model_rows = slice(int(0.06 * height), int(0.8 * height))  # below the title, above the labels and legend
    for i in range(5):
        columns = np.flatnonzero(ink[model_rows, i * cell:(i + 1) * cell].any(axis=0))
        assert columns[-1] - columns[0] >= 0.5 * cell, f"frame {i} spans {columns[-1] - columns[0]} of {cell} px"
    title_rows = np.flatnonzero(ink[: int(0.06 * height), :].any(axis=1))
    title_columns = np.flatnonzero(ink[: int(0.06 * height), :].any(axis=0))
    assert len(title_rows) and title_columns[-1] < 0.1 * width  # only the title, at the left


def test_gif_filmstrip_frames_move(chair, tmp_path, capsys):
    program_path = tmp_path / "wide.parsel"
    program_path.write_text(CHAIR_PROGRAM, encoding="utf-8")
    out = tmp_path / "strip.gif"
    assert main(["render", "chair", str(program_path), "-o", str(out), "--frames", "4"]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    image = Image.open(out)
    assert image.format == "GIF" and image.n_frames == 6  # 4 forwards, 2 back (ends not repeated)
    assert image.info["loop"] == 0 and image.info["duration"] == 120
    frames = []
    for i in range(image.n_frames):
        image.seek(i)
        frames.append(np.asarray(image.convert("RGB"), dtype=int))
    assert np.abs(frames[0] - frames[3]).sum() > 0  # the shape moves between the ends of the range
    assert np.array_equal(frames[2], frames[4])  # played back: frame 4 repeats frame 2
    assert [p.name for p in tmp_path.iterdir() if p.name != "wide.parsel"] == ["strip.gif"]


def test_unknown_filmstrip_format_fails_before_loading(tmp_path, capsys):
    assert main(["render", "chair", "missing.json", "-o", str(tmp_path / "strip.mp4")]) == 2
    assert "unknown picture format '.mp4' (known: .gif, .pdf, .png, .svg)" in capsys.readouterr().err


def test_render_with_a_backend(tmp_path, capsys, monkeypatch):
    """``--backend`` compiles the program with that CAS backend; ``--verbose`` times each frame."""
    from parsel_core import program as program_module

    used = []
    original = program_module.compile_program
    monkeypatch.setattr(program_module, "compile_program",
                        lambda program, shape, backend: used.append(backend.name) or original(program, shape, backend))
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM, encoding="utf-8")
    out = tmp_path / "strip.png"
    assert main(["render", "tiny_table", str(program_path), "-o", str(out), "--frames", "2", "--backend", "sympy",
                 "--verbose"]) == 0
    captured = capsys.readouterr()
    assert used == ["sympy"] and Image.open(out).format == "PNG"
    assert "parsel: frame x = 0:" in captured.err and "sympy evaluation" in captured.err


def test_render_to_stdout_writes_the_picture_bytes(tmp_path, capfdbinary):
    """``-o - --format gif``: the picture's bytes on stdout, nothing on stderr with --quiet, no file."""
    import io

    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM, encoding="utf-8")
    assert main(["render", "tiny_table", str(program_path), "-o", "-", "--format", "gif", "--frames", "2",
                 "--quiet"]) == 0
    captured = capfdbinary.readouterr()
    assert Image.open(io.BytesIO(captured.out)).format == "GIF" and captured.err == b""
    assert main(["render", "tiny_table", str(program_path), "-o", "-"]) == 2
    assert b"-o -: name the format with --format" in capfdbinary.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["widen.parsel"]


@pytest.mark.parametrize("flag", ["-o", "--output", "--html"])  # --html: the old spelling
def test_view_page_to_stdout(tmp_path, capsys, flag):
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM, encoding="utf-8")
    assert main(["view", str(program_path), "--shape", "tiny_table", flag, "-"]) == 0
    out = capsys.readouterr().out
    assert out.lstrip().lower().startswith("<!doctype html>") and "</html>" in out
    assert [p.name for p in tmp_path.iterdir()] == ["widen.parsel"]


def test_view_writes_the_page_with_o_as_with_html(tmp_path, capsys):
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM, encoding="utf-8")
    assert main(["view", str(program_path), "--shape", "tiny_table", "-o", str(tmp_path / "a.html")]) == 0
    assert main(["view", str(program_path), "--shape", "tiny_table", "--html", str(tmp_path / "b.html")]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'a.html'}\n{tmp_path / 'b.html'}\n"
    assert (tmp_path / "a.html").read_text() == (tmp_path / "b.html").read_text()
    assert main(["view", str(program_path), "-o", "x.html", "--html", "y.html"]) == 2
    assert "not both" in capsys.readouterr().err


def test_render_without_o_writes_stdout_with_a_format(tmp_path, capfdbinary):
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(TABLE_PROGRAM, encoding="utf-8")
    assert main(["render", "tiny_table", str(program_path), "--format", "png", "--frames", "2", "--quiet"]) == 0
    captured = capfdbinary.readouterr()
    assert Image.open(__import__("io").BytesIO(captured.out)).format == "PNG" and captured.err == b""
    assert main(["render", "tiny_table", str(program_path)]) == 2
    assert b"no -o FILE: name an output file, or the format" in capfdbinary.readouterr().err
