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
from parsel_core.part import Part
from parsel_core.plugins import deformers, get_cas_backend
from parsel_core.program import Program, compile_program, evaluate
from parsel_mesh import deform
from parsel_mesh.deform import CageDeformer, cage_weights_of, deformed_meshes, deformed_vertices
from parsel_mesh.examples import example_path
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
