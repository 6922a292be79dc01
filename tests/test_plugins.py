"""The plugin system: every hook works, is tested and documented; broken plugins are isolated."""

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from parsel_core import Hexahedron, Part, ShapeGraph, hookimpl, plugins
from parsel_core import hookspecs as hookspecs_module
from parsel_core.cli import main
from parsel_core.interfaces import (
    Completion,
    Deformer,
    Exporter,
    LLMProvider,
    RelationDetector,
    ShapeLoader,
    Solver,
    SolveRequest,
)
from parsel_core.loading import load_shape
from parsel_core.program import Program, evaluate

ROOT = Path(__file__).resolve().parents[1]
HOOKS = sorted(name for name in dir(hookspecs_module) if name.startswith("parsel_"))


def test_every_hook_has_a_test_and_a_docs_entry():
    docs = (ROOT / "docs" / "plugins.md").read_text()
    test_text = "\n".join(p.read_text() for p in (ROOT / "tests").glob("test_*.py") if p.name != Path(__file__).name)
    test_text += Path(__file__).read_text().split("# -- hook tests --")[-1]
    assert len(HOOKS) >= 10
    for hook in HOOKS:
        assert f"`{hook}`" in docs, f"docs/plugins.md lacks an entry for {hook}"
        assert f"def {hook}(" in test_text, f"no test implements {hook}"
        assert getattr(hookspecs_module, hook).__doc__, f"{hook} has no docstring"


def test_hookspecs_are_all_in_one_file():
    tree = ast.parse((ROOT / "parsel_core" / "hookspecs.py").read_text())
    specs = [node.name for node in tree.body if isinstance(node, ast.FunctionDef)]
    assert sorted(specs) == HOOKS
    for path in (ROOT / "parsel_core").rglob("*.py"):
        if path.name != "hookspecs.py":
            assert "HookspecMarker" not in path.read_text(), path


# -- hook tests --

def test_hook_edit_operators(parsel_register):
    from dataclasses import dataclass
    from typing import ClassVar

    from parsel_core.ops import EditOp

    @dataclass(frozen=True)
    class Lift(EditOp):
        name: ClassVar[str] = "lift"

        def transform(self, points, amount, math):
            return points + np.array([0.0, 1.0, 0.0]) * amount

    class Plugin:
        @hookimpl
        def parsel_edit_operators(self):
            return [Lift]

    parsel_register(Plugin(), name="lift-plugin")
    shape = ShapeGraph([Part("a", "a", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1)))])
    program = Program.from_text("lift(a, amount=2 * x)")
    assert np.allclose(evaluate(program, shape, {"x": 0.5}).parts["a"][:, 1], [0, 0, 1, 1, 0, 0, 1, 1] + np.ones(8))


def test_hook_cas_backends(parsel_register):
    from parsel_sympy.backend import SympyBackend

    class Renamed(SympyBackend):
        name = "sympy-renamed"

    class Plugin:
        @hookimpl
        def parsel_cas_backends(self):
            return [Renamed]

    parsel_register(Plugin())
    assert "sympy-renamed" in plugins.cas_backend_names()
    assert plugins.get_cas_backend("sympy-renamed").name == "sympy-renamed"


def test_hook_shape_loaders(parsel_register, tmp_path):
    class BoxListLoader(ShapeLoader):
        name = "box-list"
        extensions = (".boxes",)

        def load(self, path):
            parts = []
            for i, line in enumerate(path.read_text().splitlines()):
                lo_hi = [float(v) for v in line.split()]
                parts.append(Part(f"p{i}", "box", Hexahedron.from_bounds(lo_hi[:3], lo_hi[3:])))
            return ShapeGraph(parts, name=path.stem)

    class Plugin:
        @hookimpl
        def parsel_shape_loaders(self):
            return [BoxListLoader()]

    parsel_register(Plugin())
    path = tmp_path / "two.boxes"
    path.write_text("0 0 0 1 1 1\n2 0 0 3 1 1\n")
    shape = load_shape(str(path))
    assert list(shape.parts) == ["p0", "p1"]


def test_hook_relation_detectors(parsel_register, parsel_shape):
    from parsel_core.relations import GroundContact

    class FloorDetector(RelationDetector):
        name = "floor"

        def detect(self, shape, tolerance):
            out = []
            for pid, part in shape.parts.items():
                corners = part.hexahedron.corners
                on_floor = np.abs(corners[:, 1]) < tolerance
                if on_floor.sum() == 4:
                    weights = np.eye(8)[on_floor]
                    out.append(GroundContact(f"floor_{pid}", (pid,), tuple(map(tuple, weights))))
            return out

    class Plugin:
        @hookimpl
        def parsel_relation_detectors(self):
            return [FloorDetector()]

    parsel_register(Plugin())
    detector = plugins.relation_detectors()["floor"]
    found = detector.detect(parsel_shape, 1e-6)
    assert sorted(r.members[0] for r in found) == ["leg_bl", "leg_br", "leg_fl", "leg_fr"]


def test_hook_llm_providers(parsel_register):
    class Echo(LLMProvider):
        name = "echo"

        def complete(self, prompt, *, task, samples=1, **options):
            return [Completion(f"{task}:{prompt}") for _ in range(samples)]

    class Plugin:
        @hookimpl
        def parsel_llm_providers(self):
            return [Echo]

    parsel_register(Plugin())
    provider = plugins.get_named("LLM provider", plugins.llm_providers(), "echo")
    assert [c.text for c in provider.complete("hi", task="seed_edit", samples=2)] == ["seed_edit:hi"] * 2


def test_hook_deformers(parsel_register, parsel_shape):
    class CornerDeformer(Deformer):
        """Moves 'meshes' that are just the corners (the identity cage)."""

        name = "corners"

        def deform(self, shape, evaluation):
            return {pid: evaluation.parts[pid] for pid in shape.parts}

    class Plugin:
        @hookimpl
        def parsel_deformers(self):
            return [CornerDeformer()]

    parsel_register(Plugin())
    program = Program.from_text("translate(top, dir=(0, 1, 0), amount=x)")
    meshes = plugins.deformers()["corners"].deform(parsel_shape, evaluate(program, parsel_shape, {"x": 0.5}))
    assert np.allclose(meshes["top"], parsel_shape.part("top").hexahedron.corners + (0, 0.5, 0))


def test_hook_exporters(parsel_register, parsel_shape, tmp_path):
    class CountExporter(Exporter):
        name = "count"
        extensions = (".count",)

        def export(self, shape, evaluation, path):
            path.write_text(str(len(evaluation.parts)))

    class Plugin:
        @hookimpl
        def parsel_exporters(self):
            return [CountExporter()]

    parsel_register(Plugin())
    exporters = plugins.exporters()
    assert {"count", "hexahedra-obj", "hexahedra-json"} <= set(exporters)
    evaluation = evaluate(Program.from_text("translate(top, dir=(0, 1, 0), amount=x)"), parsel_shape, {"x": 0.5})
    exporters["count"].export(parsel_shape, evaluation, tmp_path / "a.count")
    assert (tmp_path / "a.count").read_text() == "12"
    exporters["hexahedra-obj"].export(parsel_shape, evaluation, tmp_path / "a.obj")
    obj = (tmp_path / "a.obj").read_text().splitlines()
    assert sum(line.startswith("o ") for line in obj) == 11 and sum(line.startswith("f ") for line in obj) == 66
    exporters["hexahedra-json"].export(parsel_shape, evaluation, tmp_path / "a.hex.json")
    data = json.loads((tmp_path / "a.hex.json").read_text())
    assert np.allclose(data["parts"]["top"], evaluation.parts["top"])


def test_hook_solvers(parsel_register, parsel_shape):
    class SeedOnly(Solver):
        name = "seed-only"

        def solve(self, request):
            return request.seed

    class Plugin:
        @hookimpl
        def parsel_solvers(self):
            return [SeedOnly]

    parsel_register(Plugin())
    seed = Program.from_text("translate(top, dir=(0, 1, 0), amount=x)")
    assert plugins.solvers()["seed-only"].solve(SolveRequest(parsel_shape, seed)) == seed


def test_hook_example_shapes(parsel_register):
    def one_box():
        return ShapeGraph([Part("only", "box", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1)))], name="one_box")

    class Plugin:
        @hookimpl
        def parsel_example_shapes(self):
            return {"one_box": one_box}

    parsel_register(Plugin())
    assert load_shape("one_box").name == "one_box"
    assert load_shape("tiny_table").name == "tiny_table"


def test_hook_register_commands(parsel_register, capsys):
    class Plugin:
        @hookimpl
        def parsel_register_commands(self, subparsers):
            parser = subparsers.add_parser("hello", help="say hello")
            parser.add_argument("--name", default="world")
            parser.set_defaults(func=lambda args: print(f"hello {args.name}") or 0)

    parsel_register(Plugin())
    assert main(["hello", "--name", "chair"]) == 0
    assert capsys.readouterr().out == "hello chair\n"


# -- installed plugins, environment controls and isolation --

def run_parsel(*args, env=None):
    environment = {k: v for k, v in os.environ.items() if k not in ("PARSEL_STRICT_PLUGINS", "PARSEL_PLUGINS")}
    environment.update(env or {})
    return subprocess.run([sys.executable, "-m", "parsel_core.cli", *args], capture_output=True, text=True,
                          env=environment, timeout=120)


def test_plugins_json_lists_backends_and_the_example_operator():
    result = run_parsel("plugins", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert {"sympy", "symengine"} <= set(data["provides"]["cas_backends"])
    assert "twist" in data["provides"]["edit_operators"]
    twist = next(p for p in data["plugins"] if p["name"] == "twist")
    assert twist["version"] == "0.1.0" and twist["hooks"] == ["parsel_edit_operators"]
    assert twist["provides"] == {"edit_operators": ["twist"]}


def test_parsel_plugins_env_limits_what_loads():
    result = run_parsel("plugins", "--json", env={"PARSEL_PLUGINS": "sympy"})
    data = json.loads(result.stdout)
    assert data["provides"]["cas_backends"] == ["sympy"]
    assert "twist" not in data["provides"]["edit_operators"]
    assert "translate" in data["provides"]["edit_operators"]  # built-ins always load


def test_parsel_plugins_naming_a_plugin_not_installed_is_an_error_listing_the_installed():
    result = run_parsel("plugins", env={"PARSEL_PLUGINS": "sympy,twsit"})
    assert result.returncode == 2 and result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("parsel: error: PARSEL_PLUGINS names 'twsit', which is not installed (installed: ")
    assert "sympy" in lines[0] and "twist" in lines[0] and "aep" in lines[0]


@pytest.fixture
def broken_plugin_path(tmp_path):
    source = ROOT / "tests" / "fixtures" / "broken_plugin"
    target = tmp_path / "site"
    shutil.copytree(source, target)
    return {"PYTHONPATH": os.pathsep.join([str(target), os.environ.get("PYTHONPATH", "")])}


def test_broken_plugin_does_not_stop_the_command_line(broken_plugin_path):
    result = run_parsel("--help", env=broken_plugin_path)
    assert result.returncode == 0
    assert "plugins" in result.stdout
    assert result.stderr == ""  # --help imports no plugin, so a broken one cannot get in the way
    result = run_parsel("plugins", env=broken_plugin_path)
    assert result.returncode == 0
    assert "parsel plugin 'broken'" in result.stderr and "broken on purpose" in result.stderr
    listing = run_parsel("plugins", "--json", env=broken_plugin_path)
    broken = next(p for p in json.loads(listing.stdout)["plugins"] if p["name"] == "broken")
    assert "broken on purpose" in broken["error"]


def test_broken_plugin_is_an_error_in_strict_mode(broken_plugin_path):
    result = run_parsel("plugins", env={**broken_plugin_path, "PARSEL_STRICT_PLUGINS": "1"})
    assert result.returncode != 0
    assert "parsel plugin 'broken'" in result.stderr


def test_detectors_run_on_shapes_without_relations(parsel_register, tmp_path):
    from parsel_core.detection import detect_relations
    from parsel_core.examples import ground as ground_contact

    class FloorOnly(RelationDetector):
        name = "floor-only"

        def detect(self, shape, tolerance):
            return [ground_contact(f"g_{pid}", part) for pid, part in shape.parts.items()
                    if part.hexahedron.corners[:, 1].min() < tolerance]

    class Plugin:
        @hookimpl
        def parsel_relation_detectors(self):
            return [FloorOnly()]

    parsel_register(Plugin())
    bare = ShapeGraph([Part("a", "a", Hexahedron.from_bounds((0, 0, 0), (1, 1, 1))),
                       Part("b", "b", Hexahedron.from_bounds((0, 1, 0), (1, 2, 1)))], name="bare")
    detected = detect_relations(bare, families=["floor-only"])
    assert list(detected.relations) == ["g_a"]
    path = tmp_path / "bare.shape.json"
    path.write_text(json.dumps(bare.to_dict()))
    assert "g_a" in load_shape(str(path)).relations
    assert not load_shape(str(path), detect=False).relations


def test_hook_prompt_templates(parsel_register, tmp_path):
    from pathlib import Path

    template = tmp_path / "seed.txt"
    template.write_text("Edit {shape} as asked: {request}")

    class Plugin:
        @hookimpl
        def parsel_prompt_templates(self):
            return {"seed_edit": Path(template), "type_hints": "hints for {shape}"}

    parsel_register(Plugin())
    templates = plugins.prompt_templates()
    assert templates["seed_edit"] == "Edit {shape} as asked: {request}"
    assert templates["type_hints"] == "hints for {shape}"


def test_fresh_python_runs_code_where_nothing_is_imported_yet(parsel_fresh_python):
    assert "pytest" in sys.modules
    assert parsel_fresh_python("import sys\nprint('pytest' in sys.modules, 6 * 7)").split() == ["False", "42"]
    with pytest.raises(pytest.fail.Exception, match="(?s)exited with 1: .*ZeroDivisionError"):
        parsel_fresh_python("print('partial')\n1 / 0")
