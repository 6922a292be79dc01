"""Checks on the bundled example assets and their generator.

The relation detectors are tested against these assets, so the geometric facts they
are meant to exhibit (floor contact, mirror pairs, evenly spaced copies, attached
parts) are asserted here on the reloaded GLB files rather than on in-memory meshes.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

PLUGIN_DIR = Path(__file__).resolve().parents[1]
if str(PLUGIN_DIR) not in sys.path:
    sys.path.insert(0, str(PLUGIN_DIR))

build = importlib.import_module("parsel_mesh.examples.build")

ASSETS = ("chair", "table", "cabinet", "shelf")


def _indexed(label: str, count: int) -> list[str]:
    return [f"{label}.{i:03d}" for i in range(count)]


PART_NAMES: dict[str, list[str]] = {
    "chair": [
        "seat",
        *_indexed("leg", 4),
        *_indexed("back_upright", 2),
        "back_rail",
        *_indexed("back_slat", 5),
    ],
    "table": ["top", *_indexed("leg", 4), *_indexed("apron", 4)],
    "cabinet": ["body", *_indexed("door", 2), *_indexed("handle", 2), "plinth"],
    "shelf": [*_indexed("side_panel", 2), *_indexed("board", 5), "back_panel"],
}

GROUND_PARTS: dict[str, set[str]] = {
    "chair": set(_indexed("leg", 4)),
    "table": set(_indexed("leg", 4)),
    "cabinet": {"plinth"},
    "shelf": set(_indexed("side_panel", 2)),
}

X, Y, Z = 0, 1, 2

MIRROR_PAIRS: dict[str, list[tuple[str, str, int]]] = {
    "chair": [
        ("leg.000", "leg.001", X),
        ("leg.002", "leg.003", X),
        ("leg.000", "leg.002", Z),
        ("leg.001", "leg.003", Z),
        ("back_upright.000", "back_upright.001", X),
    ],
    "table": [
        ("leg.000", "leg.001", X),
        ("leg.002", "leg.003", X),
        ("leg.000", "leg.002", Z),
        ("apron.000", "apron.001", Z),
        ("apron.002", "apron.003", X),
    ],
    "cabinet": [("door.000", "door.001", X), ("handle.000", "handle.001", X)],
    "shelf": [("side_panel.000", "side_panel.001", X)],
}

ROWS: dict[str, list[tuple[list[str], tuple[float, float, float]]]] = {
    "chair": [(_indexed("back_slat", 5), (0.06, 0.0, 0.0))],
    "shelf": [(_indexed("board", 5), (0.0, 0.383, 0.0))],
}

CONTACTS: dict[str, list[tuple[str, str]]] = {
    "chair": [
        *[(leg, "seat") for leg in _indexed("leg", 4)],
        *[(upright, "seat") for upright in _indexed("back_upright", 2)],
        *[(upright, "back_rail") for upright in _indexed("back_upright", 2)],
        *[(slat, "seat") for slat in _indexed("back_slat", 5)],
        *[(slat, "back_rail") for slat in _indexed("back_slat", 5)],
    ],
    "table": [
        *[(leg, "top") for leg in _indexed("leg", 4)],
        *[(apron, "top") for apron in _indexed("apron", 4)],
        ("apron.000", "leg.000"),
        ("apron.000", "leg.001"),
        ("apron.001", "leg.002"),
        ("apron.001", "leg.003"),
        ("apron.002", "leg.000"),
        ("apron.002", "leg.002"),
        ("apron.003", "leg.001"),
        ("apron.003", "leg.003"),
    ],
    "cabinet": [
        ("body", "plinth"),
        ("door.000", "body"),
        ("door.001", "body"),
        ("handle.000", "door.000"),
        ("handle.001", "door.001"),
    ],
    "shelf": [
        *[
            (board, side)
            for board in _indexed("board", 5)
            for side in _indexed("side_panel", 2)
        ],
        *[(board, "back_panel") for board in _indexed("board", 5)],
        *[("back_panel", side) for side in _indexed("side_panel", 2)],
    ],
}

MIN_JOINT_OVERLAP = 0.0015
"""Attached parts interpenetrate by at least this much (m) on every axis."""


@pytest.fixture(scope="module")
def built_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("examples")
    build.build(out)
    return out


@pytest.fixture(scope="module")
def scenes(built_dir: Path) -> dict[str, trimesh.Scene]:
    return {
        name: trimesh.load(built_dir / f"{name}.glb", force="scene") for name in ASSETS
    }


def _part(scene: trimesh.Scene, name: str) -> trimesh.Trimesh:
    return scene.geometry[name]


def _same_point_sets(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    if a.shape != b.shape:
        return False
    return bool(
        cKDTree(b).query(a)[0].max() <= tol and cKDTree(a).query(b)[0].max() <= tol
    )


@pytest.mark.parametrize("asset", ASSETS)
def test_part_names(scenes: dict[str, trimesh.Scene], asset: str) -> None:
    scene = scenes[asset]
    assert sorted(scene.graph.nodes_geometry) == sorted(PART_NAMES[asset])
    assert sorted(scene.geometry) == sorted(PART_NAMES[asset])


@pytest.mark.parametrize("asset", ASSETS)
def test_nodes_are_world_space_parts_with_materials(
    scenes: dict[str, trimesh.Scene], asset: str
) -> None:
    scene = scenes[asset]
    for node in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[node]
        assert geometry == node
        np.testing.assert_array_equal(transform, np.eye(4))
        material = scene.geometry[geometry].visual.material
        assert material.name == node.split(".")[0]
        assert material.baseColorFactor is not None


@pytest.mark.parametrize("asset", ASSETS)
def test_parts_are_closed_solids(scenes: dict[str, trimesh.Scene], asset: str) -> None:
    for name, mesh in scenes[asset].geometry.items():
        assert mesh.is_watertight, name
        assert mesh.is_winding_consistent, name
        assert mesh.volume > 0, name
        assert 100 <= len(mesh.vertices) <= 5000, name


@pytest.mark.parametrize("asset", ASSETS)
def test_ground_parts_stand_on_floor(
    scenes: dict[str, trimesh.Scene], asset: str
) -> None:
    scene = scenes[asset]
    on_floor = {
        name for name, mesh in scene.geometry.items() if abs(mesh.bounds[0][Y]) <= 1e-9
    }
    assert on_floor == GROUND_PARTS[asset]
    assert min(mesh.bounds[0][Y] for mesh in scene.geometry.values()) >= 0.0


@pytest.mark.parametrize(
    ("asset", "height"),
    [("chair", 0.90), ("table", 0.75), ("cabinet", 0.90), ("shelf", 1.60)],
)
def test_overall_height_and_centring(
    scenes: dict[str, trimesh.Scene], asset: str, height: float
) -> None:
    bounds = scenes[asset].bounds
    assert bounds[1][Y] == pytest.approx(height, abs=1e-6)
    assert bounds[0][X] == pytest.approx(-bounds[1][X], abs=1e-6)


def test_chair_seat_height(scenes: dict[str, trimesh.Scene]) -> None:
    assert _part(scenes["chair"], "seat").bounds[1][Y] == pytest.approx(0.45, abs=1e-6)


@pytest.mark.parametrize("asset", ASSETS)
def test_mirror_pairs(scenes: dict[str, trimesh.Scene], asset: str) -> None:
    scene = scenes[asset]
    for first, second, axis in MIRROR_PAIRS[asset]:
        reflected = _part(scene, first).vertices.copy()
        reflected[:, axis] *= -1
        assert _same_point_sets(reflected, _part(scene, second).vertices, 1e-9), (
            first,
            second,
        )
        assert len(_part(scene, first).faces) == len(_part(scene, second).faces)


@pytest.mark.parametrize("asset", sorted(ROWS))
def test_rows_are_evenly_spaced_translated_copies(
    scenes: dict[str, trimesh.Scene], asset: str
) -> None:
    scene = scenes[asset]
    for names, step in ROWS[asset]:
        first = _part(scene, names[0])
        centres = np.array([_part(scene, n).bounds.mean(axis=0) for n in names])
        np.testing.assert_allclose(
            np.diff(centres, axis=0), np.tile(step, (len(names) - 1, 1)), atol=1e-6
        )
        for k, name in enumerate(names):
            moved = first.vertices + k * np.asarray(step)
            assert _same_point_sets(moved, _part(scene, name).vertices, 1e-6), name


@pytest.mark.parametrize("asset", ASSETS)
def test_attached_parts_interpenetrate(
    scenes: dict[str, trimesh.Scene], asset: str
) -> None:
    scene = scenes[asset]
    for a, b in CONTACTS[asset]:
        lo = np.maximum(_part(scene, a).bounds[0], _part(scene, b).bounds[0])
        hi = np.minimum(_part(scene, a).bounds[1], _part(scene, b).bounds[1])
        assert np.all(hi - lo >= MIN_JOINT_OVERLAP), (a, b, hi - lo)


@pytest.mark.parametrize("asset", ASSETS)
def test_every_part_is_connected(asset: str) -> None:
    graph = nx.Graph(CONTACTS[asset])
    graph.add_nodes_from(PART_NAMES[asset])
    assert nx.is_connected(graph)


@pytest.mark.parametrize("asset", ASSETS)
def test_committed_glb_matches_fresh_build(built_dir: Path, asset: str) -> None:
    committed = build.EXAMPLES_DIR / f"{asset}.glb"
    assert committed.is_file(), (
        f"missing {committed}; run python -m parsel_mesh.examples.build"
    )
    # Geometry, names and materials, not bytes: GLB encoding differs between trimesh releases.
    shipped = trimesh.load(committed, force="scene")
    fresh = trimesh.load(built_dir / f"{asset}.glb", force="scene")
    assert sorted(shipped.geometry) == sorted(fresh.geometry), f"{committed.name} is stale; rebuild it"
    for name, mesh in fresh.geometry.items():
        assert np.allclose(shipped.geometry[name].vertices, mesh.vertices, atol=1e-9), name
        assert np.array_equal(shipped.geometry[name].faces, mesh.faces), name


def test_rebuild_is_byte_identical(built_dir: Path, tmp_path: Path) -> None:
    build.build(tmp_path)
    for asset in ASSETS:
        assert (tmp_path / f"{asset}.glb").read_bytes() == (
            built_dir / f"{asset}.glb"
        ).read_bytes(), asset


def test_bundle_is_small() -> None:
    total = sum(
        (build.EXAMPLES_DIR / f"{asset}.glb").stat().st_size for asset in ASSETS
    )
    assert total < 2_000_000


def test_runs_as_script(built_dir: Path, tmp_path: Path) -> None:
    script = Path(build.__file__)
    subprocess.run(
        [sys.executable, str(script), "--out", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    for asset in ASSETS:
        assert (tmp_path / f"{asset}.glb").read_bytes() == (
            built_dir / f"{asset}.glb"
        ).read_bytes()
    assert build.main(["--check", "--out", str(tmp_path)]) == 0
