"""Pre-fitted parts: a sidecar that lets a mesh asset load without reading its meshes.

Fitting a part's box needs its mesh, and reading a GLB needs trimesh, whose import alone
costs more CPU than a whole edit request. ``<file>.parts.json`` beside an asset records,
for the file's SHA-256, each part's name and fitted hexahedron (and the node hierarchy).
The loader then builds the shape from it and gives each part a :class:`LazyMesh` that
reads the file on first use (deforming, exporting, the slider page), so ``parsel edit``
and ``parsel inspect`` never read a mesh. A sidecar whose hash does not match the file
is ignored; labels still come from the ``.labels.json`` sidecar at each load. The
bundled examples carry one, written by ``python -m parsel_mesh.examples.build``; a test
checks each against a fresh fit.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.io import atomic_write_text, read_json
from parsel_core.part import Part
from parsel_mesh.naming import natural_key, read_sidecar, resolve_labels, sidecar_path

PREFIT_FORMAT = "parsel.prefit"
PREFIT_VERSION = 1
PREFIT_SUFFIX = ".parts.json"


def prefit_path(path: Path) -> Path:
    """``chair.glb`` -> ``chair.glb.parts.json`` beside it."""
    return path.with_name(path.name + PREFIT_SUFFIX)


def file_digest(path: Path) -> str:
    """SHA-256 of the file's bytes, as hex."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def prefit_data(path: Path) -> dict[str, Any]:
    """The sidecar document of a mesh file, from a full read and fit of its parts."""
    from parsel_mesh.loaders import READERS, shape_from_meshes

    path = Path(path)
    meshes = READERS[path.suffix.lower()](path)
    shape = shape_from_meshes(meshes, labels={name: name for name, _ in meshes})  # labels are not stored
    hierarchy = {name: list(mesh.metadata.get("parents", [])) for name, mesh in meshes
                 if getattr(mesh, "metadata", None) and mesh.metadata.get("parents")}
    return {
        "format": PREFIT_FORMAT,
        "version": PREFIT_VERSION,
        "sha256": file_digest(path),
        "names": [name for name, _ in meshes],  # file order: label resolution sees them so
        "corners": {pid: part.hexahedron.corners.tolist() for pid, part in shape.parts.items()},
        "hierarchy": hierarchy,
    }


def write_prefit(path: Path) -> Path:
    """Write (or refresh) the sidecar of a mesh file; returns its path."""
    path = Path(path)
    target = prefit_path(path)
    data = prefit_data(path)
    lines = [f" {json.dumps(key)}: {json.dumps(value)}" for key, value in data.items() if key != "corners"]
    corners = ",\n".join(f"  {json.dumps(pid)}: {json.dumps(c)}" for pid, c in data["corners"].items())
    lines.append(f' "corners": {{\n{corners}\n }}')
    atomic_write_text(target, "{\n" + ",\n".join(lines) + "\n}\n")
    return target


def read_prefit(path: Path) -> dict[str, Any] | None:
    """The sidecar of ``path`` when there is one for these exact bytes, else ``None``."""
    sidecar = prefit_path(path)
    if not sidecar.is_file():
        return None
    data = read_json(sidecar, "pre-fitted parts")
    if not isinstance(data, dict) or data.get("format") != PREFIT_FORMAT:
        raise ParselError(f"{sidecar}: not a pre-fitted parts file (expected \"format\": \"{PREFIT_FORMAT}\")")
    if data.get("version") != PREFIT_VERSION:
        return None  # written by another parsel: fit afresh
    if data.get("sha256") != file_digest(path):
        return None  # the asset changed since: fit afresh
    names, corners, hierarchy = data.get("names"), data.get("corners"), data.get("hierarchy", {})
    if not isinstance(names, list) or not isinstance(corners, dict) or set(names) != set(corners) \
            or not isinstance(hierarchy, dict):
        raise ParselError(f"{sidecar}: \"names\" and \"corners\" must list the same parts")
    return data


def shape_from_prefit(path: Path, data: dict[str, Any], kind: str) -> ShapeGraph:
    """The shape :func:`parsel_mesh.loaders.load_mesh_shape` would build, from the sidecar."""
    resolved = path.resolve()
    names = [str(n) for n in data["names"]]
    labels = resolve_labels(names, read_sidecar(resolved), source=str(sidecar_path(resolved)))
    digest = data["sha256"]
    parts = []
    for name in sorted(names, key=natural_key):
        try:
            hexahedron = Hexahedron(np.asarray(data["corners"][name], dtype=float))
        except (TypeError, ValueError) as exc:
            raise ParselError(f"{prefit_path(path)}: corners of part {name!r}: {exc}") from None
        parts.append(Part(name, labels[name], hexahedron, name=name, mesh=LazyMesh(str(path), name, digest)))
    metadata: dict[str, Any] = {"format": kind, "loader": "parsel-mesh"}
    if data.get("hierarchy"):
        metadata["hierarchy"] = {str(k): list(v) for k, v in data["hierarchy"].items()}
    return ShapeGraph(parts, name=resolved.stem, source=str(path), metadata=metadata)


@lru_cache(maxsize=8)
def _read_meshes(path: str, digest: str) -> dict[str, Any]:
    """Every part mesh of a file, read once for all its lazy parts."""
    from parsel_mesh.loaders import READERS

    file = Path(path)
    if not file.is_file() or file_digest(file) != digest:
        raise ParselError(f"{path}: changed or removed since the shape was loaded; load it again")
    return dict(READERS[file.suffix.lower()](file))


class LazyMesh:
    """A part's mesh, read from its file on first use; attributes are the mesh's own.

    ``part.mesh.vertices`` and the like read the file (once for all parts); ``load()``
    returns the mesh itself where an API needs the real object.
    """

    __slots__ = ("path", "part", "digest")

    def __init__(self, path: str, part: str, digest: str) -> None:
        self.path, self.part, self.digest = path, part, digest

    def load(self) -> Any:
        return _read_meshes(self.path, self.digest)[self.part]

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.load(), name)

    def __reduce__(self):
        return (LazyMesh, (self.path, self.part, self.digest))

    def __repr__(self) -> str:
        return f"LazyMesh({self.path!r}, {self.part!r})"
