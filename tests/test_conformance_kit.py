"""The conformance kit (parsel_core.testing): every bundled plugin passes it, and it catches broken plugins."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.interfaces import Exporter, ShapeLoader
from parsel_core.ops import EditOp, Vector
from parsel_core.testing import check_plugin, plugin_checks
from parsel_core.testing.test_conformance import test_parsel_conformance  # noqa: F401 - the kit's test, run here

ROOT = Path(__file__).resolve().parents[1]
#: The entry points of the packages under plugins/: each runs the kit here.
PARSEL_PLUGINS = sorted(
    line.split("=")[0].strip()
    for pyproject in ROOT.glob("plugins/*/pyproject.toml")
    for block in [pyproject.read_text(encoding="utf-8").split("[project.entry-points.parsel]")[1:]]
    for line in (block[0].strip().split("\n\n")[0].splitlines() if block else [])
    if "=" in line
)


def test_every_bundled_plugin_is_listed():
    assert len(PARSEL_PLUGINS) == len(list(ROOT.glob("plugins/*/pyproject.toml")))
    assert {"aep", "mesh", "sympy", "symengine", "twist", "view"} <= set(PARSEL_PLUGINS)


@dataclass(frozen=True)
class Taper(EditOp):
    """Shrinks points towards the axis in proportion to their height along it: a plugin-style operator that is right."""

    name: ClassVar[str] = "taper_kit"
    unit_fields: ClassVar[tuple[str, ...]] = ("axis",)
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    axis: Vector = (0.0, 1.0, 0.0)

    def transform(self, points, amount, math):
        o, n = np.asarray(self.origin), np.asarray(self.axis)
        centred = points - o
        height = centred[..., 0:1] * n[0] + centred[..., 1:2] * n[1] + centred[..., 2:3] * n[2]
        along = height * n
        return o + along + (centred - along) * (1 - height * amount)


@dataclass(frozen=True)
class SplitTaper(Taper):
    """Broken on purpose: the symbolic path (object arrays) tapers twice as hard as the numeric one."""

    name: ClassVar[str] = "split_taper"

    def transform(self, points, amount, math):
        if np.asarray(points).dtype == object:
            amount = amount * 2
        return super().transform(points, amount, math)


@dataclass(frozen=True)
class BatchTaper(Taper):
    """Broken on purpose: a batch of slider values tapers twice as hard as one value at a time."""

    name: ClassVar[str] = "batch_taper"

    def transform(self, points, amount, math):
        if np.ndim(amount) > 0:
            amount = amount * 2
        return super().transform(points, amount, math)


@dataclass(frozen=True)
class Skew(EditOp):
    """Broken on purpose: a direction field, but mirroring is left to the base class though the
    map is not equivariant (it moves points along a fixed world axis)."""

    name: ClassVar[str] = "skew_kit"
    unit_fields: ClassVar[tuple[str, ...]] = ("dir",)
    dir: Vector = (0.0, 1.0, 0.0)

    def transform(self, points, amount, math):
        height = points[..., 0:1] * self.dir[0] + points[..., 1:2] * self.dir[1] + points[..., 2:3] * self.dir[2]
        return points + height * np.array([1.0, 0.0, 0.0]) * amount


class Operators:
    def __init__(self, *ops):
        self.ops = list(ops)

    @hookimpl
    def parsel_edit_operators(self):
        return self.ops


def failures(name: str) -> list[str]:
    passed, failed, skipped = check_plugin(name)
    assert passed, f"no check of {name} passed"
    return failed


def test_a_correct_operator_passes(parsel_register):
    parsel_register(Operators(Taper), name="taper_kit_plugin")
    assert failures("taper_kit_plugin") == []
    ids = [check.id for check in plugin_checks("taper_kit_plugin")]
    assert "taper_kit_plugin: operator 'taper_kit': symbolic path = numeric path" in ids
    assert "taper_kit_plugin: operator 'taper_kit': JavaScript form = numeric path" in ids


def test_numeric_and_symbolic_paths_that_disagree_fail_naming_the_operator(parsel_register):
    parsel_register(Operators(SplitTaper), name="broken_taper_plugin")
    failed = failures("broken_taper_plugin")
    assert all(m.startswith("broken_taper_plugin: operator 'split_taper'") and "\n" not in m for m in failed), failed
    (symbolic,) = [m for m in failed if "symbolic path" in m]
    assert symbolic.startswith("broken_taper_plugin: operator 'split_taper' (whole part): the symbolic path (")
    assert "and the numeric path disagree by" in symbolic
    # the page's point map is traced through the symbolic path, so it disagrees too
    assert any("the JavaScript point map differs from transform" in m for m in failed)


def test_batched_and_per_sample_evaluations_that_disagree_fail_naming_the_value(parsel_register):
    parsel_register(Operators(BatchTaper), name="batch_taper_plugin")
    failed = failures("batch_taper_plugin")
    batched = [m for m in failed if "per-sample evaluation" in m]
    assert batched and batched[0].startswith("batch_taper_plugin: operator 'batch_taper' (whole part): "
                                             "the per-sample evaluation and the numeric path disagree by ")
    assert "at x = 0.35 (corner" in batched[0] or "at x = 0.8 (corner" in batched[0], batched[0]


def test_a_map_that_does_not_mirror_fails(parsel_register):
    parsel_register(Operators(Skew), name="skew_plugin")
    failed = failures("skew_plugin")
    assert len(failed) == 1 and failed[0].startswith("skew_plugin: operator 'skew_kit': the mirrored op does not map")


class LeakyLoader(ShapeLoader):
    name = "leaky"
    extensions = (".leaky",)

    def load(self, path):
        return int(Path(path).read_bytes())  # ValueError, not a ParselError


class DirectExporter(Exporter):
    name = "direct"
    extensions = (".direct",)

    def export(self, shape, evaluation, path):
        if not Path(path).parent.is_dir():
            raise ParselError(f"{path}: no such folder")
        with open(path, "w", encoding="utf-8") as handle:  # straight into the output: not atomic
            handle.write("edited\n")


class Interfaces:
    @hookimpl
    def parsel_shape_loaders(self):
        return [LeakyLoader()]

    @hookimpl
    def parsel_exporters(self):
        return [DirectExporter()]


def test_loaders_and_exporters_that_break_their_contracts_fail(parsel_register):
    parsel_register(Interfaces(), name="leaky_plugin")
    failed = failures("leaky_plugin")
    assert len(failed) == 2, failed
    assert any(m.startswith("leaky_plugin: shape loader 'leaky': a garbage .leaky file raises ValueError")
               for m in failed)
    assert any(m.startswith("leaky_plugin: exporter 'direct': writes straight into edited.direct") for m in failed)


def test_a_plugin_that_is_not_installed_fails_listing_the_installed():
    (check,) = plugin_checks("not_a_plugin")
    with pytest.raises(AssertionError, match=r"not_a_plugin: no such plugin is installed \(installed: .*twist"):
        check.run()
