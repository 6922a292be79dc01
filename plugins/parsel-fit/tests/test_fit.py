"""parsel fit: surface samples that follow edits, the Chamfer distance, parameter recovery, the command."""

import json

import numpy as np
import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.examples import WIDEN_TINY_TABLE
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.loading import load_shape
from parsel_core.part import Part
from parsel_core.program import Evaluation, Program, evaluate
from parsel_fit.chamfer import chamfer_distance
from parsel_fit.fit import fit_program
from parsel_fit.surface import SurfaceSampler
from parsel_fit.targets import load_target

TWO_SLIDERS = WIDEN_TINY_TABLE.replace("param x in [0, 0.5] default 0.25", "param x in [0, 0.5] default 0\n"
                                       "param y in [0, 0.4] default 0") + \
    "scale_1d(top, origin=(0, 0.75, 0), dir=(0, 1, 0), amount=4 * y)\n"


def _target(shape, program, values, noise, seed=7):
    """Samples of the edited shape drawn with another seed, plus Gaussian noise (fraction of the diagonal)."""
    points = SurfaceSampler.of(shape, 4096, seed).points(shape, evaluate(program, shape, values))
    rng = np.random.default_rng(seed)
    return points + rng.normal(scale=noise * shape.size, size=points.shape)


def test_chamfer_distance_by_hand():
    a = np.array([[0.0, 0.0, 0.0]])
    b = np.array([[1.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    # a -> b: 1; b -> a: (1 + 3) / 2 = 2; the mean of the two directions is 1.5
    assert chamfer_distance(a, b) == pytest.approx(1.5)
    assert chamfer_distance(b, b) == 0.0


def test_samples_stay_on_the_surface_of_the_edited_box():
    shape = ShapeGraph([Part("box", "box", Hexahedron.from_box((0, 0, 0), (2, 2, 2)))])
    sampler = SurfaceSampler.of(shape, 600, seed=3)
    program = Program.from_text("scale_1d(box, origin=(0, 0, 0), dir=(1, 0, 0), amount=x)")
    points = sampler.points(shape, evaluate(program, shape, {"x": 0.5}))
    assert len(points) == 600
    # the box is now [-1.5, 1.5] x [-1, 1]^2: every sample lies on one of its faces
    scaled = np.abs(points) / np.array([1.5, 1.0, 1.0])
    assert np.allclose(scaled.max(axis=1), 1.0)
    assert np.isclose(np.abs(points[:, 0]).max(), 1.5)


def test_one_parameter_is_recovered_from_a_noisy_target():
    shape = load_shape("tiny_table")
    program = Program.from_text(WIDEN_TINY_TABLE)
    target = _target(shape, program, {"x": 0.31}, noise=0.005)
    result = fit_program(shape, program, target)
    assert abs(result.values["x"] - 0.31) < 0.02 * 0.5  # within 2% of the range
    assert result.distance_after < result.distance_before
    assert result.start_values == {"x": 0.25} and result.evaluations > 10


def test_two_parameters_are_recovered():
    shape = load_shape("tiny_table")
    program = Program.from_text(TWO_SLIDERS)
    target = _target(shape, program, {"x": 0.12, "y": 0.3}, noise=0.005)
    result = fit_program(shape, program, target, starts=2, samples=1024)
    assert abs(result.values["x"] - 0.12) < 0.02 * 0.5
    assert abs(result.values["y"] - 0.3) < 0.02 * 0.4


def test_a_fixed_parameter_is_not_fitted():
    shape = load_shape("tiny_table")
    program = Program.from_text(TWO_SLIDERS)
    target = _target(shape, program, {"x": 0.12, "y": 0.3}, noise=0.0)
    result = fit_program(shape, program, target, starts=2, fixed={"y": 0.1})
    assert result.values["y"] == 0.1


def test_the_fit_is_never_worse_than_the_defaults():
    shape = load_shape("tiny_table")
    program = Program.from_text(WIDEN_TINY_TABLE)
    target = SurfaceSampler.of(shape, 2048, 5).points(shape, Evaluation(shape.rest_corners())) + 10.0
    result = fit_program(shape, program, target, starts=1, samples=512)
    assert result.distance_after <= result.distance_before


def test_targets_from_points_meshes_and_shapes(tmp_path):
    (tmp_path / "p.xyz").write_text("# x y z\n0 0 0\n1, 2, 3\n", encoding="utf-8")
    assert load_target(str(tmp_path / "p.xyz")).tolist() == [[0, 0, 0], [1, 2, 3]]
    np.save(tmp_path / "p.npy", np.ones((4, 3)))
    assert load_target(str(tmp_path / "p.npy")).shape == (4, 3)
    import trimesh

    trimesh.creation.box(extents=(2, 2, 2)).export(tmp_path / "box.ply")
    points = load_target(str(tmp_path / "box.ply"), count=500)
    assert points.shape == (500, 3) and np.allclose(np.abs(points).max(axis=1), 1.0)
    assert abs(load_target("tiny_table", count=1000).shape[0] - 1000) < 20  # rounded per part
    (tmp_path / "bad.xyz").write_text("1 2 three\n", encoding="utf-8")
    with pytest.raises(ParselError, match="bad.xyz: not a list of numbers"):
        load_target(str(tmp_path / "bad.xyz"))
    (tmp_path / "flat.xyz").write_text("1 2\n", encoding="utf-8")
    with pytest.raises(ParselError, match="flat.xyz: expected a non-empty list of 3D points"):
        load_target(str(tmp_path / "flat.xyz"))


def _widen_files(tmp_path):
    """The widening program and a noisy scan of tiny_table widened to x = 0.4, as files."""
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(WIDEN_TINY_TABLE, encoding="utf-8")
    target = _target(load_shape("tiny_table"), Program.from_text(WIDEN_TINY_TABLE), {"x": 0.4}, noise=0.002)
    np.savetxt(tmp_path / "target.xyz", target)
    return program_path, tmp_path / "target.xyz"


def test_fit_command_writes_the_fitted_program(tmp_path, capsys):
    program_path, target_path = _widen_files(tmp_path)
    out = tmp_path / "fitted.json"
    assert main(["fit", "tiny_table", str(program_path), str(target_path), "-o", str(out),
                 "--points", "2048"]) == 0
    printed = capsys.readouterr().out
    assert "Chamfer distance:" in printed and "at the defaults ->" in printed
    assert "(range [0, 0.5], was 0.25)" in printed
    data = json.loads(out.read_text())
    (parameter,) = data["parameters"]
    assert abs(parameter["default"] - 0.4) < 0.01 and parameter["lo"] == 0 and parameter["hi"] == 0.5
    assert data["metadata"]["fit"]["distance_after"] < data["metadata"]["fit"]["distance_before"]
    assert main(["apply", "tiny_table", str(out), "-o", str(tmp_path / "fitted.hex.json")]) == 0


def test_fit_command_errors_are_one_line_and_write_nothing(tmp_path, capsys):
    program_path = tmp_path / "widen.parsel"
    program_path.write_text(WIDEN_TINY_TABLE, encoding="utf-8")
    out = tmp_path / "fitted.json"
    assert main(["fit", "tiny_table", str(program_path), str(tmp_path / "missing.ply"), "-o", str(out)]) == 2
    assert "missing.ply: target file not found" in capsys.readouterr().err
    assert main(["fit", "tiny_table", str(program_path), "chair", "-o", str(tmp_path / "fitted.txt")]) == 2
    assert "written as JSON" in capsys.readouterr().err
    assert not out.exists()


def test_a_batch_case_with_a_target_is_fitted(tmp_path):
    from parsel_batch.cases import CaseFormatError, parse_case
    from parsel_batch.runner import run_case

    shape = load_shape("tiny_table")
    seed = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"
    plain = run_case(parse_case({"id": "plain", "shape": "tiny_table", "seed": seed}, base=tmp_path))
    program = Program.from_json(plain.files["program.json"])
    known = 0.6 * program.parameters[0].hi
    np.savetxt(tmp_path / "wide.xyz", _target(shape, program, {"x": known}, noise=0.0))
    case = parse_case({"id": "fit", "shape": "tiny_table", "seed": seed, "target": "wide.xyz"}, base=tmp_path)
    assert case.target == str(tmp_path / "wide.xyz")
    outcome = run_case(case)
    assert outcome.ok, outcome.record["error"]
    fit = outcome.record["fit"]
    assert fit["distance_after"] < fit["distance_before"]
    assert abs(fit["values"]["x"] - known) < 0.02 * program.parameters[0].hi
    fitted = json.loads(outcome.files["fitted.json"])
    assert "cpu_s" not in fitted["metadata"]["fit"]  # batch outputs stay reproducible
    assert fitted["parameters"][0]["default"] == fit["values"]["x"]
    missing = run_case(parse_case({"id": "gone", "shape": "tiny_table", "seed": seed, "target": "gone.ply"},
                                  base=tmp_path))
    assert not missing.ok and "gone.ply: target file not found" in missing.record["error"]["message"]
    with pytest.raises(CaseFormatError, match="'target' must be"):
        parse_case({"shape": "tiny_table", "seed": seed, "target": 3}, base=tmp_path)


def test_fit_command_prints_the_program_on_stdout_with_a_backend(tmp_path, capsys):
    program_path, target_path = _widen_files(tmp_path)
    argv = ["fit", "tiny_table", str(program_path), str(target_path), "--points", "1024",
            "--starts", "2"]
    assert main([*argv, "-o", "-", "--backend", "symengine", "--verbose"]) == 0
    captured = capsys.readouterr()
    fitted = Program.from_json(captured.out)  # stdout holds the program only
    assert abs(fitted.parameters[0].default - 0.4) < 0.02
    assert "Chamfer distance:" in captured.err and "fit start" in captured.err and "fit polish" in captured.err
    assert main(argv) == 0  # no -o: stdout as well
    # the numpy reference and the compiled backend agree to rounding
    assert Program.from_json(capsys.readouterr().out).parameters[0].default == pytest.approx(
        fitted.parameters[0].default, abs=1e-6)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["target.xyz", "widen.parsel"]


def test_a_fit_that_cannot_come_closer_says_why():
    """A slider that only widens cannot come closer to a narrower target: the fit stays at rest
    and says that x would have to go below its range."""
    shape = load_shape("tiny_table")
    widen = Program.from_text(WIDEN_TINY_TABLE.replace("default 0.25", "default 0"))
    narrow = Program.from_text("param x in [0, 1]\n"
                               "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=-0.3)\n")
    target = _target(shape, narrow, {"x": 1.0}, noise=0.0)
    result = fit_program(shape, widen, target, starts=2, samples=1024)
    assert not result.lowered and result.values == result.start_values == {"x": 0.0}
    assert "x is at the lower end of [0, 0.5]" in result.no_gain and "below the range" in result.no_gain
    # the same slider centred on the rest shape (amount k*(x - 0.5)) reaches the narrower top
    centred = Program.from_text("param x in [0, 1] default 0.5\n"
                                "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x - 0.5)\n")
    result = fit_program(shape, centred, target, starts=2, samples=1024)
    assert result.lowered and result.no_gain is None and abs(result.values["x"] - 0.2) < 0.03
