"""Mesh exporters: a loaded GLB exports back through the core with the same part names and meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.part import Part
from parsel_core.plugins import exporter_for, exporters
from parsel_core.program import Evaluation, Program, evaluate
from parsel_mesh.deform import deformed_meshes
from parsel_mesh.examples import example_path
from parsel_mesh.exporters import GLBExporter, MeshExporter, OBJExporter, PLYExporter
from parsel_mesh.loaders import load_mesh_shape

PROGRAM = """\
param x in [0, 1] default 0.5
scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)
translate(face('leg.000', 'v+'), dir=(-1, 0, 0), amount=0.05 * x)
"""


@pytest.fixture(scope="module")
def chair() -> ShapeGraph:
    return load_mesh_shape(example_path("chair"))


def _rest(shape: ShapeGraph) -> Evaluation:
    return Evaluation(shape.rest_corners())


def test_exporters_are_registered():
    registered = exporters()
    assert isinstance(registered["mesh-glb"], GLBExporter)
    assert isinstance(registered["mesh-obj"], OBJExporter)
    assert isinstance(registered["mesh-ply"], PLYExporter)
    assert "hexahedra-obj" in registered  # the core's box exporter is still there for bare shapes


def test_a_loaded_glb_exports_back_with_the_same_part_names_and_meshes(chair, tmp_path):
    path = tmp_path / "chair.glb"
    exporter = exporter_for(chair, path)
    assert exporter.name == "mesh-glb"
    exporter.export(chair, _rest(chair), path)
    again = load_mesh_shape(path)
    assert list(again.parts) == list(chair.parts)
    for pid, part in chair.parts.items():
        reloaded = again.parts[pid]
        assert reloaded.name == part.name and reloaded.label == part.label
        np.testing.assert_allclose(np.asarray(reloaded.mesh.vertices), np.asarray(part.mesh.vertices), atol=1e-6)
        np.testing.assert_array_equal(reloaded.mesh.faces, part.mesh.faces)
        assert reloaded.mesh.visual.material.name == part.mesh.visual.material.name
        np.testing.assert_allclose(reloaded.hexahedron.corners, part.hexahedron.corners, atol=1e-6)


@pytest.mark.parametrize(("suffix", "name", "tolerance"), [(".glb", "mesh-glb", 1e-6), (".obj", "mesh-obj", 0.0),
                                                           (".ply", "mesh-ply", 0.0)])
def test_edited_meshes_round_trip(chair, tmp_path, suffix, name, tolerance):
    evaluation = evaluate(Program.from_text(PROGRAM), chair, {"x": 0.7})
    expected = deformed_meshes(chair, evaluation)
    path = tmp_path / f"edited{suffix}"
    exporter = exporter_for(chair, path)
    assert exporter.name == name
    exporter.export(chair, evaluation, path)
    again = load_mesh_shape(path)
    assert list(again.parts) == list(chair.parts)
    for pid, mesh in expected.items():
        np.testing.assert_allclose(np.asarray(again.parts[pid].mesh.vertices), mesh.vertices, atol=tolerance, rtol=0)
    assert not np.allclose(expected["seat"].vertices, chair.parts["seat"].mesh.vertices)


def test_ply_keeps_face_colours(chair, tmp_path):
    path = tmp_path / "c.ply"
    PLYExporter().export(chair, None, path)
    seat = load_mesh_shape(path).parts["seat"].mesh
    assert seat.visual.face_colors[0].tolist() == [196, 150, 104, 255]


def test_group_instances_are_exported_by_name(tmp_path, row_shape):
    shape = row_shape
    evaluation = evaluate(Program.from_text("change_count(row, amount=1)"), shape)
    path = tmp_path / "row.glb"
    GLBExporter().export(shape, evaluation, path)
    assert list(load_mesh_shape(path).parts) == [f"slat_0#{i}" for i in range(4)]


def test_can_export_needs_meshes(chair):
    bare = ShapeGraph([Part("top", "top", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1)))], name="bare")
    for exporter in (GLBExporter(), OBJExporter(), PLYExporter()):
        assert exporter.can_export(chair)
        assert not exporter.can_export(bare)
    assert exporter_for(bare, Path("bare.obj")).name == "hexahedra-obj"


def test_shape_without_meshes_is_an_error(tmp_path):
    bare = ShapeGraph([Part("top", "top", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1)))], name="bare")
    with pytest.raises(ParselError, match="part\\(s\\) 'top' have no mesh"):
        GLBExporter().export(bare, _rest(bare), tmp_path / "bare.glb")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("exporter", [GLBExporter(), OBJExporter(), PLYExporter()], ids=lambda e: e.name)
def test_missing_output_directory_is_named(chair, tmp_path, exporter):
    target = tmp_path / "missing" / f"out{exporter.extensions[0]}"
    with pytest.raises(ParselError, match="output directory .*missing does not exist") as info:
        exporter.export(chair, _rest(chair), target)
    assert str(target) in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_a_failed_export_leaves_the_old_file_and_no_temporary(chair, tmp_path, monkeypatch):
    path = tmp_path / "chair.glb"
    path.write_bytes(b"previous")

    def fail(self, shape, meshes):
        raise RuntimeError("encoder crashed")

    monkeypatch.setattr(GLBExporter, "encode", fail)
    with pytest.raises(RuntimeError):
        GLBExporter().export(chair, _rest(chair), path)
    assert path.read_bytes() == b"previous"
    assert [p.name for p in tmp_path.iterdir()] == ["chair.glb"]


@pytest.mark.parametrize("exporter", [GLBExporter(), OBJExporter(), PLYExporter()], ids=lambda e: e.name)
def test_files_are_written_atomically(chair, tmp_path, monkeypatch, exporter):
    import parsel_mesh.exporters as module

    calls = []
    monkeypatch.setattr(module, "atomic_write_bytes", lambda path, data: calls.append((Path(path), len(data))))
    target = tmp_path / f"out{exporter.extensions[0]}"
    exporter.export(chair, _rest(chair), target)
    assert calls and calls[0][0] == target and calls[0][1] > 0
    assert not target.exists()


def test_exporters_share_one_base(chair):
    assert all(isinstance(e, MeshExporter) for e in (GLBExporter(), OBJExporter(), PLYExporter()))


def test_glb_export_keeps_the_node_hierarchy(tmp_path):
    """chair -> {seat, legs -> {leg.000, leg.001}}, the legs group moved by its node transform."""
    import trimesh

    from parsel_mesh.testing import box_mesh

    scene = trimesh.Scene()
    scene.graph.update(frame_from=scene.graph.base_frame, frame_to="chair", matrix=np.eye(4))
    moved = trimesh.transformations.translation_matrix((0, 0, 0.5))
    scene.graph.update(frame_from="chair", frame_to="legs", matrix=moved)
    scene.add_geometry(box_mesh((-0.5, 0.4, 0), (0.5, 0.5, 1)), node_name="seat", geom_name="seat",
                       parent_node_name="chair")
    for i, x in enumerate((-0.4, 0.3)):
        scene.add_geometry(box_mesh((x, 0, -0.1), (x + 0.1, 0.4, 0.1)), node_name=f"leg.00{i}", geom_name=f"leg.00{i}",
                           parent_node_name="legs")
    source = tmp_path / "chair.glb"
    source.write_bytes(scene.export(file_type="glb"))
    shape = load_mesh_shape(source)
    legs = ["chair", "legs"]
    assert shape.metadata["hierarchy"] == {"seat": ["chair"], "leg.000": legs, "leg.001": legs}
    np.testing.assert_allclose(shape.parts["leg.000"].mesh.bounds, [(-0.4, 0, 0.4), (-0.3, 0.4, 0.6)])  # node moved it
    program = Program.from_text("param x in [0, 1] default 0\ntranslate('leg.000', dir=(1, 0, 0), amount=x)\n")
    out = tmp_path / "edited.glb"
    GLBExporter().export(shape, evaluate(program, shape, {"x": 0.2}), out)
    back = trimesh.load(out, force="scene")
    parents = back.graph.transforms.parents
    assert parents["seat"] == "chair" and parents["leg.000"] == parents["leg.001"] == "legs"
    assert parents["legs"] == "chair" and parents["chair"] == back.graph.base_frame
    reloaded = load_mesh_shape(out)
    assert reloaded.metadata["hierarchy"] == shape.metadata["hierarchy"]
    np.testing.assert_allclose(reloaded.parts["leg.000"].mesh.bounds, [(-0.2, 0, 0.4), (-0.1, 0.4, 0.6)], atol=1e-6)


@pytest.mark.parametrize(("loaded", "names", "kept"), [
    ({"seat": ["root"], "cushion": ["root", "seat"]}, ["seat", "cushion"],
     {"seat": ["root"], "cushion": ["root", "seat"]}),  # a part under another part
    ({"legs": ["legs"], "seat": []}, ["legs", "seat"], {"seat": []}),  # named after its mesh, like its parent node
    ({"seat": ["root"], "cushion": ["root", "x", "seat"]}, ["seat", "cushion"], {"seat": ["root"]}),  # a second 'seat'
    ({"seat": ["seat"], "cushion": ["seat"]}, ["seat", "cushion"], {}),  # dropping one path drops its descendants'
    ({"leg#1": ["legs"]}, ["leg#1"], {"leg#1": ["legs"]}),  # a part whose own name has '#'
    ({"slat": ["back"]}, ["slat#0", "slat#1"], {"slat#0": ["back"], "slat#1": ["back"]}),  # group instances
])
def test_glb_hierarchy_keeps_only_consistent_paths(loaded, names, kept):
    from types import SimpleNamespace

    from parsel_mesh.exporters import glb_hierarchy

    assert glb_hierarchy(SimpleNamespace(metadata={"hierarchy": loaded}), dict.fromkeys(names)) == kept


def test_a_part_named_like_its_parent_node_is_not_lost(tmp_path):
    import trimesh

    from parsel_mesh.testing import box_mesh

    scene = trimesh.Scene()
    scene.graph.update(frame_from=scene.graph.base_frame, frame_to="legs", matrix=np.eye(4))
    scene.add_geometry(box_mesh((0, 0, 0), (0.1, 0.4, 0.1)), node_name="geometry_5", geom_name="legs",
                       parent_node_name="legs")
    scene.add_geometry(box_mesh((-0.5, 0.4, -0.5), (0.5, 0.5, 0.5)), node_name="seat", geom_name="seat")
    source = tmp_path / "odd.glb"
    source.write_bytes(scene.export(file_type="glb"))
    shape = load_mesh_shape(source)
    assert sorted(shape.parts) == ["legs", "seat"]
    out = tmp_path / "out.glb"
    GLBExporter().export(shape, None, out)
    assert sorted(load_mesh_shape(out).parts) == ["legs", "seat"]
