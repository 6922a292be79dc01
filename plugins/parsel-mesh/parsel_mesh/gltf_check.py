"""Checks on a GLB / GLTF document before trimesh reads it.

trimesh walks a node graph by following ``children`` and trusts the numbers it finds, so
a node graph with a cycle makes it loop for ever and a scale of ``1e308`` reaches the
box fitting as infinities. The JSON part of the file is read here first (cheap: no
buffers are decoded) and refused in one line when its node graph is not a forest, a node
transform is not finite or beyond ``max_magnitude``, or its meshes hold more vertices
or triangles than the limits allow.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

from parsel_core.config import check_limit, limit
from parsel_core.errors import ParselError

GLB_MAGIC = b"glTF"
JSON_CHUNK = 0x4E4F534A
#: Node fields holding numbers, with the count each must have.
TRANSFORM_FIELDS = {"translation": 3, "rotation": 4, "scale": 3, "matrix": 16}
#: glTF primitive modes and how many indices make one triangle (4: triangles; 5, 6: strips, fans).
TRIANGLE_MODES = {4: 3, 5: 1, 6: 1}


def gltf_json(path: Path) -> Any:
    """The JSON document of a ``.glb`` (its first chunk) or a ``.gltf`` file."""
    kind = path.suffix.lower().lstrip(".").upper()
    try:
        with open(path, "rb") as handle:
            head = handle.read(20)
            if kind == "GLTF":
                text = head + handle.read()
            else:
                if len(head) < 20 or head[:4] != GLB_MAGIC:
                    raise ParselError(f"{path}: cannot read GLB file: no GLB header ('glTF' and version)")
                _, _, _, chunk_length, chunk_type = struct.unpack("<4sIIII", head)
                if chunk_type != JSON_CHUNK:
                    raise ParselError(f"{path}: cannot read GLB file: its first chunk is not JSON")
                text = handle.read(chunk_length)
                if len(text) < chunk_length:
                    raise ParselError(f"{path}: cannot read GLB file: its JSON chunk is cut off")
    except OSError as exc:
        raise ParselError(f"{path}: cannot read: {exc.strerror}") from None
    try:
        return json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ParselError(f"{path}: cannot read {kind} file: its JSON is not readable ({type(exc).__name__})") \
            from None


def _list(doc: dict, key: str, path: Path) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list):
        raise ParselError(f"{path}: glTF field {key!r} must be a list")
    return value


def _index(value: Any, size: int, where: str, path: Path) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < size:
        raise ParselError(f"{path}: {where} {value!r} is not an index below {size}")
    return value


def check_node_graph(nodes: list, path: Path) -> None:
    """Every node has at most one parent and no node is its own ancestor (walked without recursion)."""
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise ParselError(f"{path}: glTF node {i} is not an object")
        children = node.get("children", [])
        if not isinstance(children, list):
            raise ParselError(f"{path}: glTF node {i}: children must be a list")
        for child in children:
            child = _index(child, len(nodes), f"glTF node {i}: child", path)
            if child == i:
                raise ParselError(f"{path}: glTF node {i} is its own child (a cycle)")
            if child in parent:
                raise ParselError(f"{path}: glTF node {child} has two parents ({parent[child]} and {i})")
            parent[child] = i
    # With at most one parent each, a cycle is a chain of parents that comes back to its start.
    state: dict[int, int] = {}  # 1: on the chain being followed, 2: known to reach a root
    for start in range(len(nodes)):
        chain, at = [], start
        while at in parent and state.get(at) is None:
            state[at] = 1
            chain.append(at)
            at = parent[at]
            if state.get(at) == 1:
                raise ParselError(f"{path}: glTF node graph has a cycle through node {at}")
        for node in chain:
            state[node] = 2


def check_transforms(nodes: list, path: Path) -> None:
    """Node translations, rotations, scales and matrices: the right count of finite, sane numbers."""
    bound = limit("max_magnitude")
    for i, node in enumerate(nodes):
        for key, count in TRANSFORM_FIELDS.items():
            if key not in node:
                continue
            values = node[key]
            if not isinstance(values, list) or len(values) != count or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
                raise ParselError(f"{path}: glTF node {i}: {key} must be {count} numbers")
            if not all(_sane(v, bound) for v in values):
                raise ParselError(f"{path}: glTF node {i}: {key} holds a number that is not finite or is over "
                                  f"the limit max_magnitude = {bound:g} (raise it with PARSEL_MAX_MAGNITUDE)")


def _sane(value: int | float, bound: float) -> bool:
    try:
        return math.isfinite(value) and abs(value) <= bound
    except OverflowError:  # an integer beyond any float
        return False


def check_sizes(doc: dict, path: Path) -> None:
    """Vertex and triangle counts of all mesh primitives, from the accessors, against the limits."""
    accessors = _list(doc, "accessors", path)
    vertices = triangles = 0
    for m, mesh in enumerate(_list(doc, "meshes", path)):
        primitives = mesh.get("primitives", []) if isinstance(mesh, dict) else None
        if not isinstance(primitives, list):
            raise ParselError(f"{path}: glTF mesh {m}: primitives must be a list")
        for primitive in primitives:
            if not isinstance(primitive, dict):
                raise ParselError(f"{path}: glTF mesh {m}: a primitive is not an object")
            attributes = primitive.get("attributes", {})
            position = attributes.get("POSITION") if isinstance(attributes, dict) else None
            count = _count(accessors, position, path)
            vertices += count
            per = TRIANGLE_MODES.get(primitive.get("mode", 4))
            if per is not None:
                indexed = _count(accessors, primitive.get("indices"), path) if "indices" in primitive else count
                triangles += indexed // 3 if per == 3 else max(indexed - 2, 0)
    check_limit("max_vertices", f"{path}: vertices", vertices)
    check_limit("max_faces", f"{path}: triangles", triangles)


def _count(accessors: list, index: Any, path: Path) -> int:
    if index is None:
        return 0
    accessor = accessors[_index(index, len(accessors), "glTF accessor", path)]
    count = accessor.get("count", 0) if isinstance(accessor, dict) else None
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise ParselError(f"{path}: glTF accessor {index}: count must be a non-negative integer")
    return count


def check_gltf(path: Path) -> None:
    """Refuse a GLB / GLTF whose structure would hang or exhaust the reader (module docstring)."""
    doc = gltf_json(path)
    if not isinstance(doc, dict):
        raise ParselError(f"{path}: glTF JSON must be an object")
    nodes = _list(doc, "nodes", path)
    check_node_graph(nodes, path)
    check_limit("max_parts", f"{path}: glTF nodes with a mesh", sum(isinstance(n, dict) and "mesh" in n for n in nodes))
    check_transforms(nodes, path)
    for s, scene in enumerate(_list(doc, "scenes", path)):
        roots = scene.get("nodes", []) if isinstance(scene, dict) else None
        if not isinstance(roots, list):
            raise ParselError(f"{path}: glTF scene {s}: nodes must be a list")
        for root in roots:
            _index(root, len(nodes), f"glTF scene {s}: node", path)
    check_sizes(doc, path)
