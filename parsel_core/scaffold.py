"""``parsel new-plugin NAME``: a plugin package to start from, with its tests and CI.

The files come from ``parsel_core/plugin_template/`` (each ``*.tmpl`` is a
:class:`string.Template`: ``$name`` the operator and entry-point name, ``$module`` the
Python package, ``$cls`` the operator class, ``$dist`` the distribution suffix). The
package it writes installs and passes the conformance kit as it is: one edit operator
(a taper named ``NAME``), a hand-computed test, the kit, and a CI workflow that installs
parsel with the plugin and runs them.
"""

from __future__ import annotations

import keyword
import os
import re
import shutil
import tempfile
from importlib import resources
from pathlib import Path
from string import Template

from parsel_core.errors import ParselError

TEMPLATE_PACKAGE = "parsel_core"
TEMPLATE_FOLDER = "plugin_template"


def template_files() -> dict[str, str]:
    """Relative path (``package/`` standing for the module folder) -> template text."""
    root = resources.files(TEMPLATE_PACKAGE).joinpath(TEMPLATE_FOLDER)
    out: dict[str, str] = {}

    def walk(folder, prefix: str) -> None:
        for entry in folder.iterdir():
            if entry.is_dir():
                walk(entry, f"{prefix}{entry.name}/")
            elif entry.name.endswith(".tmpl"):
                out[prefix + entry.name.removesuffix(".tmpl")] = entry.read_text(encoding="utf-8")

    walk(root, "")
    return out


def plugin_files(name: str) -> dict[str, str]:
    """The files of a plugin package for operator ``name`` (a lower-case identifier)."""
    if not re.fullmatch(r"[a-z][a-z0-9_]*", name) or keyword.iskeyword(name):
        raise ParselError(f"plugin name {name!r}: use a lower-case Python identifier, e.g. 'taper' or 'bend_y'")
    module = f"parsel_{name}"
    values = {"name": name, "module": module, "dist": name.replace("_", "-"),
              "cls": "".join(part.capitalize() for part in name.split("_"))}
    files = {}
    for path, text in template_files().items():
        target = path.replace("package/", f"{module}/", 1) if path.startswith("package/") else path
        files[target] = Template(text).substitute(values)
    return files


def write_plugin(name: str, target: str | Path) -> list[Path]:
    """Write the package into the new folder ``target`` (all files or none); returns the paths."""
    target = Path(target)
    if target.exists():
        raise ParselError(f"{target}: already exists; give a new folder for the plugin package")
    files = plugin_files(name)
    _write_new_folder(target, files)
    return [target / p for p in sorted(files)]


def _write_new_folder(target: Path, files: dict[str, str]) -> None:
    """Write a package tree (sub-folders included) into a hidden sibling, then rename it into
    place: a failure leaves nothing behind."""
    parent = target.resolve().parent
    if not parent.is_dir():
        raise ParselError(f"{target}: parent directory {parent} does not exist")
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=parent))
    except OSError as exc:
        raise ParselError(f"{target}: cannot write: {exc.strerror}") from None
    try:
        for relative, text in files.items():
            (staging / relative).parent.mkdir(parents=True, exist_ok=True)
            (staging / relative).write_text(text, encoding="utf-8")
        staging.chmod(0o755)
        os.replace(staging, target)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise ParselError(f"{target}: cannot write: {exc.strerror}") from None
