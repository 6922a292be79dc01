"""Writers of the watertight remesh: OBJ with one group per label, PLY with a label per face, GLB.

The suffixes are double (``.watertight.obj``) so the exporter is chosen by name next to
the plain mesh exporters (``parsel_core.plugins.exporter_for`` asks later plugins
first, and ``remesh`` loads after ``mesh``). The grid resolution comes from
``PARSEL_REMESH_RESOLUTION`` (default 160 cells along the shape's longest side), since
``parsel apply`` passes exporters no options. Files are encoded in memory and written
with ``parsel_core.io.atomic_write_bytes``: never a partial file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import Exporter
from parsel_core.io import atomic_write_bytes
from parsel_core.program import Evaluation


def resolution_from_env() -> int:
    text = os.environ.get("PARSEL_REMESH_RESOLUTION", "").strip()
    if not text:
        from parsel_remesh.remesh import DEFAULT_RESOLUTION

        return DEFAULT_RESOLUTION
    try:
        return int(text)
    except ValueError:
        raise ParselError(f"PARSEL_REMESH_RESOLUTION={text!r}: expected an integer") from None


def label_rgba(labels: list[str]) -> dict[str, np.ndarray]:
    """The labels' colours of ``parsel inspect --png``, as RGBA bytes."""
    from parsel_core.drawing import label_colours

    return {label: (np.asarray(c) * 255).round().astype(np.uint8) for label, c in label_colours(labels).items()}


def encode_obj(result, title: str) -> bytes:
    """One ``o`` object whose faces are in one ``g`` group per label (vertices shared, so still closed)."""
    lines = [f"# parsel watertight remesh of {' '.join(title.split()) or 'shape'}", "o watertight"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(result.mesh.vertices, dtype=float).tolist()]
    faces = np.asarray(result.mesh.faces, dtype=np.int64) + 1
    for label in result.labels:
        lines.append(f"g {label}")
        lines += [f"f {a} {b} {c}" for a, b, c in faces[result.face_labels == label].tolist()]
    return ("\n".join(lines) + "\n").encode("utf-8")


def encode_ply(result, title: str) -> bytes:
    """Binary PLY: shared vertices, faces with a ``part`` index (the label's) and an RGBA colour."""
    labels = result.labels
    index = {label: i for i, label in enumerate(labels)}
    colours = label_rgba(labels)
    face_dtype = np.dtype([("count", "u1"), ("vertex_indices", "<i4", (3,)), ("part", "<i4"),
                           ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")])
    faces = np.zeros(len(result.mesh.faces), dtype=face_dtype)
    faces["count"] = 3
    faces["vertex_indices"] = np.asarray(result.mesh.faces, dtype=np.int64)
    faces["part"] = [index[label] for label in result.face_labels]
    rgba = np.array([colours[label] for label in result.face_labels], dtype=np.uint8).reshape(-1, 4)
    for k, channel in enumerate(("red", "green", "blue", "alpha")):
        faces[channel] = rgba[:, k]
    vertices = np.asarray(result.mesh.vertices, dtype="<f8")
    header = ["ply", "format binary_little_endian 1.0",
              f"comment parsel watertight remesh of {' '.join(title.split())}"]
    header += [f"comment part {i} {label}" for i, label in enumerate(labels)]
    header += [f"element vertex {len(vertices)}", "property double x", "property double y", "property double z",
               f"element face {len(faces)}", "property list uchar int vertex_indices", "property int part",
               "property uchar red", "property uchar green", "property uchar blue", "property uchar alpha",
               "end_header"]
    return ("\n".join(header) + "\n").encode("ascii", errors="replace") + vertices.tobytes() + faces.tobytes()


def encode_glb(result, title: str) -> bytes:
    """A scene with one node ``watertight``: the closed mesh, coloured per face by label."""
    import trimesh

    colours = label_rgba(result.labels)
    mesh = result.mesh.copy()
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=np.array([colours[lb] for lb in result.face_labels]))
    scene = trimesh.Scene()
    scene.add_geometry(mesh, node_name="watertight", geom_name="watertight")
    return scene.export(file_type="glb")


class WatertightExporter(Exporter):
    """The remeshed shape in one file; subclasses choose the encoding."""

    def can_export(self, shape: ShapeGraph) -> bool:
        """Any shape: parts without meshes are remeshed as their boxes."""
        return bool(shape.parts)

    def encode(self, result, title: str) -> bytes:
        raise NotImplementedError

    def export(self, shape: ShapeGraph, evaluation: Evaluation | None, path: Path) -> None:
        path = Path(path)
        if path.is_dir():
            raise ParselError(f"{path}: is a directory")
        if not path.parent.is_dir():
            raise ParselError(f"{path}: output directory {path.parent} does not exist")
        from parsel_remesh.remesh import remesh

        result = remesh(shape, evaluation, resolution=resolution_from_env())
        atomic_write_bytes(path, self.encode(result, shape.name))


class WatertightOBJExporter(WatertightExporter):
    name = "watertight-obj"
    extensions = (".watertight.obj",)

    def encode(self, result, title):
        return encode_obj(result, title)


class WatertightPLYExporter(WatertightExporter):
    name = "watertight-ply"
    extensions = (".watertight.ply",)

    def encode(self, result, title):
        return encode_ply(result, title)


class WatertightGLBExporter(WatertightExporter):
    name = "watertight-glb"
    extensions = (".watertight.glb",)

    def encode(self, result, title):
        return encode_glb(result, title)


def watertight_exporters() -> list[WatertightExporter]:
    return [WatertightOBJExporter(), WatertightPLYExporter(), WatertightGLBExporter()]
