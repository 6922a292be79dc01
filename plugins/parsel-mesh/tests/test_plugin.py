"""The plugin registers through its entry point, stays cheap to import and shows in `parsel plugins`."""

from __future__ import annotations

import json

import pytest

import parsel_mesh
from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.loading import load_shape
from parsel_core.plugins import deformers, exporters, get_plugin_manager, shape_loaders
from parsel_mesh.examples import NAMES

LOADERS = {"mesh-gltf": (".glb", ".gltf"), "mesh-obj": (".obj",), "mesh-ply": (".ply",), "mesh-off": (".off",),
           "mesh-stl": (".stl",), "partnet": ()}


def test_registered_through_the_entry_point():
    pm = get_plugin_manager()
    assert pm.get_plugin("mesh") is parsel_mesh
    record = pm.records["mesh"]
    assert record.error is None and record.version == parsel_mesh.__version__


def test_contributions():
    loaders = {loader.name: loader.extensions for loader in shape_loaders()}
    for name, extensions in LOADERS.items():
        assert loaders[name] == extensions
    assert "cage" in deformers()
    assert {"mesh-glb", "mesh-obj", "mesh-ply"} <= set(exporters())
    assert set(parsel_mesh.parsel_example_shapes()) == set(NAMES)


def test_importing_the_plugin_does_not_import_trimesh(parsel_fresh_python):
    code = "import sys, parsel_mesh; parsel_mesh.parsel_shape_loaders(); parsel_mesh.parsel_example_shapes(); " \
           "parsel_mesh.parsel_exporters(); parsel_mesh.parsel_deformers(); print('trimesh' in sys.modules)"
    assert parsel_fresh_python(code).strip() == "False"


def test_parsel_plugins_lists_it(capsys):
    assert main(["plugins", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    mesh = next(p for p in data["plugins"] if p["name"] == "mesh")
    assert mesh["provides"]["shape_loaders"] == list(LOADERS)
    assert mesh["provides"]["exporters"] == ["mesh-glb", "mesh-obj", "mesh-ply"]
    assert mesh["provides"]["deformers"] == ["cage"]
    assert sorted(mesh["provides"]["example_shapes"]) == sorted(NAMES)


def test_core_reports_unknown_suffixes(tmp_path):
    path = tmp_path / "x.xyz"
    path.write_text("?")
    with pytest.raises(ParselError, match="no installed loader"):
        load_shape(str(path))
