"""Writers of edited part meshes: GLB (scene of named parts), OBJ (named objects), PLY (one mesh).

Each exporter deforms the part meshes with the cage deformer, encodes the whole file in
memory and hands it to ``parsel_core.io.atomic_write_bytes``, which writes a temporary
file beside the target and renames it, so a failure never leaves a partial file. The
names written are part ids (``<member>#<i>`` for instances of re-laid-out groups), which
are what the loaders read back as part ids.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import Exporter
from parsel_core.io import atomic_write_bytes
from parsel_core.program import Evaluation
from parsel_mesh.deform import deformed_meshes

DEFAULT_RGBA = (200, 200, 200, 255)


def has_meshes(shape: ShapeGraph) -> bool:
    """Whether every part carries a mesh (the condition for the mesh exporters)."""
    return bool(shape.parts) and all(getattr(p.mesh, "vertices", None) is not None for p in shape.parts.values())


def _one_line_name(name: str) -> str:
    """Names go on one line of a text header; line breaks would start a new directive."""
    return " ".join(str(name).split()) or "part"


def face_colors(mesh: Any) -> np.ndarray:
    """RGBA (f, 4) uint8 per face: the mesh's own colours, else its material's main colour."""
    visual = getattr(mesh, "visual", None)
    color: Any = DEFAULT_RGBA
    try:
        if visual is not None and visual.kind in ("face", "vertex"):
            return np.asarray(visual.face_colors, dtype=np.uint8)[:, :4]
        material = getattr(visual, "material", None)
        if material is not None:
            color = material.main_color
    except Exception:  # a visual without colours, or a texture trimesh cannot summarise
        color = DEFAULT_RGBA
    color = np.asarray(color, dtype=np.uint8).ravel()
    if color.size < 4:
        color = np.asarray(DEFAULT_RGBA, dtype=np.uint8)
    return np.tile(color[:4], (len(mesh.faces), 1))


def encode_glb(meshes: Mapping[str, Any], hierarchy: Mapping[str, Sequence[str]] | None = None) -> bytes:
    """A GLB scene with one node per part, node and mesh named after it, materials kept.

    ``hierarchy`` (part name -> ancestor node names, root first, as the GLB loader records
    them) puts each part back under its ancestors. Meshes are in world coordinates, so
    every node's transform is the identity: the grouping is kept, not the local frames.
    """
    import trimesh

    hierarchy = hierarchy or {}
    scene = trimesh.Scene()
    known = {scene.graph.base_frame}
    ordered = sorted(meshes, key=lambda name: len(hierarchy.get(name, ())))  # ancestors before descendants
    for name in ordered:
        parent = scene.graph.base_frame
        for ancestor in hierarchy.get(name, ()):
            if ancestor not in known:
                scene.graph.update(frame_from=parent, frame_to=ancestor, matrix=np.eye(4))
                known.add(ancestor)
            parent = ancestor
        scene.add_geometry(meshes[name], node_name=name, geom_name=name, parent_node_name=parent)
        known.add(name)
    return scene.export(file_type="glb")


def encode_obj(meshes: Mapping[str, Any], title: str = "") -> bytes:
    """OBJ text, one ``o`` object per part; coordinates in shortest round-trip form."""
    lines = [f"# parsel edited shape {_one_line_name(title)}".rstrip()]
    base = 1
    for name, mesh in meshes.items():
        lines.append(f"o {_one_line_name(name)}")
        lines.extend(f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(mesh.vertices, dtype=float).tolist())
        faces = np.asarray(mesh.faces, dtype=np.int64) + base
        lines.extend(f"f {a} {b} {c}" for a, b, c in faces.tolist())
        base += len(mesh.vertices)
    return ("\n".join(lines) + "\n").encode("utf-8")


def encode_ply(meshes: Mapping[str, Any], title: str = "") -> bytes:
    """Binary PLY of all parts merged; faces keep a ``part`` index and an RGBA colour.

    The part names are ``comment part <index> <name>`` header lines, so the merged mesh
    still reads back as parts (``loaders.read_ply``).
    """
    names = list(meshes)
    vertices = [np.asarray(meshes[n].vertices, dtype="<f8") for n in names]
    offsets = np.cumsum([0] + [len(v) for v in vertices])
    face_dtype = np.dtype([("count", "u1"), ("vertex_indices", "<i4", (3,)), ("part", "<i4"),
                           ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")])
    blocks = []
    for i, name in enumerate(names):
        mesh = meshes[name]
        block = np.zeros(len(mesh.faces), dtype=face_dtype)
        block["count"] = 3
        block["vertex_indices"] = np.asarray(mesh.faces, dtype=np.int64) + offsets[i]
        block["part"] = i
        colors = face_colors(mesh)
        for k, channel in enumerate(("red", "green", "blue", "alpha")):
            block[channel] = colors[:, k]
        blocks.append(block)
    all_vertices = np.concatenate(vertices) if vertices else np.zeros((0, 3), dtype="<f8")
    all_faces = np.concatenate(blocks) if blocks else np.zeros(0, dtype=face_dtype)
    header = ["ply", "format binary_little_endian 1.0", f"comment parsel edited shape {_one_line_name(title)}"]
    header += [f"comment part {i} {_one_line_name(name)}" for i, name in enumerate(names)]
    header += [f"element vertex {len(all_vertices)}", "property double x", "property double y", "property double z",
               f"element face {len(all_faces)}", "property list uchar int vertex_indices", "property int part",
               "property uchar red", "property uchar green", "property uchar blue", "property uchar alpha",
               "end_header"]
    return ("\n".join(header) + "\n").encode("ascii", errors="replace") + all_vertices.tobytes() + all_faces.tobytes()


def glb_hierarchy(shape: ShapeGraph, meshes: Mapping[str, Any]) -> dict[str, list[str]]:
    """Each exported mesh's ancestors from the loaded scene; a group instance (``member#i``)
    goes where its member was.

    Only consistent paths are kept: an ancestor that is itself an exported part must sit
    at that place in its own path, and no part is its own ancestor (a part named after
    its mesh can share a name with a node above it). A part whose path is not consistent
    is written at the top level rather than lost or moved under another part.
    """
    loaded = shape.metadata.get("hierarchy", {}) if shape.metadata else {}
    wanted: dict[str, list[str]] = {}
    for name in meshes:
        source = name if name in loaded else name.split("#")[0]
        if source in loaded:
            wanted[name] = list(loaded[source])

    while True:  # dropping one path can make a descendant's path inconsistent: repeat until stable
        kept = {name: parents for name, parents in wanted.items() if name not in parents and all(
            ancestor not in meshes or wanted.get(ancestor, []) == parents[:depth]
            for depth, ancestor in enumerate(parents))}
        if kept == wanted:
            return kept
        wanted = kept


class MeshExporter(Exporter):
    """Deformed part meshes to one file; subclasses choose the encoding."""

    def can_export(self, shape: ShapeGraph) -> bool:
        """True when every part has a mesh; shapes of bare hexahedra go to the hexahedra exporters."""
        return has_meshes(shape)

    def encode(self, shape: ShapeGraph, meshes: Mapping[str, Any]) -> bytes:
        raise NotImplementedError

    def export(self, shape: ShapeGraph, evaluation: Evaluation | None, path: Path) -> None:
        """Write ``shape`` as edited by ``evaluation`` (``None``: at rest) to ``path``, atomically."""
        path = Path(path)
        if not path.parent.is_dir():
            raise ParselError(f"{path}: output directory {path.parent} does not exist")
        missing = [pid for pid, part in shape.parts.items() if getattr(part.mesh, "vertices", None) is None]
        if missing:
            raise ParselError(f"{path}: shape {shape.name!r} part(s) {', '.join(map(repr, missing[:5]))} have no "
                              f"mesh; export its hexahedra with the hexahedra-obj or hexahedra-json exporter")
        atomic_write_bytes(path, self.encode(shape, deformed_meshes(shape, evaluation)))


class GLBExporter(MeshExporter):
    """``.glb``: a scene of named part nodes with their materials."""

    name = "mesh-glb"
    extensions = (".glb",)

    def encode(self, shape, meshes):
        return encode_glb(meshes, glb_hierarchy(shape, meshes))


class OBJExporter(MeshExporter):
    """``.obj``: one named object per part (geometry only; use GLB to keep materials)."""

    name = "mesh-obj"
    extensions = (".obj",)

    def encode(self, shape, meshes):
        return encode_obj(meshes, shape.name)


class PLYExporter(MeshExporter):
    """``.ply``: one merged mesh with per-face part indices and colours."""

    name = "mesh-ply"
    extensions = (".ply",)

    def encode(self, shape, meshes):
        return encode_ply(meshes, shape.name)


def mesh_exporters() -> list[MeshExporter]:
    """The exporters this plugin registers."""
    return [GLBExporter(), OBJExporter(), PLYExporter()]
