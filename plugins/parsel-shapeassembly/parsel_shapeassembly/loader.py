"""ShapeAssembly files -> shape graphs of labelled boxes with declared relations."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.interfaces import ShapeLoader
from parsel_core.io import read_json
from parsel_core.mesh import box_mesh
from parsel_core.part import Part

MAGIC = "Assembly Program_0"


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_labels_sidecar(path: Path, names: set[str]) -> dict[str, str]:
    """``<stem>.labels.json`` beside the file: part name -> label; unknown names are errors."""
    sidecar = path.with_name(path.name.split(".")[0] + ".labels.json")
    if not sidecar.exists():
        return {}
    data = read_json(sidecar, "labels")
    if not isinstance(data, dict) or not all(isinstance(v, str) for v in data.values()):
        raise ParselError(f"{sidecar}: labels must be a JSON object of part name -> label")
    unknown = sorted(set(data) - names)
    if unknown:
        raise ParselError(f"{sidecar}: names unknown part(s) {', '.join(unknown)}")
    return data


class ShapeAssemblyLoader(ShapeLoader):
    """Programs (``.sa``, or ``.txt`` starting with ``Assembly Program_0``) executed as in the paper."""

    name = "shapeassembly"
    extensions = (".sa", ".txt")

    def can_load(self, path: Path) -> bool:
        if path.suffix.lower() == ".sa":
            return True
        if path.suffix.lower() != ".txt" or not path.is_file():
            return False
        try:
            with path.open(encoding="utf-8") as handle:
                return handle.read(len(MAGIC) + 64).lstrip().startswith(MAGIC)
        except (OSError, UnicodeDecodeError):
            return False

    def load(self, path: Path) -> ShapeGraph:
        # Here, not at the top: every command lists the loaders, few read a program.
        from parsel_shapeassembly.interpreter import ShapeAssemblyError, execute
        from parsel_shapeassembly.labels import CATEGORIES, label_parts

        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ParselError(f"{path}: cannot read: {exc}") from None
        from parsel_core.config import check_limit

        check_limit("max_program_lines", f"{path}: lines", text.count("\n") + 1)
        try:
            executed = execute(text, source=str(path))
        except ShapeAssemblyError as exc:
            raise ParselError(str(exc)) from None
        if not executed.cuboids:
            raise ParselError(f"{path}: the program has no leaf cuboids")
        check_limit("max_parts", f"{path}: leaf cuboids", len(executed.cuboids))  # before labelling them
        hexahedra = {c.name: Hexahedron.canonical_box(c.center, c.dims, c.axes) for c in executed.cuboids}
        category = path.parent.name if path.parent.name in CATEGORIES else None
        labels = label_parts(category, {n: h.corners for n, h in hexahedra.items()})
        labels.update(read_labels_sidecar(path, set(hexahedra)))
        parts = [Part(name, labels[name], h, name=name, mesh=box_mesh(h)) for name, h in hexahedra.items()]
        declared = [{"kind": r.kind, "members": list(r.members), "params": _jsonable(r.params)}
                    for r in executed.relations]
        return ShapeGraph(parts, name=f"{category + '/' if category else ''}{path.stem}", source=str(path),
                          metadata={"category": category, "declared_relations": declared})

    @staticmethod
    def declared(shape: ShapeGraph) -> list[dict]:
        return shape.metadata.get("declared_relations", [])



