"""The plugin manager: the one registry in parsel.

Built-in plugins are registered first, then every entry point of the ``parsel`` group.
A plugin that fails to import or register is skipped with a warning naming it; set
``PARSEL_STRICT_PLUGINS=1`` to make that an error (CI does). ``PARSEL_PLUGINS`` (a
comma-separated list of entry-point names) limits which installed plugins load (a name
that is not installed is an error listing the installed ones); ``PARSEL_PLUGINS=""``
loads none besides the built-ins.
"""

from __future__ import annotations

import importlib
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache, lru_cache
from typing import Any

import pluggy

from parsel_core import hookspecs
from parsel_core.entrypoints import installed_entry_points
from parsel_core.errors import UnknownPluginError

ENTRY_POINT_GROUP = "parsel"
#: Sub-commands a plugin adds, declared in its metadata (``view = "parsel_view"``) so that
#: ``parsel --help`` can list them without importing the plugin.
COMMANDS_GROUP = "parsel.commands"
BUILTIN_PLUGINS = (
    "parsel_core.builtin.operators",
    "parsel_core.builtin.shapes",
    "parsel_core.builtin.exporters",
    "parsel_core.language.templates",
    "parsel_core.language.replay",
)
#: The entry-point groups parsel reads, looked up together (entrypoints.py caches them).
GROUPS = (ENTRY_POINT_GROUP, COMMANDS_GROUP)


class PluginLoadWarning(UserWarning):
    """A plugin was skipped because it failed to import or register."""


@dataclass
class PluginRecord:
    """What ``parsel plugins`` reports about one plugin."""

    name: str
    module: str
    version: str | None
    builtin: bool
    error: str | None = None
    hooks: list[str] = field(default_factory=list)


class ParselPluginManager(pluggy.PluginManager):
    """A pluggy manager that remembers where each plugin came from and what failed."""

    def __init__(self) -> None:
        super().__init__("parsel")
        self.add_hookspecs(hookspecs)
        self.records: dict[str, PluginRecord] = {}

    def register_builtin(self, module_name: str) -> None:
        module = importlib.import_module(module_name)
        self.register(module, name=module_name)
        self.records[module_name] = PluginRecord(module_name, module_name, _core_version(), True)

    def load_entry_points(self) -> None:
        strict = os.environ.get("PARSEL_STRICT_PLUGINS", "") not in ("", "0")
        allow = _allowed_plugins()
        seen = set()
        installed = installed_entry_points(GROUPS)[ENTRY_POINT_GROUP]
        missing = sorted((allow or set()) - {ep.name for ep in installed})
        if missing:
            raise UnknownPluginError(
                f"PARSEL_PLUGINS names {', '.join(map(repr, missing))}, which {'is' if len(missing) == 1 else 'are'}"
                f" not installed (installed: {', '.join(sorted({ep.name for ep in installed})) or 'none'})")
        for ep in installed:
            if ep.name in seen or (allow is not None and ep.name not in allow):
                continue
            seen.add(ep.name)
            version = ep.version
            try:
                plugin = ep.load()
                self.register(plugin, name=ep.name)
            except Exception as exc:  # a broken plugin must not take the engine down
                message = f"parsel plugin {ep.name!r} ({ep.value}) failed to load: {type(exc).__name__}: {exc}"
                if strict:
                    raise RuntimeError(message) from exc
                warnings.warn(message, PluginLoadWarning, stacklevel=2)
                self.records[ep.name] = PluginRecord(ep.name, ep.value, version, False, error=str(exc))
                continue
            self.records[ep.name] = PluginRecord(ep.name, ep.value, version, False)

    def describe(self) -> list[PluginRecord]:
        """Records with the hooks each registered plugin implements."""
        out = []
        for name, record in self.records.items():
            plugin = self.get_plugin(name)
            if plugin is not None:
                record.hooks = sorted(
                    caller.name for caller in self.get_hookcallers(plugin) or [])
            out.append(record)
        return out


def _allowed_plugins() -> set[str] | None:
    """Entry-point names ``PARSEL_PLUGINS`` allows; ``None``: all."""
    allowed = os.environ.get("PARSEL_PLUGINS")
    return None if allowed is None else {n.strip() for n in allowed.split(",") if n.strip()}


def declared_commands() -> dict[str, str]:
    """Sub-command name -> a help line naming its plugin, from metadata only (no import).

    Plugins list the commands they add under the ``parsel.commands`` entry-point group;
    plugins that ``PARSEL_PLUGINS`` leaves out are left out here too.
    """
    allow = _allowed_plugins()
    installed = installed_entry_points(GROUPS)
    out: dict[str, str] = {}
    for ep in installed[COMMANDS_GROUP]:
        if allow is not None:
            names = {e.name for e in installed[ENTRY_POINT_GROUP]
                     if ep.distribution is not None and e.distribution == ep.distribution}
            if not names & allow:
                continue
        where = ep.distribution if ep.distribution is not None else ep.value
        out.setdefault(ep.name, f"from {where} (parsel {ep.name} --help says more)")
    return out


def _core_version() -> str:
    from parsel_core import __version__

    return __version__


def make_plugin_manager(load_entry_points: bool = True) -> ParselPluginManager:
    """A fresh manager with the built-ins and (optionally) the installed plugins."""
    pm = ParselPluginManager()
    for module_name in BUILTIN_PLUGINS:
        pm.register_builtin(module_name)
    if load_entry_points:
        pm.load_entry_points()
    return pm


@lru_cache(maxsize=1)
def get_plugin_manager() -> ParselPluginManager:
    """The process-wide manager, created on first use."""
    return make_plugin_manager()


@contextmanager
def registered(plugin: Any, name: str | None = None) -> Iterator[ParselPluginManager]:
    """Register ``plugin`` for the duration of a ``with`` block (tests, notebooks)."""
    pm = get_plugin_manager()
    name = pm.register(plugin, name=name)
    try:
        yield pm
    finally:
        pm.unregister(name=name)


def _collect(hook_name: str) -> list[Any]:
    """All contributions to a list-returning hook, built-ins first, later plugins last."""
    results = getattr(get_plugin_manager().hook, hook_name)()
    items: list[Any] = []
    for result in reversed(results):  # pluggy calls the latest registration first
        items.extend(result or [])
    return items


def _by_name(items: list[Any], kind: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        name = getattr(item, "name", "")
        if not name:
            raise TypeError(f"a {kind} contributed by a plugin has no name: {item!r}")
        out[name] = item  # later registrations replace earlier ones of the same name
    return out


def edit_operators() -> dict[str, type]:
    """Registered edit operators by name."""
    from parsel_core.ops import EditOp

    ops = _by_name(_collect("parsel_edit_operators"), "edit operator")
    for name, cls in ops.items():
        if not (isinstance(cls, type) and issubclass(cls, EditOp)):
            raise TypeError(f"edit operator {name!r} is not an EditOp subclass")
    return ops


@cache
def _backend_instance(cls: type) -> Any:
    from parsel_core.cas import check_backend

    backend = cls()
    check_backend(backend)
    return backend


def cas_backend_names() -> list[str]:
    return sorted(_by_name(_collect("parsel_cas_backends"), "CAS backend"))


def get_cas_backend(name: str | None = None):
    """A CAS backend by name; ``None`` means the configured default."""
    from parsel_core.config import backend_source, default_backend_name

    classes = _by_name(_collect("parsel_cas_backends"), "CAS backend")
    origin = "" if name else f" (from {backend_source()})"
    name = name or default_backend_name(list(classes))
    if name not in classes:
        known = ", ".join(sorted(classes)) or "none installed"
        raise UnknownPluginError(f"unknown CAS backend {name!r}{origin} (installed: {known})")
    return _backend_instance(classes[name])


def _instances(hook_name: str, kind: str) -> dict[str, Any]:
    items = _by_name(_collect(hook_name), kind)
    return {name: item() if isinstance(item, type) else item for name, item in items.items()}


def shape_loaders() -> list[Any]:
    """Loaders, most recently registered first (so plugins can override built-ins)."""
    return list(reversed(list(_instances("parsel_shape_loaders", "shape loader").values())))


def relation_detectors() -> dict[str, Any]:
    return _instances("parsel_relation_detectors", "relation detector")


def llm_providers() -> dict[str, Any]:
    return _instances("parsel_llm_providers", "LLM provider")


def deformers() -> dict[str, Any]:
    return _instances("parsel_deformers", "deformer")


def exporters() -> dict[str, Any]:
    return _instances("parsel_exporters", "exporter")


def solvers() -> dict[str, Any]:
    return _instances("parsel_solvers", "solver")


def exporter_for(shape, path) -> Any:
    """The exporter for an output path: by suffix, preferring one that can export this shape
    (mesh exporters need parts with meshes; the hexahedra exporters take any shape)."""
    from pathlib import Path

    name = Path(path).name.lower()
    matching = [e for e in reversed(list(exporters().values())) if any(name.endswith(x) for x in e.extensions)]
    if not matching:
        known = sorted({x for e in exporters().values() for x in e.extensions})
        raise UnknownPluginError(f"{path}: no exporter writes this format (known: {', '.join(known)})")
    for exporter in matching:
        if getattr(exporter, "can_export", lambda shape: True)(shape):
            return exporter
    return matching[-1]


def example_shapes() -> dict[str, Any]:
    """Example name -> callable or path, later plugins overriding earlier ones."""
    out: dict[str, Any] = {}
    for result in reversed(get_plugin_manager().hook.parsel_example_shapes()):
        out.update(result or {})
    return out


def prompt_templates() -> dict[str, str]:
    """Template name -> text, later plugins overriding earlier ones (paths are read)."""
    from pathlib import Path

    out: dict[str, str] = {}
    for result in reversed(get_plugin_manager().hook.parsel_prompt_templates()):
        for name, template in (result or {}).items():
            out[name] = Path(template).read_text(encoding="utf-8") if isinstance(template, Path) else template
    return out


def get_named(kind: str, table: dict[str, Any], name: str) -> Any:
    """Look a contribution up by name with a one-line error listing what exists."""
    if name not in table:
        raise UnknownPluginError(f"unknown {kind} {name!r} (installed: {', '.join(sorted(table)) or 'none'})")
    return table[name]
