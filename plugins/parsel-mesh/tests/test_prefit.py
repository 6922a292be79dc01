"""Pre-fitted parts: the bundled assets load without reading a mesh, exactly as a full read would."""

from __future__ import annotations

import json
import pickle
import shutil

import numpy as np
import pytest
import trimesh

from parsel_core.errors import ParselError
from parsel_mesh.examples import NAMES, example_path
from parsel_mesh.loaders import READERS, load_mesh_shape
from parsel_mesh.prefit import LazyMesh, prefit_data, prefit_path, write_prefit


@pytest.fixture
def chair_copy(tmp_path):
    target = tmp_path / "chair.glb"
    shutil.copy(example_path("chair"), target)
    write_prefit(target)
    return target


@pytest.mark.parametrize("name", NAMES)
def test_bundled_sidecar_is_current(name):
    """A stale sidecar is ignored, not wrong; this keeps the bundled ones useful (regenerate:
    python -m parsel_mesh.examples.build)."""
    path = example_path(name)
    assert json.loads(prefit_path(path).read_text()) == prefit_data(path)


@pytest.mark.parametrize("name", NAMES)
def test_prefit_shape_equals_the_fitted_one(name, tmp_path):
    path = tmp_path / f"{name}.glb"
    shutil.copy(example_path(name), path)
    full = load_mesh_shape(path)  # no sidecar yet: every mesh read and fitted
    write_prefit(path)
    quick = load_mesh_shape(path)
    assert list(quick.parts) == list(full.parts)
    assert (quick.name, quick.source, quick.metadata) == (full.name, full.source, full.metadata)
    for pid, part in full.parts.items():
        other = quick.parts[pid]
        assert (other.label, other.name) == (part.label, part.name)
        assert np.array_equal(other.hexahedron.corners, part.hexahedron.corners)  # bit for bit
        assert isinstance(other.mesh, LazyMesh)
        np.testing.assert_array_equal(other.mesh.vertices, part.mesh.vertices)
        np.testing.assert_array_equal(other.mesh.faces, part.mesh.faces)
        assert isinstance(other.mesh.load(), trimesh.Trimesh)


def test_lazy_meshes_read_the_file_once_and_only_when_used(chair_copy, monkeypatch):
    reads = []
    real = READERS[".glb"]
    monkeypatch.setitem(READERS, ".glb", lambda path: reads.append(path) or real(path))
    shape = load_mesh_shape(chair_copy)
    assert reads == []
    for part in shape.parts.values():
        assert len(part.mesh.vertices) > 8
    assert reads == [chair_copy]


def test_labels_sidecar_still_applies(chair_copy):
    chair_copy.with_name("chair.labels.json").write_text(json.dumps({"seat": "cushion"}))
    assert load_mesh_shape(chair_copy).parts["seat"].label == "cushion"


def test_a_changed_asset_is_fitted_afresh(chair_copy):
    before = load_mesh_shape(chair_copy)
    scene = trimesh.load(chair_copy, force="scene", process=False)
    scene.apply_translation((1.0, 0.0, 0.0))
    chair_copy.write_bytes(scene.export(file_type="glb"))
    after = load_mesh_shape(chair_copy)
    assert not isinstance(after.parts["seat"].mesh, LazyMesh)
    np.testing.assert_allclose(after.parts["seat"].hexahedron.corners,
                               before.parts["seat"].hexahedron.corners + [1.0, 0.0, 0.0], atol=1e-6)


def test_an_asset_changed_after_loading_is_an_error_on_use(chair_copy):
    shape = load_mesh_shape(chair_copy)
    chair_copy.write_bytes(chair_copy.read_bytes() + b"\0")
    with pytest.raises(ParselError, match="changed or removed since the shape was loaded"):
        shape.parts["seat"].mesh.vertices  # noqa: B018


def test_a_malformed_sidecar_is_a_one_line_error(chair_copy):
    prefit_path(chair_copy).write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ParselError, match=r"chair\.glb\.parts\.json: not a pre-fitted parts file"):
        load_mesh_shape(chair_copy)
    data = prefit_data(chair_copy)
    data["names"] = data["names"][1:]
    prefit_path(chair_copy).write_text(json.dumps(data))
    with pytest.raises(ParselError, match="must list the same parts"):
        load_mesh_shape(chair_copy)


def test_lazy_meshes_pickle_without_their_mesh(chair_copy):
    mesh = load_mesh_shape(chair_copy).parts["seat"].mesh
    copy = pickle.loads(pickle.dumps(mesh))
    assert (copy.path, copy.part, copy.digest) == (mesh.path, mesh.part, mesh.digest)
    np.testing.assert_array_equal(copy.vertices, mesh.vertices)
    with pytest.raises(AttributeError):
        copy.__no_such_dunder__  # noqa: B018
