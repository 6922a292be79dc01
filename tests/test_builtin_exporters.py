"""The core's hexahedra exporters: closed boxes facing outward, mirrored parts included."""

from __future__ import annotations

import numpy as np
import pytest

from parsel_core.examples import tiny_table
from parsel_core.plugins import exporters
from parsel_core.program import Program, evaluate


def obj_volumes(text: str) -> dict[str, float]:
    """Signed volume per object by the divergence theorem: positive when its faces face outward."""
    volumes: dict[str, float] = {}
    vertices: list[list[float]] = []
    name = ""
    for line in text.splitlines():
        key, *rest = line.split()
        if key == "o":
            name, volumes[name] = rest[0], 0.0
        elif key == "v":
            vertices.append([float(v) for v in rest])
        elif key == "f":
            a, b, c, d = (np.array(vertices[int(i) - 1]) for i in rest)
            volumes[name] += (a @ np.cross(b, c) + a @ np.cross(c, d)) / 6.0
    return volumes


@pytest.mark.parametrize("amount", [0.5, -3.0])  # -3: the top is mirrored through its centre plane
def test_hexahedra_obj_faces_outward(tmp_path, amount):
    table = tiny_table()
    program = Program.from_text(f"scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount={amount})")
    evaluation = evaluate(program, table, {})
    path = tmp_path / "table.obj"
    exporters()["hexahedra-obj"].export(table, evaluation, path)
    volumes = obj_volumes(path.read_text())
    assert sorted(volumes) == sorted(table.parts)
    assert volumes["top"] == pytest.approx(1.0 * abs(1 + amount) * 0.05 * 0.6)
    assert all(v > 0 for v in volumes.values())
