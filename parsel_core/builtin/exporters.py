"""Writers of edited hexahedra: JSON corners and an OBJ of boxes, for any shape."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from parsel_core import hookimpl
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import FACE_QUADS, Hexahedron
from parsel_core.interfaces import Exporter
from parsel_core.io import atomic_write_text
from parsel_core.program import Evaluation


def _solid_parts(shape: ShapeGraph, evaluation: Evaluation) -> list[tuple[str, np.ndarray]]:
    """Every real part's corners, with groups whose layout changed replaced by their instances."""
    replaced = {m for g in evaluation.instances for m in shape.relations[g].members}
    out = [(pid, np.asarray(evaluation.parts[pid])) for pid in shape.parts if pid not in replaced]
    for group, instances in evaluation.instances.items():
        first = shape.relations[group].members[0]
        out.extend((f"{first}#{i}", corners) for i, corners in enumerate(instances))
    return out


class HexahedraJSONExporter(Exporter):
    """``{"parts": {id: corners}}``: the edited proxies, for other tools and for audits."""

    name = "hexahedra-json"
    extensions = (".hex.json",)

    def export(self, shape: ShapeGraph, evaluation: Evaluation, path: Path) -> None:
        data = {"shape": shape.name, "parts": {pid: c.tolist() for pid, c in _solid_parts(shape, evaluation)}}
        atomic_write_text(path, json.dumps(data, indent=1) + "\n")


class HexahedraOBJExporter(Exporter):
    """One OBJ object per part: its edited hexahedron as a closed quad mesh."""

    name = "hexahedra-obj"
    extensions = (".obj",)

    def export(self, shape: ShapeGraph, evaluation: Evaluation, path: Path) -> None:
        lines = [f"# {shape.name}: edited hexahedra"]
        base = 1
        for pid, corners in _solid_parts(shape, evaluation):
            lines.append(f"o {pid}")
            lines.extend(f"v {x!r} {y!r} {z!r}" for x, y, z in corners.tolist())
            mirrored = Hexahedron(corners).volume < 0  # a mirrored frame: reverse the quads to face outward
            lines.extend("f " + " ".join(str(base + k) for k in (quad[::-1] if mirrored else quad))
                         for quad in FACE_QUADS)
            base += 8
        atomic_write_text(path, "\n".join(lines) + "\n")


@hookimpl
def parsel_exporters():
    return [HexahedraJSONExporter(), HexahedraOBJExporter()]
