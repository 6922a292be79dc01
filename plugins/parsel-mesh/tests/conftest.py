"""Fixtures: small meshes and scenes built in memory (no asset files but the PartNet fixture)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import trimesh

from parsel_core.graph import ShapeGraph
from parsel_core.relations import TranslationSymmetry
from parsel_mesh.loaders import shape_from_meshes
from parsel_mesh.testing import box_mesh, named_scene

FIXTURES = Path(__file__).resolve().parent / "fixtures"


def small_parts() -> dict[str, trimesh.Trimesh]:
    """A seat, two mirrored legs and a back: enough for names, labels and symmetry."""
    return {
        "Seat": box_mesh((-0.2, 0.4, -0.2), (0.2, 0.45, 0.2)),
        "leg.000": box_mesh((-0.2, 0.0, -0.02), (-0.16, 0.4, 0.02)),
        "leg.001": box_mesh((0.16, 0.0, -0.02), (0.2, 0.4, 0.02)),
        "back_slat_2": box_mesh((-0.05, 0.45, -0.2), (0.05, 0.9, -0.18)),
    }


@pytest.fixture
def parts() -> dict[str, trimesh.Trimesh]:
    return small_parts()


@pytest.fixture
def write_glb(tmp_path: Path) -> Callable[..., Path]:
    def write(meshes: dict[str, trimesh.Trimesh] | None = None, name: str = "shape.glb") -> Path:
        path = tmp_path / name
        path.write_bytes(named_scene(meshes or small_parts()).export(file_type="glb"))
        return path

    return write


@pytest.fixture
def partnet_dir() -> Path:
    return FIXTURES / "partnet_chair"


@pytest.fixture
def row_shape() -> ShapeGraph:
    """Three box slats 0.2 apart in a translation group ``row`` (members slat_0..slat_2)."""
    meshes = {f"slat_{i}": box_mesh((0.2 * i, 0, 0), (0.2 * i + 0.05, 0.4, 0.02)) for i in range(3)}
    identity = tuple(range(8))
    row = TranslationSymmetry("row", ("slat_0", "slat_1", "slat_2"), step=(0.2, 0.0, 0.0),
                              correspondence=(identity,) * 3)
    return shape_from_meshes(meshes, name="row").with_relations([row])
