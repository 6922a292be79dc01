"""Test helpers: run the page's evaluator in Node, and find a headless Chromium for browser tests.

Both are optional on a machine: :func:`node_path` and :func:`browser_problem` say why
one is missing, so a test can skip with that reason instead of failing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from parsel_view.page import static_text
from parsel_view.scene import PageData

#: Where Debian's chromium package puts the browser; PARSEL_CHROMIUM overrides.
CHROMIUM = "/usr/bin/chromium"
#: Headless, offline and reproducible: no sandbox (CI runs as root), no network services,
#: a fresh profile per launch, WebGL on the SwiftShader software rasteriser.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader", "--enable-unsafe-swiftshader")
#: Headless Chromium paces frames to a virtual 60 Hz display; without that pacing a
#: measured frame rate is what the page and the rasteriser sustain, not the clock's.
UNPACED_FLAGS = ("--disable-gpu-vsync", "--disable-frame-rate-limit")

_NODE_RUNNER = r"""
"use strict";
const fs = require("fs");
const [evalPath, amountsPath, scenePath, valuesPath] = process.argv.slice(2);
const ParselEval = require(evalPath);
const program = require(amountsPath);
const scene = JSON.parse(fs.readFileSync(scenePath, "utf8"));
const model = new ParselEval.Model(scene, program.amounts, program.pointMaps);
const plain = (c) => Array.from(c, (v) => (Number.isNaN(v) ? null : v));
const results = JSON.parse(fs.readFileSync(valuesPath, "utf8")).map((values) => {
  const evaluation = model.evaluate(values);
  const parts = Object.create(null);
  for (const pid in evaluation.parts) parts[pid] = plain(evaluation.parts[pid]);
  const instances = Object.create(null);
  for (const g in evaluation.instances) instances[g] = evaluation.instances[g].map(plain);
  const vertices = Object.create(null), flipped = [];
  for (const item of model.drawList(evaluation)) {
    vertices[item.name] = plain(model.deformInto(item.mesh, item.corners));
    if (model.flipped(item.mesh, item.corners)) flipped.push(item.name);
  }
  const broken = model.brokenRelations(evaluation).map((b) => b.id).sort();
  return { parts, instances, removed: Object.keys(evaluation.removed).sort(), vertices, amounts: evaluation.amounts,
           flipped: flipped.sort(), broken };
});
process.stdout.write(JSON.stringify(results));
"""


def node_path() -> str | None:
    """The ``node`` executable, if installed."""
    return shutil.which("node")


def node_evaluate(page: PageData, values: Sequence[Mapping[str, float]]) -> list[dict[str, Any]]:
    """Evaluate the page's program with ``parsel_eval.js`` in Node at each set of ``values``.

    Returns per set: ``parts`` (id -> 24 corner numbers, ``None`` for NaN), ``instances``,
    ``removed``, ``vertices`` (drawn name -> flat float32 positions), ``amounts``,
    ``flipped`` (drawn names whose mesh an edit mirrors or folds, ``Model.flipped``) and
    ``broken`` (ids of the relations the values break, ``Model.brokenRelations``)."""
    node = node_path()
    if node is None:
        raise RuntimeError("node is not installed")
    with tempfile.TemporaryDirectory(prefix="parsel-view-node-") as tmp:
        folder = Path(tmp)
        files = {"parsel_eval.js": static_text("parsel_eval.js"), "amounts.js": page.amounts_js,
                 "scene.json": page.scene_json(), "values.json": json.dumps(list(values)),
                 "run.js": _NODE_RUNNER}
        for name, text in files.items():
            (folder / name).write_text(text, encoding="utf-8")
        done = subprocess.run([node, str(folder / "run.js"), str(folder / "parsel_eval.js"), str(folder / "amounts.js"),
                               str(folder / "scene.json"), str(folder / "values.json")],
                              capture_output=True, text=True, timeout=120)
        if done.returncode != 0:
            raise RuntimeError(f"node failed: {done.stderr.strip()}")
        return json.loads(done.stdout)


def chromium_path() -> str:
    return os.environ.get("PARSEL_CHROMIUM", CHROMIUM)


def browser_problem() -> str | None:
    """Why the browser tests cannot run here, or ``None`` when they can."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright for Python is not installed (pip install playwright; no browser download is needed)"
    if not Path(chromium_path()).exists():
        return f"no Chromium at {chromium_path()} (apt-get install -y chromium, or set PARSEL_CHROMIUM)"
    return None


@contextmanager
def chromium_page(width: int = 800, height: int = 600, *, paced: bool = False) -> Iterator[Any]:
    """A Playwright page in a fresh headless Chromium profile, closed afterwards.

    Frames are drawn as fast as the page asks for them unless ``paced`` (60 Hz, as a
    display would)."""
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="parsel-view-chromium-") as profile, sync_playwright() as p:
        # Playwright takes the profile directory itself (it refuses --user-data-dir in args).
        flags = [*CHROMIUM_FLAGS, *(() if paced else UNPACED_FLAGS)]
        context = p.chromium.launch_persistent_context(
            profile, executable_path=chromium_path(), headless=True, args=flags,
            viewport={"width": width, "height": height})
        try:
            page = context.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.parsel_errors = errors
            yield page
        finally:
            context.close()
