"""Watertight remeshing: fields, the designed gap case on the chair, labels, exporters, bad input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from parsel_core.errors import ParselError
from parsel_core.plugins import exporter_for
from parsel_core.program import Program, evaluate
from parsel_core.relations import Attachment
from parsel_mesh.deform import deformed_meshes
from parsel_mesh.examples import example_path
from parsel_mesh.loaders import load_mesh_shape, shape_from_meshes
from parsel_mesh.testing import box_mesh
from parsel_remesh.exporters import WatertightPLYExporter
from parsel_remesh.remesh import remesh
from parsel_remesh.sdf import part_field

#: The designed extreme edit: the seat and back rise, the legs are held where they are.
RAISE_SEAT = """\
param x in [0, 0.3] default 0.2
translate(seat, dir=(0, 1, 0), amount=x)
translate(back_rail, dir=(0, 1, 0), amount=x)
translate('back_upright.000', dir=(0, 1, 0), amount=x)
translate('back_upright.001', dir=(0, 1, 0), amount=x)
""" + "".join(f"translate('back_slat.00{i}', dir=(0, 1, 0), amount=x)\n" for i in range(5)) + \
    "".join(f"keep_fixed('leg.00{i}')\n" for i in range(4))


@pytest.fixture(scope="module")
def chair():
    """The bundled chair with its seat-leg attachments (detected relations are not needed here)."""
    shape = load_mesh_shape(example_path("chair"))
    attachments = []
    for i in range(4):
        leg = shape.parts[f"leg.00{i}"].hexahedron.corners
        top = leg[[2, 3, 6, 7]].mean(axis=0)  # centre of the leg's top face (v = 1)
        from parsel_core.cage import point_weights

        attachments.append(Attachment(f"seat_leg_{i}", (f"leg.00{i}", "seat"),
                                      weights_a=tuple(map(tuple, point_weights(leg, top[None]))),
                                      weights_b=tuple(map(tuple, point_weights(shape.parts["seat"].hexahedron.corners,
                                                                               top[None])))))
    return shape.with_relations(attachments)


def stacked_boxes():
    meshes = {"top": box_mesh((0, 0.3, 0), (0.4, 0.35, 0.4)), "post": box_mesh((0.15, 0, 0.15), (0.25, 0.3, 0.25))}
    shape = shape_from_meshes(meshes, name="stool")
    post = shape.parts["post"].hexahedron.corners
    contact = post[[2, 3, 6, 7]].mean(axis=0)
    from parsel_core.cage import point_weights

    attach = Attachment("post_top", ("post", "top"), weights_a=tuple(map(tuple, point_weights(post, contact[None]))),
                        weights_b=tuple(map(tuple, point_weights(shape.parts["top"].hexahedron.corners,
                                                                 contact[None]))))
    return shape.with_relations([attach])


def components(mesh) -> int:
    return len(mesh.split(only_watertight=False))


def test_box_field_is_the_signed_distance():
    mesh = box_mesh((0, 0, 0), (1, 0.5, 0.25))
    corners = np.asarray(mesh.vertices)
    field = part_field(corners, mesh.vertices, mesh.faces, spacing=0.02)
    assert field.band == pytest.approx(0.06)  # 3 cells of exact distance, clamped beyond
    uvw = np.array([[0.5, 0.5, 0.5], [0.5, 0.5, 0.9], [0.98, 0.5, 0.5], [1.02, 0.5, 0.5], [0.5, 2.0, 0.5]])
    np.testing.assert_allclose(field.sample(uvw), [-0.06, -0.025, -0.02, 0.02, 0.06], atol=1e-9)


def test_stacked_boxes_gap_is_bridged():
    shape = stacked_boxes()
    program = Program.from_text("translate(top, dir=(0, 1, 0), amount=x)\nkeep_fixed(post)")
    evaluation = evaluate(program, shape, {"x": 0.5})
    plain = trimesh.util.concatenate(list(deformed_meshes(shape, evaluation).values()))
    assert components(plain) == 2
    assert components(remesh(shape, evaluation, resolution=64, bridge=False).mesh) == 2
    result = remesh(shape, evaluation, resolution=64)
    assert result.mesh.is_watertight and components(result.mesh) == 1
    assert result.bridges == [{"relation": "post_top", "moved": "post", "gap": pytest.approx(0.5)}]
    assert result.mesh.bounds[1][1] == pytest.approx(0.85, abs=0.02)


def test_the_designed_gap_on_the_chair(chair):
    """Seat raised 20 cm over legs held in place: the plain meshes fall apart, the remesh is one closed piece."""
    evaluation = evaluate(Program.from_text(RAISE_SEAT), chair, {"x": 0.2})
    plain = trimesh.util.concatenate(list(deformed_meshes(chair, evaluation).values()))
    assert components(plain) == len(chair.parts)  # 13 separate part meshes
    legs = [plain_leg for name, plain_leg in deformed_meshes(chair, evaluation).items() if name.startswith("leg")]
    seat_bottom = deformed_meshes(chair, evaluation)["seat"].bounds[0][1]
    assert seat_bottom - max(leg.bounds[1][1] for leg in legs) > 0.19  # the visible gap
    unbridged = remesh(chair, evaluation, resolution=128, bridge=False)
    assert components(unbridged.mesh) == 5  # the four legs stay apart from the rest
    result = remesh(chair, evaluation, resolution=128)
    assert result.mesh.is_watertight and result.mesh.is_volume
    assert components(result.mesh) == 1
    assert sorted(b["moved"] for b in result.bridges) == [f"leg.00{i}" for i in range(4)]
    # labels: every label is there, faces low down are legs, faces at the seat's height are seat
    assert result.labels == ["back_rail", "back_slat", "back_upright", "leg", "seat"]
    centres = result.mesh.triangles_center
    assert set(result.face_labels[centres[:, 1] < 0.3]) == {"leg"}
    assert (result.face_labels[np.abs(centres[:, 1] - 0.63) < 0.01] == "seat").mean() > 0.8


def test_rest_shape_remeshes_to_one_closed_piece(chair):
    result = remesh(chair, resolution=128)
    assert result.mesh.is_watertight and components(result.mesh) == 1
    assert result.bridges == []


def test_exporters_are_chosen_by_double_suffix(tmp_path, monkeypatch):
    monkeypatch.setenv("PARSEL_REMESH_RESOLUTION", "48")
    shape = stacked_boxes()
    evaluation = evaluate(Program.from_text("translate(top, dir=(0, 1, 0), amount=x)\nkeep_fixed(post)"), shape,
                          {"x": 0.3})
    for suffix in (".watertight.obj", ".watertight.ply", ".watertight.glb"):
        path = tmp_path / f"stool{suffix}"
        exporter = exporter_for(shape, path)
        assert exporter.name == "watertight-" + suffix.rsplit(".", 1)[1]
        exporter.export(shape, evaluation, path)
        mesh = trimesh.load(path, force="mesh", process=False)
        if suffix != ".watertight.glb":  # GLB stores per-vertex data, so trimesh splits label seams on reading
            assert mesh.is_watertight and components(mesh) == 1, suffix
    assert exporter_for(shape, tmp_path / "plain.obj").name == "mesh-obj"
    from parsel_core.loading import load_shape

    reread = load_shape(str(tmp_path / "stool.watertight.ply"), detect=False)
    assert sorted(reread.parts) == ["post", "top"]  # faces labelled per part label


def test_bad_output_paths_leave_nothing(tmp_path):
    shape = stacked_boxes()
    exporter = WatertightPLYExporter()
    with pytest.raises(ParselError, match="output directory .* does not exist"):
        exporter.export(shape, None, tmp_path / "missing" / "a.watertight.ply")
    with pytest.raises(ParselError, match="is a directory"):
        (tmp_path / "d.watertight.ply").mkdir()
        exporter.export(shape, None, tmp_path / "d.watertight.ply")
    with pytest.raises(ParselError, match="resolution"):
        remesh(shape, None, resolution=2)
    assert [p.name for p in tmp_path.iterdir()] == ["d.watertight.ply"]
