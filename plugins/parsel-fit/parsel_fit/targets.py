"""Targets to fit to: a mesh, a point cloud, or another shape, as surface points.

Point clouds are read as numbers (``.xyz``/``.pts``/``.txt``: three columns, ``.npy``:
an (n, 3) array; nothing is evaluated), mesh and point-cloud files through trimesh
(``.ply``, ``.obj``, ``.off``, ``.stl``, ``.glb``, ``.gltf``), anything else as a
parsel shape (an example name, a ShapeAssembly program, a ``.shape.json``, a PartNet
folder), whose parts' surfaces are sampled at rest.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from parsel_core.errors import ParselError

POINT_SUFFIXES = (".xyz", ".pts", ".npy")
MESH_SUFFIXES = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")
DEFAULT_TARGET_SAMPLES = 4096


def _checked(points: np.ndarray, where: str) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise ParselError(f"{where}: expected a non-empty list of 3D points, got an array of shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ParselError(f"{where}: points must be finite numbers")
    return points


def read_points(path: Path) -> np.ndarray:
    """An (n, 3) point list from ``.npy`` or whitespace/comma separated text."""
    try:
        if path.suffix.lower() == ".npy":
            data = np.load(path, allow_pickle=False)
        else:
            text = path.read_text(encoding="utf-8").replace(",", " ")
            rows = [line.split() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
            data = np.array([[float(v) for v in row] for row in rows], dtype=float) if rows else np.zeros((0, 3))
    except (OSError, UnicodeDecodeError) as exc:
        raise ParselError(f"{path}: cannot read points: {exc}") from None
    except ValueError as exc:
        raise ParselError(f"{path}: not a list of numbers: {exc}") from None
    return _checked(data, str(path))


def mesh_points(path: Path, count: int, seed: int) -> np.ndarray:
    """Surface samples of a mesh file, or the vertices of a point-cloud file."""
    import trimesh

    try:
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many kinds for a bad file
        raise ParselError(f"{path}: cannot read as a mesh: {exc}") from None
    if isinstance(loaded, trimesh.Scene):
        geometries = [g for g in loaded.dump() if hasattr(g, "vertices")]
        meshes = [g for g in geometries if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        loaded = trimesh.util.concatenate(meshes) if meshes else (geometries[0] if geometries else None)
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        points, _ = trimesh.sample.sample_surface(loaded, count, seed=seed)
        return _checked(points, str(path))
    if loaded is not None and hasattr(loaded, "vertices"):
        return _checked(loaded.vertices, str(path))
    raise ParselError(f"{path}: holds no mesh or points")


def shape_points(shape, count: int, seed: int) -> np.ndarray:
    """Surface samples of a parsel shape at rest."""
    from parsel_core.program import Evaluation
    from parsel_fit.surface import SurfaceSampler

    sampler = SurfaceSampler.of(shape, count, seed)
    return sampler.points(shape, Evaluation(shape.rest_corners()))


def load_target(spec: str, count: int = DEFAULT_TARGET_SAMPLES, seed: int = 1) -> np.ndarray:
    """Target points for a file or shape name (see the module docstring)."""
    from parsel_core.loading import load_shape

    path = Path(spec)
    suffix = path.suffix.lower()
    if suffix in POINT_SUFFIXES or (suffix == ".txt" and path.is_file() and not _is_program(path)):
        return read_points(path)
    if suffix in MESH_SUFFIXES:
        if not path.is_file():
            raise ParselError(f"{path}: target file not found")
        return mesh_points(path, count, seed)
    return shape_points(load_shape(spec, detect=False), count, seed)


def _is_program(path: Path) -> bool:
    try:
        with path.open(encoding="utf-8") as handle:
            return handle.read(200).lstrip().startswith("Assembly")
    except (OSError, UnicodeDecodeError):
        return False
