"""Scene data the page receives: meshes, their cage coordinates and flags."""

from __future__ import annotations

import trimesh

from parsel_mesh.loaders import shape_from_meshes
from parsel_mesh.testing import box_mesh
from parsel_view.scene import mesh_data


def test_meshes_are_marked_closed_only_when_their_back_faces_never_show(chair):
    assert all(mesh["closed"] for mesh in mesh_data(chair))  # the bundled chair's parts are closed volumes
    quad = trimesh.Trimesh([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0.1)], [(0, 1, 2), (0, 2, 3)], process=False)
    box = box_mesh((0, 0, 0), (1, 1, 1))
    inside_out = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    shape = shape_from_meshes({"quad": quad, "box": box, "inside_out": inside_out}, name="mixed")
    assert {m["id"]: m["closed"] for m in mesh_data(shape)} == {"quad": False, "box": True, "inside_out": False}
