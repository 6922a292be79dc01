"""Every format reads back its part names; labels, sidecars, PartNet; bad input is a one-line ParselError."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from parsel_core.errors import ParselError
from parsel_core.loading import load_shape
from parsel_mesh.exporters import encode_obj, encode_ply
from parsel_mesh.loaders import load_mesh_shape, shape_from_meshes, split_obj
from parsel_mesh.testing import box_mesh, named_scene

NAMES = ["back_slat_2", "leg.000", "leg.001", "Seat"]
LABELS = {"Seat": "seat", "leg.000": "leg", "leg.001": "leg", "back_slat_2": "back_slat"}


def _write_off(path: Path, meshes: dict[str, trimesh.Trimesh]) -> Path:
    lines = ["OFF"] + [f"# part {i} {name}" for i, name in enumerate(meshes)]
    vertices, faces, base = [], [], 0
    for i, mesh in enumerate(meshes.values()):
        vertices += [" ".join(map(repr, v)) for v in mesh.vertices.tolist()]
        faces += [f"3 {a + base} {b + base} {c + base} {i}" for a, b, c in mesh.faces.tolist()]
        base += len(mesh.vertices)
    lines += [f"{len(vertices)} {len(faces)} 0", *vertices, *faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def _write_stl(path: Path, meshes: dict[str, trimesh.Trimesh]) -> Path:
    text = ""
    for name, mesh in meshes.items():
        solid = trimesh.exchange.stl.export_stl_ascii(mesh).strip()
        text += solid.replace("solid \n", f"solid {name}\n", 1).rsplit("endsolid", 1)[0] + f"endsolid {name}\n"
    path.write_text(text)
    return path


def _write_gltf(path: Path, meshes: dict[str, trimesh.Trimesh]) -> Path:
    files = named_scene(meshes).export(file_type="gltf")
    for name, data in files.items():
        (path.parent / (path.name if name == "model.gltf" else name)).write_bytes(data)
    return path


def _write_obj_groups(path: Path, meshes: dict[str, trimesh.Trimesh]) -> Path:
    lines, base = [], 1
    for name, mesh in meshes.items():
        lines.append(f"g {name}")
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in mesh.faces.tolist()]
        base += len(mesh.vertices)
    path.write_text("\n".join(lines) + "\n")
    return path


WRITERS = {
    "glb": lambda path, meshes: path.write_bytes(named_scene(meshes).export(file_type="glb")) and path,
    "gltf": _write_gltf,
    "obj": lambda path, meshes: path.write_bytes(encode_obj(meshes)) and path,
    "obj-groups": _write_obj_groups,
    "ply": lambda path, meshes: path.write_bytes(encode_ply(meshes)) and path,
    "off": _write_off,
    "stl": _write_stl,
}
SUFFIX = {"obj-groups": "obj"}


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_each_format_reads_back_part_names_and_geometry(tmp_path, fmt, parts):
    meshes = parts
    path = WRITERS[fmt](tmp_path / f"shape.{SUFFIX.get(fmt, fmt)}", meshes)
    shape = load_mesh_shape(path)
    assert list(shape.parts) == NAMES
    assert shape.name == "shape" and shape.source == str(path)
    for name, part in shape.parts.items():
        assert part.name == name
        assert part.label == LABELS[name]
        assert isinstance(part.mesh, trimesh.Trimesh)
        expected = meshes[name].vertices
        got = np.asarray(part.mesh.vertices)
        # same point set (some formats unshare vertices), in world coordinates
        assert got.min(axis=0) == pytest.approx(expected.min(axis=0), abs=1e-6)
        assert got.max(axis=0) == pytest.approx(expected.max(axis=0), abs=1e-6)
        assert np.abs(part.hexahedron.corners - expected).max() < 1e-6  # a box mesh is its own cage


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_formats_load_through_the_core(tmp_path, fmt, parts):
    path = WRITERS[fmt](tmp_path / f"shape.{SUFFIX.get(fmt, fmt)}", parts)
    assert set(load_shape(str(path)).parts) == set(NAMES)


def test_glb_node_transforms_are_applied(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(box_mesh((0, 0, 0), (1, 1, 1)), node_name="lid", geom_name="box",
                       transform=trimesh.transformations.translation_matrix([0, 2, 0]))
    scene.add_geometry(box_mesh((0, 0, 0), (1, 1, 1)), node_name="base", geom_name="box2")
    path = tmp_path / "crate.glb"
    path.write_bytes(scene.export(file_type="glb"))
    shape = load_mesh_shape(path)
    assert list(shape.parts) == ["base", "lid"]
    assert shape.parts["lid"].hexahedron.corners[:, 1].min() == pytest.approx(2.0)
    assert np.asarray(shape.parts["lid"].mesh.vertices)[:, 1].min() == pytest.approx(2.0)


def test_glb_parts_keep_their_materials(tmp_path):
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    mesh = box_mesh((0, 0, 0), (1, 1, 1))
    mesh.visual = TextureVisuals(material=PBRMaterial(name="oak", baseColorFactor=[120, 84, 52, 255]))
    path = tmp_path / "m.glb"
    path.write_bytes(named_scene({"top": mesh, "leg": box_mesh((0, -1, 0), (0.1, 0, 0.1))}).export(file_type="glb"))
    material = load_mesh_shape(path).parts["top"].mesh.visual.material
    assert material.name == "oak"
    assert list(material.baseColorFactor) == [120, 84, 52, 255]


def test_obj_objects_win_over_groups_and_materials_load(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n")
    text = """mtllib m.mtl
o Seat
g ignored_group
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
usemtl red
f 1 2 3
f 1 2 4
f 1 3 4
f 2 3 4
o Leg.001
g other_group
v 0 -1 0
v 0.1 -1 0
v 0 0 0.1
v 0.1 0 0.1
usemtl blue
f 5 6 7
f 5 6 8
f 5 7 8
f 6 7 8
"""
    path = tmp_path / "chair.obj"
    path.write_text(text)
    shape = load_mesh_shape(path)
    assert list(shape.parts) == ["Leg.001", "Seat"]
    assert shape.parts["Leg.001"].label == "leg"
    assert len(shape.parts["Seat"].mesh.vertices) == 4
    assert np.asarray(shape.parts["Seat"].mesh.visual.material.diffuse)[:3].tolist() == [255, 0, 0]


def test_split_obj_keeps_the_material_in_force_across_objects():
    shared, parts = split_obj("v 0 0 0\nusemtl wood\no a\nf 1 1 1\no b\nf 1 1 1\nusemtl steel\nf 1 1 1\n")
    assert shared == ["v 0 0 0"]
    assert parts == {"a": ["usemtl wood", "f 1 1 1"], "b": ["usemtl wood", "f 1 1 1", "usemtl steel", "f 1 1 1"]}


def test_obj_relative_indices_refer_to_the_vertices_before_the_face(tmp_path):
    path = tmp_path / "rel.obj"
    path.write_text("o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf -4 -3 -2\nf -4 -3 -1\n"
                    "o b\nv 5 0 0\nv 6 0 0\nv 5 1 0\nv 5 0 1\nf -4 -3 -2\nf -4 -3 -1\n")
    shape = load_mesh_shape(path)
    assert np.asarray(shape.parts["a"].mesh.vertices)[:, 0].max() == 1.0
    assert np.asarray(shape.parts["b"].mesh.vertices)[:, 0].min() == 5.0


def test_obj_groups_when_one_object_holds_them(tmp_path):
    path = tmp_path / "g.obj"
    path.write_text("o chair\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\ng seat\nf 1 2 3\nf 1 2 4\n"
                    "g leg_1\nf 1 3 4\nf 2 3 4\n")
    assert list(load_mesh_shape(path).parts) == ["leg_1", "seat"]


def test_single_named_ascii_stl_solid(tmp_path):
    path = tmp_path / "one.stl"
    path.write_text(trimesh.exchange.stl.export_stl_ascii(box_mesh((0, 0, 0), (1, 1, 1))).replace(
        "solid \n", "solid tabletop\n", 1))
    shape = load_mesh_shape(path)
    assert list(shape.parts) == ["tabletop"]


def test_ascii_ply_with_part_comments(tmp_path):
    path = tmp_path / "t.ply"
    path.write_text("""ply
format ascii 1.0
comment part 0 top
comment part 1 leg 2
element vertex 5
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
property int part
end_header
0 0 0
1 0 0
0 1 0
0 0 1
1 1 1
3 0 1 2 0
3 0 3 4 1
""")
    shape = load_mesh_shape(path)
    assert list(shape.parts) == ["leg 2", "top"]
    assert shape.parts["leg 2"].label == "leg"


def test_sidecar_overrides_labels(write_glb):
    path = write_glb()
    path.with_name("shape.labels.json").write_text(json.dumps({"Seat": "chair_seat", "leg.001": "rear_leg"}))
    labels = {pid: p.label for pid, p in load_mesh_shape(path).parts.items()}
    assert labels == {"back_slat_2": "back_slat", "leg.000": "leg", "leg.001": "rear_leg", "Seat": "chair_seat"}


def test_partnet_directory(partnet_dir):
    shape = load_mesh_shape(partnet_dir)
    assert shape.name == "partnet_chair"
    assert {pid: p.label for pid, p in shape.parts.items()} == {
        "back_surface_2": "back_surface", "leg_7": "leg", "leg_8": "leg", "seat_surface_4": "seat_surface"}
    # leaf 8 lists two obj files: they are merged into one part
    leg = shape.parts["leg_8"]
    assert len(leg.mesh.vertices) == 16
    np.testing.assert_allclose(leg.hexahedron.corners.min(axis=0), [0.16, 0.0, 0.16])
    np.testing.assert_allclose(leg.hexahedron.corners.max(axis=0), [0.2, 0.4, 0.2])
    assert set(load_mesh_shape(partnet_dir / "result_after_merging.json").parts) == set(shape.parts)
    assert set(load_shape(str(partnet_dir)).parts) == set(shape.parts)


def test_partnet_sidecar(tmp_path, partnet_dir):
    import shutil

    target = tmp_path / "chair_1"
    shutil.copytree(partnet_dir, target)
    (tmp_path / "chair_1.labels.json").write_text(json.dumps({"leg_7": "front_leg"}))
    assert load_mesh_shape(target).parts["leg_7"].label == "front_leg"


def test_shape_from_meshes_orders_parts_naturally(parts):
    shape = shape_from_meshes({"leg.10": parts["leg.000"], "leg.2": parts["leg.001"]}, name="s")
    assert list(shape.parts) == ["leg.2", "leg.10"]
    assert shape.parts["leg.10"].label == "leg"


# -- bad input -------------------------------------------------------------------------------

def _single_mesh(path: Path) -> Path:
    trimesh.Trimesh(box_mesh((0, 0, 0), (1, 1, 1)).vertices, box_mesh((0, 0, 0), (1, 1, 1)).faces).export(str(path))
    return path


@pytest.mark.parametrize("suffix", [".glb", ".ply", ".off", ".stl", ".obj"])
def test_single_unnamed_mesh_is_an_error(tmp_path, suffix):
    path = _single_mesh(tmp_path / f"blob{suffix}")
    if suffix == ".obj":  # trimesh writes an 'o' line; drop it
        path.write_text("\n".join(line for line in path.read_text().splitlines() if not line.startswith("o ")))
    with pytest.raises(ParselError, match="scene has no named parts") as info:
        load_mesh_shape(path)
    assert str(path) in str(info.value)


def _write(tmp_path: Path, name: str, data: str | bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


BAD_FILES = {
    "garbage glb": ("x.glb", b"\x00\x01 definitely not a glb", "cannot read GLB file"),
    "garbage ply": ("x.ply", b"not a ply", "not a PLY file"),
    "ply without part property": ("x.ply", "ply\nformat ascii 1.0\ncomment part 0 a\nelement vertex 3\n"
                                  "property float x\nproperty float y\nproperty float z\nelement face 1\n"
                                  "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                                  "faces have no 'part' property"),
    "ply empty part": ("x.ply", "ply\nformat ascii 1.0\ncomment part 0 a\ncomment part 1 lid\nelement vertex 4\n"
                       "property float x\nproperty float y\nproperty float z\nelement face 2\n"
                       "property list uchar int vertex_indices\nproperty int part\nend_header\n"
                       "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 0\n3 0 1 3 0\n", "part 'lid' has no faces"),
    "off undeclared index": ("x.off", "OFF\n# part 0 a\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 0\n3 0 1 3 5\n",
                             "undeclared part index(es) 5"),
    "off face without index": ("x.off", "OFF\n# part 0 a\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
                               "face 0 has no part index"),
    "off bad vertex index": ("x.off", "OFF\n# part 0 a\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9 0\n",
                             "indexes a missing vertex"),
    "obj collinear part": ("x.obj", "o stick\nv 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n",
                           "part 'stick' is degenerate: its vertices are collinear"),
    "obj nan vertex": ("x.obj", "o lid\nv 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n",
                       "part 'lid' has NaN or infinite vertex coordinates"),
    "obj orphan faces": ("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no lid\nf 1 2 3\n",
                         "1 face(s) come before the first 'o' line"),
    "unknown suffix": ("x.xyz", "whatever", "unknown mesh suffix '.xyz'"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_files(tmp_path, case):
    name, data, fragment = BAD_FILES[case]
    path = _write(tmp_path, name, data)
    with pytest.raises(ParselError) as info:
        load_mesh_shape(path)
    message = str(info.value)
    assert fragment in message
    assert str(path) in message
    assert "\n" not in message


def test_missing_file(tmp_path):
    with pytest.raises(ParselError, match="no such file"):
        load_mesh_shape(tmp_path / "nope.glb")


def test_directory_that_is_not_partnet(tmp_path):
    with pytest.raises(ParselError, match="not a PartNet shape"):
        load_mesh_shape(tmp_path)


def test_empty_part_is_an_error():
    empty = trimesh.Trimesh(vertices=np.zeros((3, 3)), faces=np.zeros((0, 3), dtype=int), process=False)
    with pytest.raises(ParselError, match="src: part 'lid' has no faces"):
        shape_from_meshes({"lid": empty}, source="src")


def test_flat_part_is_allowed(tmp_path):
    panel = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]], faces=[[0, 1, 2], [1, 3, 2]])
    shape = shape_from_meshes({"panel": panel, "leg": box_mesh((0, -1, 0), (0.1, 0, 0.1))})
    assert shape.parts["panel"].hexahedron.volume > 0


def test_labels_file_naming_unknown_part(write_glb):
    path = write_glb()
    sidecar = path.with_name("shape.labels.json")
    sidecar.write_text(json.dumps({"stool": "seat"}))
    with pytest.raises(ParselError, match=r"labels file names unknown part\(s\) 'stool'") as info:
        load_mesh_shape(path)
    assert str(sidecar) in str(info.value)


def test_partnet_missing_obj(tmp_path, partnet_dir):
    import shutil

    target = tmp_path / "broken"
    shutil.copytree(partnet_dir, target)
    (target / "objs" / "original-3.obj").unlink()
    with pytest.raises(ParselError, match=r"original-3.obj: obj file of part 'leg_8' is missing"):
        load_mesh_shape(target)


@pytest.mark.parametrize(("text", "fragment"), [
    ("{}", "expected a list holding the root node"),
    ("[{\"name\": \"chair\"}]", "every node needs an 'id' and a 'name'"),
    ("[{\"id\": 0, \"name\": \"chair\"}]", "leaf part 'chair_0' lists no 'objs'"),
    ("[oops", "not valid JSON"),
])
def test_partnet_bad_hierarchy(tmp_path, text, fragment):
    (tmp_path / "result_after_merging.json").write_text(text)
    with pytest.raises(ParselError, match=fragment):
        load_mesh_shape(tmp_path)


def test_an_obj_object_without_faces_is_an_error_but_an_empty_group_is_not(tmp_path):
    vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
    path = tmp_path / "empty.obj"
    path.write_text(vertices + "o seat\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\no leg\n")
    with pytest.raises(ParselError, match=r"empty.obj: part 'leg' has no faces") as info:
        load_mesh_shape(path)
    assert "\n" not in str(info.value)
    path.write_text("g default\n" + vertices + "g seat\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"
                    "g leg\nf 1 3 2\nf 1 4 3\nf 1 2 4\nf 2 3 4\n")
    assert sorted(load_mesh_shape(path).parts) == ["leg", "seat"]
