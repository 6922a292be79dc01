"""Mesh files built to hang or exhaust the readers: refused in one line, before trimesh reads them."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from parsel_core.errors import ParselError
from parsel_mesh.gltf_check import check_node_graph
from parsel_mesh.loaders import load_mesh_shape, obj_part_chunk, read_obj

BOX = [(k & 1, (k >> 1) & 1, (k >> 2) & 1) for k in range(8)]
TRIANGLES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
             (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def glb(edit=None) -> bytes:
    """Two box nodes, ``seat`` and ``leg``, sharing one mesh; ``edit`` changes the JSON."""
    positions = b"".join(struct.pack("<3f", *p) for p in BOX)
    indices = b"".join(struct.pack("<3H", *t) for t in TRIANGLES)
    binary = positions + indices
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(binary)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(positions)},
                           {"buffer": 0, "byteOffset": len(positions), "byteLength": len(indices)}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [0, 0, 0],
                          "max": [1, 1, 1]},
                         {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "nodes": [{"name": "seat", "mesh": 0, "translation": [0, 2, 0]}, {"name": "leg", "mesh": 0}],
           "scenes": [{"nodes": [0, 1]}], "scene": 0}
    if edit:
        edit(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def test_the_glb_builder_makes_a_readable_file(tmp_path):
    path = tmp_path / "ok.glb"
    path.write_bytes(glb())
    assert sorted(load_mesh_shape(path).parts) == ["leg", "seat"]


def _cycle(doc):
    doc["nodes"][0]["children"] = [1]
    doc["nodes"][1]["children"] = [0]


def _self(doc):
    doc["nodes"][1]["children"] = [1]


def _two_parents(doc):
    doc["nodes"].append({"name": "frame", "children": [1]})
    doc["nodes"][0]["children"] = [1]


def _scale(doc):
    doc["nodes"][0]["scale"] = [1e308, 1e308, 1e308]


def _huge_int(doc):
    doc["nodes"][1]["translation"] = [10**400, 0, 0]


def _count(doc):
    doc["accessors"][1]["count"] = 10**9


@pytest.mark.parametrize("edit, fragment", [
    (_cycle, "cycle"), (_self, "its own child"), (_two_parents, "two parents"),
    (_scale, "max_magnitude"), (_huge_int, "max_magnitude"), (_count, "max_faces"),
])
def test_glb_node_graphs_and_numbers_that_would_hang_or_overflow_are_refused(tmp_path, edit, fragment):
    path = tmp_path / "bad.glb"
    path.write_bytes(glb(edit))
    with pytest.raises(ParselError, match=fragment) as info:
        load_mesh_shape(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_long_chain_of_nodes_is_walked_without_recursion(tmp_path):
    nodes = [{"children": [i + 1]} for i in range(200_000)] + [{}]
    check_node_graph(nodes, tmp_path / "chain.glb")
    nodes[-1] = {"children": [0]}  # close the chain into a loop
    with pytest.raises(ParselError, match="cycle"):
        check_node_graph(nodes, tmp_path / "chain.glb")


def test_two_obj_objects_of_one_name_are_refused_not_merged(tmp_path):
    path = tmp_path / "twice.obj"
    vertices = "".join(f"v {x} {y} {z}\n" for x, y, z in BOX)
    path.write_text(vertices + "o seat\nf 1 2 3\no leg\nf 5 6 7\no seat\nf 2 3 4\n")
    with pytest.raises(ParselError, match="duplicate part name.*'seat'"):
        read_obj(path)


def test_each_obj_part_gets_only_the_vertices_it_uses_in_file_order():
    tables = {"v": [f"v {i} 0 0" for i in range(1, 7)], "vt": ["vt 0 0", "vt 1 1"], "vn": []}
    chunk = obj_part_chunk("lid", ["usemtl red", "f 5/2 2/1 6/2"], tables, ["mtllib a.mtl"])
    assert chunk.splitlines() == ["mtllib a.mtl", "v 2 0 0", "v 5 0 0", "v 6 0 0", "vt 0 0", "vt 1 1", "o lid",
                                  "usemtl red", "f 2/2 1/1 3/2"]
    with pytest.raises(ValueError, match="face index 9"):
        obj_part_chunk("lid", ["f 1 2 9"], tables, [])


def test_an_obj_of_many_parts_reads_each_part_with_its_own_vertices(tmp_path):
    lines, faces = [], []
    for p in range(100):
        lines += [f"v {x + 2 * p} {y} {z}" for x, y, z in BOX]
        faces += [f"o part{p}"] + [f"f {8 * p + a + 1} {8 * p + b + 1} {8 * p + c + 1}" for a, b, c in TRIANGLES]
    path = tmp_path / "many.obj"
    path.write_text("\n".join(lines + faces) + "\n")
    meshes = dict(read_obj(path))
    assert len(meshes) == 100 and all(len(m.vertices) == 8 for m in meshes.values())
    np.testing.assert_allclose(meshes["part42"].vertices.min(axis=0), [84, 0, 0])
