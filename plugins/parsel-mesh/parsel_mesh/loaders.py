"""Reading part-segmented mesh files into shape graphs.

Every format comes down to a list of named meshes in world coordinates; the name is the
part id, its label comes from the name (``naming.label_of``) or a sidecar, and its
hexahedron is the fitted box (``fitting.hexahedron_of``). Where the parts come from:

* GLB / GLTF and STL: the scene's named nodes (STL: the ``solid NAME`` blocks of an
  ASCII file), read by trimesh.
* OBJ: ``o`` objects, or ``g`` groups when there are at least two groups but fewer than two objects.
* PLY and OFF: one merged mesh whose faces carry a part index, with the names in header
  comments (``comment part 0 seat`` / ``# part 0 seat``); the ``mesh-ply`` exporter
  writes this form.
* PartNet: a directory with ``result_after_merging.json`` and ``objs/`` (``partnet.py``).

trimesh is imported inside the functions that need it, so importing this module (which
every ``parsel`` command does when it lists loaders) stays cheap.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import ShapeLoader
from parsel_core.part import Part
from parsel_mesh.fitting import hexahedron_of
from parsel_mesh.naming import is_generated_name, natural_key, read_sidecar, resolve_labels, sidecar_path

NamedMeshes = list[tuple[str, Any]]
NO_NAMED_PARTS = "scene has no named parts"


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _read_failure(path: Path, kind: str, exc: BaseException) -> ParselError:
    return ParselError(f"{path}: cannot read {kind} file: {_one_line(exc)}")


# -- checking and assembling ---------------------------------------------------------------

def check_mesh(mesh: Any, where: str) -> np.ndarray:
    """The vertices that faces use, after checking the mesh can be a part; ``where`` names it."""
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))))
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=float)
    if faces.size == 0:
        raise ParselError(f"{where} has no faces")
    if not np.all(np.isfinite(vertices)):
        raise ParselError(f"{where} has NaN or infinite vertex coordinates")
    from parsel_core.config import limit

    bound = limit("max_magnitude")
    if np.abs(vertices).max(initial=0.0) > bound:
        raise ParselError(f"{where} has vertex coordinates over the limit max_magnitude = {bound:g} "
                          "(raise it with PARSEL_MAX_MAGNITUDE)")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ParselError(f"{where} has faces that index missing vertices")
    return vertices[np.unique(faces)]


def part_of(name: str, label: str, mesh: Any, where: str) -> Part:
    """A :class:`Part` carrying ``mesh``, its hexahedron fitted to the used vertices."""
    points = check_mesh(mesh, where)
    try:
        hexahedron = hexahedron_of(points)
    except ValueError as exc:
        raise ParselError(f"{where} is degenerate: {exc}") from None
    return Part(name, label, hexahedron, name=name, mesh=mesh)


def shape_from_meshes(meshes: Mapping[str, Any] | Sequence[tuple[str, Any]], *, name: str = "shape",
                      source: str | None = None, labels: Mapping[str, str] | None = None,
                      metadata: Mapping[str, Any] | None = None) -> ShapeGraph:
    """A shape graph from named meshes (world coordinates), parts in natural name order.

    ``labels`` gives a label per name; names without one get :func:`naming.label_of`.
    Errors name ``source`` and the part.
    """
    items = list(meshes.items()) if isinstance(meshes, Mapping) else list(meshes)
    where = source or name
    if not items:
        raise ParselError(f"{where}: {NO_NAMED_PARTS}")
    from parsel_core.config import check_limit

    check_limit("max_parts", f"{where}: parts", len(items))
    check_limit("max_faces", f"{where}: faces", sum(len(getattr(m, "faces", ())) for _, m in items))
    names = [n for n, _ in items]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1}, key=natural_key)
        raise ParselError(f"{where}: duplicate part name(s) {', '.join(map(repr, twice))}")
    resolved = resolve_labels(names, defaults=labels)
    parts = [part_of(n, resolved[n], mesh, f"{where}: part {n!r}")
             for n, mesh in sorted(items, key=lambda item: natural_key(item[0]))]
    return ShapeGraph(parts, name=name, source=source, metadata=metadata)


# -- formats ---------------------------------------------------------------------------------

def read_scene(path: Path) -> NamedMeshes:
    """Named nodes of a GLB / GLTF / STL scene, each mesh moved to world coordinates.

    A node is named by its own name, or its geometry's when the node's was made up by the
    reader; a scene whose names are all made up (one unnamed mesh) has no named parts.
    The names of a node's ancestors (root first) go to ``mesh.metadata["parents"]``, so the
    hierarchy can be written back (:func:`parsel_mesh.exporters.encode_glb`).
    """
    import trimesh

    if path.suffix.lower() in (".glb", ".gltf"):
        from parsel_mesh.gltf_check import check_gltf

        check_gltf(path)  # cycles, non-finite transforms and sizes, before trimesh walks it
    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise _read_failure(path, path.suffix.lower().lstrip(".").upper(), exc) from None
    out: NamedMeshes = []
    parent_of = scene.graph.transforms.parents
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node]
        geometry = scene.geometry.get(geometry_name)
        if not isinstance(geometry, trimesh.Trimesh):
            continue  # points, lines and other non-surface geometry are not parts
        name = node if not is_generated_name(node, path) or is_generated_name(geometry_name, path) \
            else geometry_name
        mesh = geometry.copy()
        if not np.array_equal(transform, np.eye(4)):
            mesh.apply_transform(transform)
        parents, at = [], parent_of.get(node)
        while at is not None and at != scene.graph.base_frame:
            parents.insert(0, str(at))
            at = parent_of.get(at)
        mesh.metadata["parents"] = parents
        out.append((str(name), mesh))
    if not out or all(is_generated_name(n, path) for n, _ in out):
        raise ParselError(f"{path}: {NO_NAMED_PARTS} (a single unnamed mesh cannot be edited by part)")
    return out


_OBJ_SHARED = frozenset({"v", "vt", "vn", "vp", "mtllib"})


def _absolute_face(rest: str, counts: Mapping[str, int]) -> str:
    """A face's ``v/vt/vn`` references with relative (negative) indices made absolute.

    Parts are re-read with all vertex data in front of their faces, where a relative
    index would point elsewhere, so ``f -3 -2 -1`` is resolved against the counts so far.
    """
    kinds = ("v", "vt", "vn")
    out = []
    for token in rest.split():
        fields = token.split("/")
        for k, value in enumerate(fields[:3]):
            if value.startswith("-"):
                fields[k] = str(counts[kinds[k]] + int(value) + 1)
        out.append("/".join(fields))
    return "f " + " ".join(out)


def split_obj(text: str) -> tuple[list[str], dict[str, list[str]]]:
    """Vertex-data lines shared by all parts, and each part's own lines (``usemtl`` + faces).

    Parts are the ``o`` objects, or the ``g`` groups when at least two groups but fewer
    than two objects have faces. Raises ``ValueError`` when faces belong to no named object
    or group, or when a named object has no faces (groups without faces, such as the
    ``g default`` some exporters write before the vertices, are not parts).
    """
    text = text.replace("\r\n", "\n").replace("\\\n", " ")
    shared: list[str] = []
    faces: list[tuple[str | None, str | None, str | None, str]] = []  # (object, group, material, line)
    counts = {"v": 0, "vt": 0, "vn": 0}
    obj = group = material = None
    declared: list[str] = []  # object names in file order
    runs: list[str] = []  # object names as their blocks start
    for line in text.split("\n"):
        key, rest = (line.split(None, 1) + ["", ""])[:2]
        rest = rest.strip()
        if key in _OBJ_SHARED:
            shared.append(f"{key} {rest}")
            if key in counts:
                counts[key] += 1
        elif key == "o":
            obj = rest or None
            if obj is not None:
                runs.append(obj)
            if obj is not None and obj not in declared:
                declared.append(obj)
        elif key == "g":
            group = rest or None
        elif key == "usemtl":
            material = rest or None
        elif key == "f":
            faces.append((obj, group, material, _absolute_face(rest, counts) if "-" in rest else f"f {rest}"))
    objects = {f[0] for f in faces if f[0] is not None}
    groups = {f[1] for f in faces if f[1] is not None}
    if not objects and not groups:
        raise ValueError(NO_NAMED_PARTS)
    column = 0 if len(objects) >= 2 or (objects and len(groups) < 2) else 1
    directive = "o" if column == 0 else "g"
    if column == 0:
        empty = [name for name in declared if name not in objects]
        if empty:
            raise ValueError(f"part {empty[0]!r} has no faces")
        twice = sorted({name for name in runs if runs.count(name) > 1})
        if twice:
            raise ValueError(f"duplicate part name(s) {', '.join(map(repr, twice))} (two 'o' blocks of one name)")
    orphans = sum(1 for f in faces if f[column] is None)
    if orphans:
        raise ValueError(f"{orphans} face(s) come before the first '{directive}' line and belong to no part")
    parts: dict[str, list[str]] = {}
    current: dict[str, str | None] = {}
    for face in faces:
        name, material = face[column], face[2]
        lines = parts.setdefault(name, [])
        if material is not None and current.get(name) != material:
            lines.append(f"usemtl {material}")
            current[name] = material
        lines.append(face[3])
    return shared, parts


_OBJ_INDEXED = ("v", "vt", "vn")


def obj_part_chunk(name: str, lines: Sequence[str], tables: Mapping[str, Sequence[str]],
                   others: Sequence[str]) -> str:
    """One part as an OBJ of its own: only the vertex data its faces use, renumbered.

    Handing each part the whole file's vertex data would make reading a file of many
    parts cost parts x vertices; the used entries keep their file order, as trimesh
    would keep them. Raises ``ValueError`` for an index that is not an entry of the file.
    """
    used: dict[str, set[int]] = {kind: set() for kind in _OBJ_INDEXED}
    faces = [line.split()[1:] if line.startswith("f ") else None for line in lines]
    for tokens in faces:
        for token in tokens or ():
            for k, value in enumerate(token.split("/")[:3]):
                if value:
                    index = int(value)
                    if not 1 <= index <= len(tables[_OBJ_INDEXED[k]]):
                        raise ValueError(f"face index {index} is not one of the file's {_OBJ_INDEXED[k]} lines")
                    used[_OBJ_INDEXED[k]].add(index)
    renumber = {kind: {old: new for new, old in enumerate(sorted(used[kind]), start=1)} for kind in _OBJ_INDEXED}
    body = []
    for line, tokens in zip(lines, faces):
        if tokens is None:
            body.append(line)
            continue
        out = []
        for token in tokens:
            fields = token.split("/")
            for k, value in enumerate(fields[:3]):
                if value:
                    fields[k] = str(renumber[_OBJ_INDEXED[k]][int(value)])
            out.append("/".join(fields))
        body.append("f " + " ".join(out))
    data = [tables[kind][old - 1] for kind in _OBJ_INDEXED for old in sorted(used[kind])]
    return "\n".join([*others, *data, f"o {name}", *body]) + "\n"


def read_obj(path: Path) -> NamedMeshes:
    """OBJ objects (or groups) as parts, each read by trimesh with the file's materials.

    Each part is handed to trimesh as the vertex data its faces use plus those faces
    (:func:`obj_part_chunk`), so the split does not depend on the trimesh version's
    object / group options.
    """
    import trimesh

    from parsel_core.config import check_limit

    try:
        text = path.read_bytes().decode("utf-8", errors="replace")
        shared, parts = split_obj(text)
        check_limit("max_parts", f"{path}: parts", len(parts))  # each part is read on its own: check first
        check_limit("max_vertices", f"{path}: vertices", sum(line.startswith("v ") for line in shared))
        check_limit("max_faces", f"{path}: faces", sum(len(lines) for lines in parts.values()))
    except OSError as exc:
        raise ParselError(f"{path}: cannot read: {exc.strerror}") from None
    except ValueError as exc:
        raise ParselError(f"{path}: {exc}") from None
    resolver = trimesh.resolvers.FilePathResolver(str(path))
    tables = {kind: [line for line in shared if line.startswith(kind + " ")] for kind in _OBJ_INDEXED}
    others = [line for line in shared if line.split(" ", 1)[0] not in _OBJ_INDEXED]
    out: NamedMeshes = []
    for name, lines in parts.items():
        try:
            chunk = obj_part_chunk(name, lines, tables, others)
            mesh = trimesh.load(io.BytesIO(chunk.encode("utf-8")), file_type="obj", resolver=resolver,
                                force="mesh", process=False)
        except Exception as exc:
            raise ParselError(f"{path}: part {name!r}: cannot read OBJ faces: {_one_line(exc)}") from None
        out.append((name, mesh))
    return out


_PART_COMMENT = re.compile(r"^part\s+(-?\d+)\s+(.+?)\s*$")


def _part_names(comments: Sequence[str], path: Path) -> dict[int, str]:
    """``{index: name}`` from ``part <index> <name>`` comments."""
    names: dict[int, str] = {}
    for comment in comments:
        match = _PART_COMMENT.match(comment.strip())
        if match:
            index, name = int(match.group(1)), match.group(2)
            if index in names:
                raise ParselError(f"{path}: part index {index} is declared twice")
            names[index] = name
    return names


def _split_tagged(path: Path, mesh: Any, tags: np.ndarray, names: Mapping[int, str]) -> NamedMeshes:
    """One mesh per declared part from a merged mesh and per-face part indices."""
    tags = np.asarray(tags).astype(np.int64).ravel()
    faces = np.asarray(mesh.faces)
    if faces.size and (faces.min() < 0 or faces.max() >= len(mesh.vertices)):
        raise ParselError(f"{path}: faces index missing vertices (a vertex index past the end)")
    if len(tags) != len(mesh.faces):
        raise ParselError(f"{path}: {len(tags)} part indices for {len(mesh.faces)} faces "
                          f"(part-tagged files must be triangles)")
    undeclared = sorted(set(np.unique(tags).tolist()) - set(names))
    if undeclared:
        raise ParselError(f"{path}: faces use undeclared part index(es) {', '.join(map(str, undeclared))}")
    out: NamedMeshes = []
    for index, name in names.items():
        selected = np.flatnonzero(tags == index)
        if not len(selected):
            raise ParselError(f"{path}: part {name!r} has no faces")
        out.append((name, mesh.submesh([selected], append=True, only_watertight=False)))
    return out


def ply_comments(path: Path) -> list[str]:
    """Text of the ``comment`` lines of a PLY header."""
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ParselError(f"{path}: not a PLY file (no 'ply' ... 'end_header' header)")
    lines = head[:end].decode("latin-1").splitlines()
    return [line.strip()[len("comment"):].strip() for line in lines if line.strip().startswith("comment")]


def read_ply(path: Path) -> NamedMeshes:
    """A PLY whose faces carry a ``part`` property, named by ``comment part <i> <name>`` lines."""
    import trimesh

    try:
        names = _part_names(ply_comments(path), path)
    except OSError as exc:
        raise ParselError(f"{path}: cannot read: {exc.strerror}") from None
    if not names:
        raise ParselError(f"{path}: {NO_NAMED_PARTS} (a PLY names its parts with 'comment part <index> <name>' "
                          f"lines and a 'part' face property)")
    try:
        mesh = trimesh.load(str(path), file_type="ply", force="mesh", process=False)
    except Exception as exc:
        raise _read_failure(path, "PLY", exc) from None
    try:
        tags = mesh.metadata["_ply_raw"]["face"]["data"]["part"]
    except (KeyError, TypeError, ValueError, IndexError):
        raise ParselError(f"{path}: PLY declares part names but its faces have no 'part' property") from None
    return _split_tagged(path, mesh, tags, names)


def parse_off(text: str, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[int, str]]:
    """Vertices, triangles (polygons fanned), each triangle's part index and the part names.

    Part names come from ``# part <index> <name>`` comments; each face line ends with its
    part index (one integer after the vertex indices, where OFF allows a colour-map index).
    """
    comments, rows = [], []
    for line in text.splitlines():
        body, hash_, comment = line.partition("#")
        if hash_:
            comments.append(comment)
        if body.strip():
            rows.append(body.split())
    names = _part_names(comments, path)
    if not rows or rows[0][0].upper() not in ("OFF", "COFF"):
        raise ParselError(f"{path}: not an OFF file (first line must be OFF or COFF)")
    header = rows[0][1:] or (rows[1] if len(rows) > 1 else [])
    body = rows[1:] if rows[0][1:] else rows[2:]
    try:
        n_vertices, n_faces = int(header[0]), int(header[1])
        vertices = np.array([[float(x) for x in row[:3]] for row in body[:n_vertices]], dtype=float)
        if vertices.shape != (n_vertices, 3) or len(body) < n_vertices + n_faces:
            raise ValueError("fewer vertices or faces than its header declares")
        if not names:
            raise ParselError(f"{path}: {NO_NAMED_PARTS} (an OFF names its parts with '# part <index> <name>' "
                              f"comments and a part index after each face's vertex indices)")
        triangles, tags = [], []
        for i, row in enumerate(body[n_vertices:n_vertices + n_faces]):
            count = int(row[0])
            if len(row) != count + 2:
                raise ValueError(f"face {i} has no part index (expected {count} vertex indices then one integer)")
            indices = [int(x) for x in row[1:count + 1]]
            for k in range(1, count - 1):
                triangles.append((indices[0], indices[k], indices[k + 1]))
                tags.append(int(row[count + 1]))
    except (ValueError, IndexError) as exc:
        raise ParselError(f"{path}: malformed OFF: {exc}") from None
    return vertices, np.array(triangles, dtype=np.int64).reshape(-1, 3), np.array(tags, dtype=np.int64), names


def read_off(path: Path) -> NamedMeshes:
    """An OFF whose faces carry part indices named in ``# part`` comments (see :func:`parse_off`)."""
    import trimesh

    try:
        text = path.read_bytes().decode("utf-8", errors="replace")
    except OSError as exc:
        raise ParselError(f"{path}: cannot read: {exc.strerror}") from None
    vertices, triangles, tags, names = parse_off(text, path)
    if len(triangles) and (triangles.min() < 0 or triangles.max() >= len(vertices)):
        raise ParselError(f"{path}: malformed OFF: a face indexes a missing vertex")
    mesh = trimesh.Trimesh(vertices=vertices, faces=triangles, process=False, validate=False)
    return _split_tagged(path, mesh, tags, names)


READERS: dict[str, Callable[[Path], NamedMeshes]] = {
    ".glb": read_scene,
    ".gltf": read_scene,
    ".stl": read_scene,
    ".obj": read_obj,
    ".ply": read_ply,
    ".off": read_off,
}


def load_mesh_shape(path: Path | str) -> ShapeGraph:
    """A shape from a mesh file or a PartNet directory, labels overridden by a sidecar if present."""
    from parsel_mesh import partnet

    path = Path(path)
    if not path.exists():
        raise ParselError(f"{path}: no such file or directory")
    if partnet.is_partnet(path):
        return partnet.load_partnet(path)
    if path.is_dir():
        raise ParselError(f"{path}: a directory that is not a PartNet shape (no {partnet.HIERARCHY_FILE})")
    suffix = path.suffix.lower()
    if suffix not in READERS:
        raise ParselError(f"{path}: unknown mesh suffix {suffix!r} (reads {', '.join(sorted(READERS))})")
    from parsel_mesh.prefit import read_prefit, shape_from_prefit

    prefit = read_prefit(path)  # fitted boxes saved beside the file: no mesh read until one is used
    if prefit is not None:
        return shape_from_prefit(path, prefit, suffix.lstrip("."))
    meshes = READERS[suffix](path)
    return assemble(path, meshes, {}, suffix.lstrip("."))


def assemble(path: Path, meshes: NamedMeshes, defaults: Mapping[str, str], kind: str) -> ShapeGraph:
    """The shape of named meshes read from ``path``, with sidecar labels applied."""
    names = [name for name, _ in meshes]
    resolved = path.resolve()  # "." has no name to derive a sidecar or a shape name from
    labels = resolve_labels(names, read_sidecar(resolved), source=str(sidecar_path(resolved)), defaults=defaults)
    stem = resolved.name if resolved.is_dir() else resolved.stem
    metadata: dict[str, Any] = {"format": kind, "loader": "parsel-mesh"}
    hierarchy = {name: list(mesh.metadata.get("parents", [])) for name, mesh in meshes
                 if getattr(mesh, "metadata", None) and mesh.metadata.get("parents")}
    if hierarchy:
        metadata["hierarchy"] = hierarchy  # part id -> names of its ancestor nodes, root first
    return shape_from_meshes(meshes, name=stem, source=str(path), labels=labels, metadata=metadata)


class MeshLoader(ShapeLoader):
    """One mesh format read through trimesh (see the module docstring for where parts come from)."""

    def __init__(self, name: str, extensions: tuple[str, ...]) -> None:
        self.name = name
        self.extensions = extensions

    def load(self, path: Path) -> ShapeGraph:
        return load_mesh_shape(path)


class PartNetLoader(ShapeLoader):
    """A PartNet shape directory (or its ``result_after_merging.json``): leaf parts."""

    name = "partnet"
    extensions = ()

    def can_load(self, path: Path) -> bool:
        from parsel_mesh.partnet import is_partnet

        return is_partnet(Path(path))

    def load(self, path: Path) -> ShapeGraph:
        from parsel_mesh.partnet import load_partnet

        return load_partnet(Path(path))


def shape_loaders() -> list[ShapeLoader]:
    """The loaders this plugin registers, one per format."""
    return [
        MeshLoader("mesh-gltf", (".glb", ".gltf")),
        MeshLoader("mesh-obj", (".obj",)),
        MeshLoader("mesh-ply", (".ply",)),
        MeshLoader("mesh-off", (".off",)),
        MeshLoader("mesh-stl", (".stl",)),
        PartNetLoader(),
    ]
