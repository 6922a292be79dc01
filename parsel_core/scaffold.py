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
import re
from importlib import resources
from pathlib import Path
from string import Template

from parsel_core.errors import ParselError
from parsel_core.io import write_outdir

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
    write_outdir(target, files)
    return [target / p for p in sorted(files)]
