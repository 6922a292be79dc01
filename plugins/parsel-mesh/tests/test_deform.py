"""The cage deformer: exact on cages, affine edits stay affine, cached weights, group instances."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from parsel_core.cage import inverse_trilinear
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.loading import load_shape
from parsel_core.part import Part
from parsel_core.plugins import deformers, get_cas_backend
from parsel_core.program import Program, compile_program, evaluate
from parsel_mesh import deform
from parsel_mesh.deform import CageDeformer, LiveDeformation, cage_weights_of, deformed_meshes, deformed_vertices
from parsel_mesh.examples import CHAIR_ALL_PART_OPS, example_path
from parsel_mesh.loaders import load_mesh_shape, shape_from_meshes
from parsel_mesh.testing import box_mesh

CAGE_PROGRAM = """\
param x in [0, 1] default 0.5
translate(face(box, 'u+'), dir=(1, 0, 0), amount=0.3 * x)
scale_1d(box, origin=(0, 0, 0), dir=(0, 1, 0), amount=x)
translate(corner(box, 'u-v+w+'), dir=(0, 0, 1), amount=0.2 * x)
rotate(tilted, origin=(0, 0, 0), axis=(0, 0, 1), amount=0.4 * x)
translate(face(tilted, 'v+'), dir=(0, 1, 0), amount=x)
"""


def _tilted_box() -> trimesh.Trimesh:
    mesh = box_mesh((1.0, 0.0, 0.0), (1.5, 0.2, 0.3))
    mesh.apply_transform(np.vstack([np.hstack([Rotation.from_euler("xyz", [20, 30, 40], degrees=True).as_matrix(),
                                               np.zeros((3, 1))]), [0, 0, 0, 1]]))
    return mesh


@pytest.fixture
def cage_shape() -> ShapeGraph:
    return shape_from_meshes({"box": box_mesh((0, 0, 0), (1, 0.5, 0.25)), "tilted": _tilted_box()}, name="cages")


@pytest.fixture(scope="module")
def chair() -> ShapeGraph:
    return load_mesh_shape(example_path("chair"))


def _corner_of_each_vertex(shape: ShapeGraph, pid: str) -> np.ndarray:
    rest = shape.parts[pid].hexahedron.corners
    vertices = np.asarray(shape.parts[pid].mesh.vertices)
    distance = np.linalg.norm(vertices[:, None, :] - rest[None], axis=2)
    assert distance.min(axis=1).max() < 1e-12  # every vertex is a corner
    return distance.argmin(axis=1)


@pytest.mark.parametrize("x", [0.0, 0.37, 1.0])
def test_a_mesh_that_is_its_own_cage_follows_the_corners_exactly(cage_shape, x):
    program = Program.from_text(CAGE_PROGRAM)
    evaluation = evaluate(program, cage_shape, {"x": x})
    moved = deformed_vertices(cage_shape, evaluation)
    for pid in ("box", "tilted"):
        corners = np.asarray(evaluation.parts[pid])
        np.testing.assert_allclose(moved[pid], corners[_corner_of_each_vertex(cage_shape, pid)], atol=1e-12)


def test_compiled_evaluation_deforms_alike(cage_shape):
    program = Program.from_text(CAGE_PROGRAM)
    compiled = compile_program(program, cage_shape, get_cas_backend())
    a = deformed_vertices(cage_shape, compiled({"x": 0.8}))
    b = deformed_vertices(cage_shape, evaluate(program, cage_shape, {"x": 0.8}))
    for pid in a:
        np.testing.assert_allclose(a[pid], b[pid], atol=1e-12)


AFFINE_PROGRAM = """\
param x in [0, 1] default 0.5
scale_3d(seat, origin=(0, 0.43, 0), amount=0.5 * x)
rotate(seat, origin=(0, 0.43, 0), axis=(0, 1, 0), amount=0.6 * x)
shear('leg.000', origin=(0, 0, 0), normal=(0, 1, 0), dir=(1, 0, 0), amount=0.3 * x)
scale_1d('back_slat.002', origin=(0, 0.45, -0.19), dir=(0, 1, 0), amount=x)
"""


@pytest.mark.parametrize("x", [0.25, 1.0])
def test_affine_edits_keep_meshes_inside_their_edited_boxes(chair, x):
    program = Program.from_text(AFFINE_PROGRAM)
    evaluation = evaluate(program, chair, {"x": x})
    moved = deformed_vertices(chair, evaluation)
    for pid in ("seat", "leg.000", "back_slat.002"):
        corners = np.asarray(evaluation.parts[pid])
        uvw = inverse_trilinear(corners, moved[pid])
        assert uvw.min() > -1e-9 and uvw.max() < 1 + 1e-9, pid
        # an affine edit of the cage is the same affine map of every vertex
        rest = chair.parts[pid].hexahedron.corners
        homogeneous = np.hstack([rest, np.ones((8, 1))])
        affine, *_ = np.linalg.lstsq(homogeneous, corners, rcond=None)
        vertices = np.asarray(chair.parts[pid].mesh.vertices)
        np.testing.assert_allclose(moved[pid], np.hstack([vertices, np.ones((len(vertices), 1))]) @ affine,
                                   atol=1e-12)


def test_unedited_parts_stay_put(chair):
    evaluation = evaluate(Program.from_text(AFFINE_PROGRAM), chair, {"x": 1.0})
    moved = deformed_vertices(chair, evaluation)
    np.testing.assert_allclose(moved["leg.003"], np.asarray(chair.parts["leg.003"].mesh.vertices), atol=1e-12)


def test_weights_are_computed_once_per_shape_and_part(cage_shape, monkeypatch):
    calls = []
    original = deform.point_weights

    def counting(corners, points):
        calls.append(len(points))
        return original(corners, points)

    monkeypatch.setattr(deform, "point_weights", counting)
    program = Program.from_text(CAGE_PROGRAM)
    for x in (0.1, 0.5, 0.9):
        deformed_vertices(cage_shape, evaluate(program, cage_shape, {"x": x}))
    assert len(calls) == 2
    assert cage_weights_of(cage_shape, "box") is cage_weights_of(cage_shape, "box")
    assert cage_weights_of(cage_shape, "box").shape == (8, 8)


def test_changed_groups_replicate_the_first_member(row_shape):
    shape = row_shape
    evaluation = evaluate(Program.from_text("change_count(row, amount=2)"), shape)
    instances = evaluation.instances["row"]
    assert len(instances) == 5
    meshes = CageDeformer().deform(shape, evaluation)
    assert sorted(meshes) == [f"slat_0#{i}" for i in range(5)]
    for i in range(5):
        np.testing.assert_allclose(meshes[f"slat_0#{i}"].vertices, instances[i], atol=1e-12)
        np.testing.assert_array_equal(meshes[f"slat_0#{i}"].faces, shape.parts["slat_0"].mesh.faces)


def test_deform_returns_meshes_with_faces_and_materials(chair):
    deformer = deformers()["cage"]
    assert isinstance(deformer, CageDeformer)
    evaluation = evaluate(Program.from_text(AFFINE_PROGRAM), chair, {"x": 0.5})
    meshes = deformer.deform(chair, evaluation)
    assert list(meshes) == list(chair.parts)
    seat = meshes["seat"]
    assert isinstance(seat, trimesh.Trimesh)
    np.testing.assert_array_equal(seat.faces, chair.parts["seat"].mesh.faces)
    assert seat.visual.material.name == "seat"
    assert chair.parts["seat"].mesh.visual.material.name == "seat"  # the source mesh is untouched
    np.testing.assert_allclose(deformer.vertices(chair, evaluation)["seat"], seat.vertices)


def test_rest_shape_when_no_evaluation(cage_shape):
    meshes = deformed_meshes(cage_shape)
    np.testing.assert_allclose(meshes["box"].vertices, cage_shape.parts["box"].mesh.vertices, atol=1e-15)


def test_batched_evaluation_is_refused(cage_shape):
    evaluation = evaluate(Program.from_text(CAGE_PROGRAM), cage_shape, {"x": np.array([0.1, 0.2])})
    with pytest.raises(ParselError, match="batch of parameter values"):
        deformed_vertices(cage_shape, evaluation)


def test_parts_without_meshes_are_named():
    shape = ShapeGraph([Part("top", "top", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1)))], name="bare")
    with pytest.raises(ParselError, match="part 'top' has no mesh"):
        CageDeformer().deform(shape, evaluate(Program.from_text("translate(top, amount=x)"), shape))


def test_cage_products_run_on_one_blas_thread_and_restore_the_pool(monkeypatch):
    """Many BLAS threads make the memory-bound products slower on a busy machine
    (benchmarks/bench_deform.py --load); the limit holds only for the call."""
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController()
    seen = []
    real = deform._corners
    monkeypatch.setattr(deform, "_corners", lambda evaluation, pid: seen.append(
        [info["num_threads"] for info in controller.select(user_api="blas").info()]) or real(evaluation, pid))
    shape = load_mesh_shape(example_path("chair"))
    evaluation = evaluate(Program.from_text("scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)"),
                          shape, {"x": 0.5})
    with controller.limit(limits=2, user_api="blas"):
        vertices = deformed_vertices(shape, evaluation)
        after = [info["num_threads"] for info in controller.select(user_api="blas").info()]
    assert seen and all(threads == [1] * len(threads) for threads in seen)
    assert after == [2] * len(after)
    seat = shape.parts["seat"]
    np.testing.assert_allclose(vertices["seat"], cage_weights_of(shape, "seat") @ evaluation.parts["seat"])
    assert len(vertices["seat"]) == len(seat.mesh.vertices)


def _reference(shape: ShapeGraph, evaluation) -> dict[str, np.ndarray]:
    """Straightforward evaluation: each vertex's weights solved afresh, times its part's corners, in float64."""
    from parsel_core.cage import cage_weights

    out = {}
    replaced = {m for group in evaluation.instances for m in shape.relation(group).members}
    for pid, part in shape.parts.items():
        weights = cage_weights(inverse_trilinear(part.hexahedron.corners, np.asarray(part.mesh.vertices)))
        if pid not in replaced:
            out[pid] = weights @ np.asarray(evaluation.parts[pid])
        for group, instances in evaluation.instances.items():
            if shape.relation(group).members[0] == pid:
                out.update({f"{pid}#{i}": weights @ corners for i, corners in enumerate(instances)})
    return out


def _assert_close_relative(got: dict[str, np.ndarray], expected: dict[str, np.ndarray], rtol: float) -> None:
    assert sorted(got) == sorted(expected)
    for name, vertices in expected.items():
        scale = np.abs(vertices).max()
        error = np.abs(np.asarray(got[name], dtype=float) - vertices).max()
        assert error <= rtol * scale, (name, error / scale)


CHAIR_GROUP_PROGRAM = CHAIR_ALL_PART_OPS + (
    "change_count(translation_0, mode='top_down', amount=4 * x)\n")


@pytest.mark.parametrize("text", [CHAIR_ALL_PART_OPS, CHAIR_GROUP_PROGRAM], ids=["part ops", "group re-laid out"])
def test_live_deformation_matches_a_reference_evaluation(chair, text):
    """float32 buffers, skipped parts and the affine shortcut stay within 1e-6 of the float64 cage map."""
    shape = load_shape("chair") if "translation_0" in text else chair  # load_shape detects the slats' group
    program = Program.from_text(text)
    live = CageDeformer().live(shape)
    for values in ({"x": 0.3, "y": -0.2}, {"x": 0.3, "y": 0.4}, {"x": 0.9, "y": 0.4}, {"x": 0.0, "y": 0.0}):
        evaluation = evaluate(program, shape, values)
        moved = live(evaluation)
        assert all(v.dtype == np.float32 and not v.flags.writeable for v in moved.values())
        _assert_close_relative(moved, _reference(shape, evaluation), rtol=1e-6)


@pytest.mark.parametrize("order", ["F", "C"])
def test_live_deformation_in_float64_equals_the_deformer(chair, order):
    program = Program.from_text(CHAIR_ALL_PART_OPS)
    live = CageDeformer().live(chair, dtype=np.float64, order=order)
    for x in (0.2, 0.7):
        evaluation = evaluate(program, chair, {"x": x, "y": 0.1})
        moved, expected = live(evaluation), deformed_vertices(chair, evaluation)
        for pid in expected:
            assert moved[pid].flags[f"{order}_CONTIGUOUS"] and moved[pid].shape == expected[pid].shape
            np.testing.assert_allclose(moved[pid], expected[pid], rtol=0, atol=1e-12)


def test_live_deformation_layouts_agree(chair):
    """Interleaved ("C") and per-coordinate ("F") buffers hold the same float32 vertices."""
    program = Program.from_text(CHAIR_GROUP_PROGRAM)
    shape = load_shape("chair")
    by_coordinate, interleaved = CageDeformer().live(shape), CageDeformer().live(shape, order="C")
    for values in ({"x": 0.3, "y": -0.2}, {"x": 0.9, "y": 0.4}):
        evaluation = evaluate(program, shape, values)
        f, c = by_coordinate(evaluation), interleaved(evaluation)
        assert sorted(f) == sorted(c)
        for name in f:
            assert f[name].flags.f_contiguous and c[name].flags.c_contiguous
            np.testing.assert_allclose(f[name], c[name], rtol=1e-6, atol=1e-6)


def test_live_deformation_refuses_an_unknown_layout(chair):
    with pytest.raises(ValueError, match="order must be 'C' or 'F'"):
        CageDeformer().live(chair, order="K")


def test_the_trilinear_and_affine_products_agree(chair, monkeypatch):
    """Every part through the cage coordinates (no edit counts as affine) gives the same vertices."""
    program = Program.from_text(CHAIR_ALL_PART_OPS)
    evaluation = evaluate(program, chair, {"x": 0.6, "y": 0.3})
    mixed = {k: v.copy() for k, v in CageDeformer().live(chair)(evaluation).items()}
    monkeypatch.setattr(deform, "AFFINE_TOLERANCE", -1.0)
    trilinear = CageDeformer().live(chair)(evaluation)
    _assert_close_relative(trilinear, {k: v.astype(float) for k, v in mixed.items()}, rtol=1e-6)
    _assert_close_relative(trilinear, _reference(chair, evaluation), rtol=1e-6)


def test_live_deformation_recomputes_only_parts_whose_corners_moved(chair, monkeypatch):
    program = Program.from_text(CHAIR_ALL_PART_OPS)
    live = CageDeformer().live(chair)
    first = live(evaluate(program, chair, {"x": 0.5, "y": 0.1}))
    products: list[int] = []
    real = LiveDeformation._deform
    monkeypatch.setattr(LiveDeformation, "_deform",
                        lambda self, cage, corners, out: products.append(len(out)) or real(self, cage, corners, out))
    again = live(evaluate(program, chair, {"x": 0.5, "y": 0.1}))
    assert products == [] and all(again[k] is first[k] for k in first)  # same values: nothing to do
    # y moves leg.002, leg.003 and a corner of the seat (back_rail follows max(x, y) = x)
    evaluation = evaluate(program, chair, {"x": 0.5, "y": 0.3})
    moved = live(evaluation)
    assert sorted(products) == sorted(len(chair.parts[p].mesh.vertices) for p in ("leg.002", "leg.003", "seat"))
    _assert_close_relative(moved, _reference(chair, evaluation), rtol=1e-6)


def test_live_deformation_follows_group_counts(row_shape):
    program = Program.from_text("param n in [-2, 3] default 0\nchange_count(row, amount=n)")
    live = CageDeformer().live(row_shape)
    for n in (2, -1, 0, 3):
        evaluation = evaluate(program, row_shape, {"n": n})
        moved = live(evaluation)
        assert sorted(moved) == sorted(_reference(row_shape, evaluation))
        _assert_close_relative(moved, _reference(row_shape, evaluation), rtol=1e-6)


def test_live_deformation_refuses_batches(cage_shape):
    evaluation = evaluate(Program.from_text(CAGE_PROGRAM), cage_shape, {"x": np.array([0.1, 0.2])})
    with pytest.raises(ParselError, match="batch of parameter values"):
        CageDeformer().live(cage_shape)(evaluation)
