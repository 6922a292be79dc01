"""Edited shapes written as ShapeAssembly programs: the written program executes back to them."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.loading import load_shape
from parsel_core.part import Part
from parsel_core.program import Evaluation, Program, evaluate
from parsel_shapeassembly.cuboids import fit_box
from parsel_shapeassembly.exporter import _executed_corners, _set_distance, export_program
from parsel_shapeassembly.interpreter import execute
from parsel_shapeassembly.parser import MIN_DIMENSION

FIXTURES = Path(__file__).parent / "fixtures"
PROGRAMS = sorted(FIXTURES.rglob("*.txt"))


def _round_trip_errors(shape, evaluation):
    """Largest corner error (fraction of the diagonal) of every written cuboid after execution."""
    result = export_program(shape, evaluation)
    got = _executed_corners(result.text)
    return result, {key: _set_distance(got[result.names[key]], corners) / shape.size
                    for key, corners in result.expected.items()}


@pytest.fixture
def chair(tmp_path) -> Path:
    target = tmp_path / "chair" / "1277.txt"
    target.parent.mkdir()
    shutil.copy(FIXTURES / "chair" / "1277.txt", target)
    return target


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_fixture_comes_back_at_rest(path):
    shape = load_shape(str(path))
    result, errors = _round_trip_errors(shape, Evaluation(shape.rest_corners()))
    assert set(errors) == set(shape.parts)
    assert max(errors.values()) < 1e-6, {k: e for k, e in errors.items() if e >= 1e-6}
    assert not result.non_cuboids
    # the written program keeps the source's hierarchy and leaf names
    assert set(result.names.values()) == set(shape.parts)


def test_the_chair_uses_the_macros_and_its_hierarchy(chair):
    shape = load_shape(str(chair))
    text = export_program(shape, Evaluation(shape.rest_corners())).text
    assert text.startswith("Assembly Program_0 {\n\tbbox = Cuboid(")
    assert "Assembly Program_1 {" in text and "Assembly Program_2 {" in text
    assert "reflect(cube0, X)" in text and "reflect(cube1, X)" in text  # the legs
    assert "translate(cube1, X, 4, 0.757)" in text  # the back's slats, as in the source
    assert "\tProgram_2 = Cuboid(" in text and ", False)" in text  # the tilted back: one rotated sub-program


def test_an_edit_comes_back_and_the_cli_writes_a_loadable_program(chair, tmp_path, capsys):
    program = tmp_path / "wide.parsel"
    program.write_text("scale_1d(cube1, origin=(0.0, 0.0, 0.0), dir=(1, 0, 0), amount=x)\n"
                       "translate('Program_2/cube0', dir=(0, 1, 0), amount=0.1 * x)\n", encoding="utf-8")
    shape = load_shape(str(chair))
    edited = evaluate(Program.from_text(program.read_text()), shape, {"x": 0.3})
    _, errors = _round_trip_errors(shape, edited)
    assert max(errors.values()) < 1e-9
    out = tmp_path / "edited.sa.txt"
    assert main(["apply", str(chair), str(program), "--set", "x=0.3", "-o", str(out)]) == 0
    back = load_shape(str(out), detect=False)
    assert set(back.parts) == set(shape.parts)
    for pid, part in back.parts.items():
        assert _set_distance(part.hexahedron.corners, np.asarray(edited.parts[pid])) < 1e-9 * shape.size
    capsys.readouterr()
    assert main(["apply", str(chair), str(program), "--sweep", "3", "-o", str(tmp_path / "s.sa.txt")]) == 0
    assert sorted(p.name for p in tmp_path.glob("s_*.sa.txt")) == ["s_000.sa.txt", "s_001.sa.txt", "s_002.sa.txt"]
    widths = [np.ptp(load_shape(str(tmp_path / f"s_{i:03d}.sa.txt"), detect=False).parts["cube1"]
                     .hexahedron.corners[:, 0]) for i in range(3)]
    assert widths[0] < widths[1] < widths[2]


def test_a_changed_count_is_written_as_translate(chair):
    shape = load_shape(str(chair))
    group = next(r.id for r in shape.relations.values() if r.kind == "translation" and len(r.members) == 5)
    program = Program.from_text(f"change_count({group}, mode='top_down', amount=2 * x)")
    edited = evaluate(program, shape, {"x": 1.0})
    assert len(edited.instances[group]) == 7
    result, errors = _round_trip_errors(shape, edited)
    assert "translate(cube1, X, 6, " in result.text
    assert sum(key.startswith(f"{group}[") for key in errors) == 7
    assert max(errors.values()) < 1e-9


def test_a_taper_is_written_as_its_best_fitting_cuboid_and_reported():
    box = Hexahedron.from_box((0, 0, 0), (2, 2, 2))
    shape = ShapeGraph([Part("block.1", "block", box)], name="one")
    program = Program.from_text('scale_1d(face("block.1", "v+"), origin=(0, 1, 0), dir=(1, 0, 0), amount=-0.5)', )
    edited = evaluate(program, shape, {})
    result = export_program(shape, edited)
    # bottom corners at x = +-1, top at +-0.5: the least-squares cuboid is 1.5 wide, 0.25 from each corner
    assert result.non_cuboids["block.1"] == pytest.approx(0.25, abs=1e-6)
    (cuboid,) = execute(result.text).cuboids
    assert cuboid.name == "block_1"
    assert np.allclose(sorted(cuboid.dims), [1.5, 2.0, 2.0], atol=1e-6)
    assert any("block.1: not a cuboid" in note for note in result.notes())


def test_a_single_box_gives_the_hand_computed_program():
    shape = ShapeGraph([Part("box", "box", Hexahedron.from_box((0.1, 0.0, 0.0), (0.2, 0.4, 0.6)))], name="one")
    text = export_program(shape, Evaluation(shape.rest_corners())).text
    # the root box is centred at the origin and holds the part; the part rests on its bottom
    assert text == ("Assembly Program_0 {\n\tbbox = Cuboid(0.4, 0.4, 0.6, True)\n"
                    "\tbox = Cuboid(0.2, 0.4, 0.6, True)\n\tattach(box, bbox, 0.5, 0, 0.5, 0.75, 0, 0.5)\n}\n")


def test_a_rotated_box_comes_back():
    from scipy.spatial.transform import Rotation

    axes = Rotation.from_rotvec([0.2, 0.5, -0.3]).as_matrix().T
    box = Hexahedron.from_box((0.05, 0.1, -0.2), (0.3, 0.5, 0.2), axes)
    shape = ShapeGraph([Part("a", "a", box), Part("b", "b", Hexahedron.from_box((0, -0.5, 0), (1, 0.1, 1)))])
    _, errors = _round_trip_errors(shape, Evaluation(shape.rest_corners()))
    assert max(errors.values()) < 1e-7


def test_fit_box_recovers_a_rotated_box():
    from scipy.spatial.transform import Rotation

    axes = Rotation.from_rotvec([0.4, -0.1, 0.7]).as_matrix()
    corners = Hexahedron.from_box((1, 2, 3), (0.5, 1.0, 2.0), axes).corners
    box, deviation = fit_box(corners)
    assert deviation < 1e-12
    assert np.allclose(box.dims, [0.5, 1.0, 2.0]) and np.allclose(box.center, [1, 2, 3])


def test_nothing_to_write_is_an_error():
    shape = ShapeGraph([Part("a", "a", Hexahedron.from_box((0, 0, 0), (1, 1, 1)))])
    with pytest.raises(ParselError, match="nothing to write"):
        export_program(shape, Evaluation(shape.rest_corners(), removed=frozenset({"a"})))


def test_a_rotation_too_small_for_the_interpreter_gets_a_turned_block():
    from scipy.spatial.transform import Rotation

    # 1e-4 rad: the interpreter's float32 cosine of it is 1, so two attachments cannot make it
    axes = Rotation.from_rotvec([0.0, 0.0, 1e-4]).as_matrix().T
    shape = ShapeGraph([Part("slab", "slab", Hexahedron.from_box((0.0, 0.2, 0.0), (1.0, 0.05, 0.4), axes)),
                        Part("post", "post", Hexahedron.from_box((0.0, -0.2, 0.0), (0.1, 0.7, 0.1)))])
    result, errors = _round_trip_errors(shape, Evaluation(shape.rest_corners()))
    assert max(errors.values()) < 1e-7 and not result.inexact
    assert result.names["slab"] == "Program_slab_turn/slab"
    assert "Assembly Program_slab_turn {" in result.text


def test_a_part_squashed_flat_is_written_with_a_positive_thickness(tmp_path):
    shape = ShapeGraph([Part("board", "board", Hexahedron.from_box((0, 0.5, 0), (1.0, 0.1, 0.5))),
                        Part("post", "post", Hexahedron.from_box((0, 0.0, 0), (0.1, 0.9, 0.1)))])
    program = Program.from_text("scale_1d(board, origin=(0, 0.5, 0), dir=(0, 1, 0), amount=-1)")
    result, errors = _round_trip_errors(shape, evaluate(program, shape, {}))
    assert max(errors.values()) <= MIN_DIMENSION  # the flat side is written as thin as the interpreter takes
    (board,) = [c for c in execute(result.text).cuboids if c.name == "board"]
    assert min(board.dims) == pytest.approx(MIN_DIMENSION)
