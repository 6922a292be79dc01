"""parsel new-plugin: the package it writes works as written and passes the conformance kit."""

from __future__ import annotations

import importlib.util
import sys
import tomllib

import numpy as np
import pytest

from parsel_core.cli import main
from parsel_core.program import Program, evaluate
from parsel_core.testing import check_plugin


def load_module(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_new_plugin_writes_an_installable_package_that_passes_the_kit(tmp_path, capsys, parsel_register, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["new-plugin", "bend_y"]) == 0
    root = tmp_path / "parsel-bend-y"
    assert capsys.readouterr().out.split() == [f"parsel-bend-y/{p}" for p in (
        ".github/workflows/ci.yml", "README.md", "parsel_bend_y/__init__.py", "pyproject.toml", "tests/test_plugin.py")]
    project = tomllib.loads((root / "pyproject.toml").read_text())
    assert project["project"]["name"] == "parsel-bend-y"
    assert project["project"]["entry-points"]["parsel"] == {"bend_y": "parsel_bend_y"}
    workflow = (root / ".github" / "workflows" / "ci.yml").read_text()
    assert "repository: ${{ vars.PARSEL_REPOSITORY }}" in workflow and "python -m pytest tests" in workflow
    test_text = (root / "tests" / "test_plugin.py").read_text()
    assert 'PARSEL_PLUGINS = ["bend_y"]' in test_text and "test_parsel_conformance" in test_text

    module = load_module(root / "parsel_bend_y" / "__init__.py", "parsel_bend_y")
    parsel_register(module, name="bend_y")
    passed, failed, skipped = check_plugin("bend_y")
    assert failed == [] and skipped == [] and len(passed) == 8
    # the generated test's hand-computed case, run here
    tests = load_module(root / "tests" / "test_plugin.py", "parsel_bend_y_tests")
    tests.test_top_corners_move_in_by_amount_times_height()
    program = Program.from_text("param x in [0, 1]\nbend_y(top, origin=(0, 0.7, 0), axis=(0, 1, 0), amount=x)")
    from parsel_core.examples import tiny_table

    corners = evaluate(program, tiny_table(), {"x": 1.0}).parts["top"]
    assert np.all(np.isfinite(corners))
    sys.modules.pop("parsel_bend_y", None)
    sys.modules.pop("parsel_bend_y_tests", None)


def test_new_plugin_refuses_bad_names_and_existing_folders(tmp_path, capsys):
    assert main(["new-plugin", "Taper", "-o", str(tmp_path / "a")]) == 2
    assert "plugin name 'Taper': use a lower-case Python identifier" in capsys.readouterr().err
    (tmp_path / "b").mkdir()
    assert main(["new-plugin", "taper", "-o", str(tmp_path / "b")]) == 2
    assert "already exists" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b"]
    with pytest.raises(SystemExit):
        main(["new-plugin"])


def test_the_guide_shows_the_generated_operator_with_its_imports():
    from pathlib import Path

    from parsel_core.scaffold import plugin_files

    guide = (Path(__file__).resolve().parents[1] / "docs" / "plugins.md").read_text(encoding="utf-8")
    block = guide.split("and the operator, imports included:\n\n```python\n", 1)[1].split("```", 1)[0]
    assert block.startswith("from __future__ import annotations") and "from parsel_core import hookimpl" in block
    assert block in plugin_files("taper")["parsel_taper/__init__.py"]
