"""PartNet shapes: a directory with ``result_after_merging.json`` and ``objs/*.obj``.

The JSON is a list holding one root node; every node has an ``id``, a ``name`` (the
label in PartNet's hierarchy, ``chair_back``), a ``text`` and either ``children`` or,
at the leaves, the ``objs`` (file stems under ``objs/``) that make up the part. The
leaves are the finest segmentation, which is what parsel edits: each leaf becomes a part
named ``<name>_<id>`` (unique even when names repeat) with label ``name``, its obj files
merged into one mesh.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.io import read_json

HIERARCHY_FILE = "result_after_merging.json"
OBJ_DIRS = ("objs", "obj")


def shape_directory(path: Path) -> Path:
    """The shape directory of a PartNet path (the directory itself or its hierarchy file)."""
    return path.parent if path.name == HIERARCHY_FILE else path


def is_partnet(path: Path) -> bool:
    """Whether ``path`` is a PartNet shape directory or its ``result_after_merging.json``."""
    if path.name == HIERARCHY_FILE:
        return path.is_file()
    return path.is_dir() and (path / HIERARCHY_FILE).is_file()


def leaves(node: Mapping[str, Any], where: str) -> Iterator[Mapping[str, Any]]:
    """Leaf nodes (no children) in document order; malformed nodes raise naming ``where``."""
    if not isinstance(node, Mapping) or "id" not in node or "name" not in node:
        raise ParselError(f"{where}: every node needs an 'id' and a 'name', got {str(node)[:80]!r}")
    children = node.get("children") or []
    if not isinstance(children, list):
        raise ParselError(f"{where}: node {node['id']!r}: 'children' must be a list")
    if not children:
        yield node
    for child in children:
        yield from leaves(child, where)


def read_hierarchy(path: Path) -> list[Mapping[str, Any]]:
    """The leaf nodes of a PartNet hierarchy file."""
    data = read_json(path)
    if not isinstance(data, list) or not data:
        raise ParselError(f"{path}: expected a list holding the root node")
    return [leaf for root in data for leaf in leaves(root, str(path))]


def leaf_mesh(directory: Path, leaf: Mapping[str, Any], part: str) -> Any:
    """The leaf's obj files merged into one trimesh (world coordinates, as PartNet stores them)."""
    import trimesh

    objs = leaf.get("objs")
    if not isinstance(objs, list) or not objs:
        raise ParselError(f"{directory}: leaf part {part!r} lists no 'objs'")
    obj_dir = next((directory / d for d in OBJ_DIRS if (directory / d).is_dir()), directory / OBJ_DIRS[0])
    meshes = []
    for stem in objs:
        file = obj_dir / f"{stem}.obj"
        if not file.is_file():
            raise ParselError(f"{file}: obj file of part {part!r} is missing")
        try:
            meshes.append(trimesh.load(str(file), file_type="obj", force="mesh", process=False))
        except Exception as exc:
            raise ParselError(f"{file}: cannot read OBJ file: {type(exc).__name__}: {' '.join(str(exc).split())}") \
                from None
    return meshes[0] if len(meshes) == 1 else trimesh.util.concatenate(meshes)


def load_partnet(path: Path) -> ShapeGraph:
    """Leaf parts of a PartNet shape; a sidecar ``<dir>.labels.json`` beside it overrides labels."""
    from parsel_mesh.loaders import assemble

    directory = shape_directory(path)
    meshes, labels = [], {}
    for leaf in read_hierarchy(directory / HIERARCHY_FILE):
        part = f"{leaf['name']}_{leaf['id']}"
        meshes.append((part, leaf_mesh(directory, leaf, part)))
        labels[part] = str(leaf["name"])
    return assemble(directory, meshes, labels, "partnet")
