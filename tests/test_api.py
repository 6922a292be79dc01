"""The Python API (parsel_core.api): the documented example, provider objects, and the CLI as a thin caller."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from parsel_core import api, edit
from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.examples import tiny_table
from parsel_core.interfaces import Completion, LLMProvider
from parsel_core.language import InferenceError
from parsel_core.plugins import llm_providers

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "examples" / "edit_from_python.py"
TABLE_SEED = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"


def test_the_documented_example_is_the_one_in_architecture_md():
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert "```python\n" + EXAMPLE.read_text(encoding="utf-8") + "```" in text


@pytest.mark.skipif("offline" not in llm_providers(), reason="needs the offline provider (parsel-offline)")
def test_the_documented_example_runs(tmp_path):
    done = subprocess.run([sys.executable, str(EXAMPLE)], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    # offline: the seat widens along x and nothing breaks; the caller's provider: the seat deepens along z
    assert "scale_1d(seat, origin=(0.0, 0.4299999922513962, 0.0), dir=(1.0, 0.0, 0.0), amount=x)" in lines
    assert lines.count("relations: {'kept': 28, 'broken_on_purpose': 0, 'broken': 0}") == 2
    assert "prompts sent: 40 | stages: check_s, infer_s, load_s, solve_s" in lines
    assert "scale_1d seat (0.0, 0.0, 1.0)" in lines
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # the API writes nothing


class Counting(LLMProvider):
    """The caller's own provider: answers through the offline rules and remembers every task."""

    name = "counting"

    def __init__(self) -> None:
        self.tasks: list[str] = []
        self.offline = llm_providers()["offline"]

    def complete(self, prompt, *, task, samples=1, **options):
        self.tasks.append(task)
        return self.offline.complete(prompt, task=task, samples=samples, **options)


@pytest.mark.skipif("offline" not in llm_providers(), reason="needs the offline provider (parsel-offline)")
def test_a_provider_object_answers_the_prompts_and_is_gone_after_the_call():
    provider = Counting()
    result = edit(tiny_table(), "make the table wider", provider=provider, samples=2)
    offline = edit(tiny_table(), "make the table wider", samples=2)
    assert provider.tasks[0] == "seed_edit" and "type_hints" in provider.tasks
    assert result.accounting["calls"] == len(provider.tasks) and provider.tasks.count("seed_edit") == 2  # 2 samples
    assert result.program.ops == offline.program.ops
    assert result.program.metadata["provider"] == "counting" and result.record[0]["provider"] == "counting"
    assert "counting" not in llm_providers()
    assert set(result.files()) == {"program.json", "report.json", "record.jsonl"}


def test_expert_mode_gives_what_the_cli_writes(tmp_path, capsys):
    result = api.edit("tiny_table", seed=TABLE_SEED)
    assert result.inference is None and result.record == [] and set(result.files()) == {"program.json", "report.json"}
    assert result.report.counts()["broken"] == 0 and result.program.ops[0].operand == "top"
    assert set(result.timings) == {"load_s", "solve_s", "check_s"}
    assert main(["edit", "tiny_table", "--seed", TABLE_SEED, "-o", str(tmp_path / "out")]) == 0
    written = json.loads((tmp_path / "out" / "program.json").read_text())
    assert written == json.loads(result.program.to_json())


def test_a_failed_inference_keeps_its_record():
    class Mute(LLMProvider):
        name = "mute"

        def complete(self, prompt, *, task, samples=1, **options):
            return [Completion("I would rather not.") for _ in range(samples)]

    with pytest.raises(InferenceError) as caught:
        edit("tiny_table", "make the table wider", provider=Mute(), samples=1)
    assert caught.value.record and caught.value.record[0]["provider"] == "mute"
    with pytest.raises(ParselError, match="needs a request in words or a seed op"):
        edit("tiny_table")
    with pytest.raises(ParselError, match="neither a provider name nor an object with complete"):
        edit("tiny_table", "make it wider", provider=42)


def test_check_apply_and_export(tmp_path):
    program = api.edit("tiny_table", seed=TABLE_SEED).program
    report = api.check("tiny_table", program, samples=5)
    assert report.samples == 5 and report.counts()["broken"] == 0
    evaluation = api.apply("tiny_table", program, {"x": 1.0})
    rest = tiny_table().parts["top"].hexahedron.corners
    np.testing.assert_allclose(np.ptp(evaluation.parts["top"][:, 0]), 2 * np.ptp(rest[:, 0]))  # twice as wide at x = 1
    paths = api.export("tiny_table", program, tmp_path / "t.obj", sweep=3)
    assert [p.name for p in paths] == ["t_000.obj", "t_001.obj", "t_002.obj"] and all(p.stat().st_size for p in paths)
    with pytest.raises(ParselError, match="--sweep needs at least 2 steps"):
        api.export("tiny_table", program, tmp_path / "u.obj", sweep=1)
    assert not (tmp_path / "u_000.obj").exists()


PIPELINE_NAMES = {"SolveRequest", "infer", "check_program", "check_each_parameter", "solvers", "get_named",
                  "proxydural_requests", "variation_requests", "evaluate", "exporter_for", "seed_from_text"}


def test_the_cli_holds_no_pipeline_logic():
    """cmd_edit, cmd_proxydural, cmd_variations, cmd_check and cmd_apply only call parsel_core.api."""
    tree = ast.parse((ROOT / "parsel_core" / "cli.py").read_text(encoding="utf-8"))
    commands = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    for name in ("cmd_edit", "cmd_proxydural", "cmd_variations", "cmd_check", "cmd_apply"):
        used = {n.id for n in ast.walk(commands[name]) if isinstance(n, ast.Name)}
        used |= {a.name for n in ast.walk(commands[name]) if isinstance(n, ast.ImportFrom) for a in n.names}
        assert not used & PIPELINE_NAMES, f"{name} uses {sorted(used & PIPELINE_NAMES)}"
        calls = {n.func.attr for n in ast.walk(commands[name])
                 if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                 and isinstance(n.func.value, ast.Name) and n.func.value.id == "api"}
        assert calls, f"{name} does not call parsel_core.api"


def test_batch_runs_its_cases_through_the_api():
    runner = ROOT / "plugins" / "parsel-batch" / "parsel_batch" / "runner.py"
    if not runner.exists():
        pytest.skip("parsel-batch is not in this tree")
    tree = ast.parse(runner.read_text(encoding="utf-8"))
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    names |= {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
    assert not names & {"SolveRequest", "infer", "solvers", "get_named"}, sorted(names & PIPELINE_NAMES)
    assert any(isinstance(n, ast.Attribute) and n.attr == "edit" and getattr(n.value, "id", "") == "api"
               for n in ast.walk(tree))
