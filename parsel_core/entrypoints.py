"""Installed entry points, remembered between processes.

Every ``parsel`` command reads the ``parsel`` and ``parsel.commands`` entry-point groups.
Asking :mod:`importlib.metadata` costs a fresh process about 60 ms of CPU (importing it
parses package metadata with the :mod:`email` package, then every installed
distribution's ``entry_points.txt`` is read), more than any plugin's import. The answer
only changes when distributions are installed, removed or edited, so it is kept in a
small JSON file, as stevedore (OpenStack's plugin loader) does for the same reason.

The file is valid for a :func:`fingerprint` of the import path: ``sys.path`` itself and
the ``*.dist-info`` and ``*.egg-info`` in each of its folders, with the modification
times and sizes of each and of its ``entry_points.txt`` (an edit in place). Any difference, or a file that cannot be
read, is a miss: the groups are read with :mod:`importlib.metadata` again and the file
rewritten (to a temporary name, then renamed). A cache folder that cannot be written is
no error; the process reads the metadata each time.

The folder is ``$PARSEL_CACHE_DIR``, else ``$XDG_CACHE_HOME/parsel``, else
``~/.cache/parsel``; ``PARSEL_CACHE_DIR=`` (empty) turns the cache off.
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Bumped when the file's layout changes.
FORMAT = 1
_INFO_SUFFIXES = (".dist-info", ".egg-info")


@dataclass(frozen=True)
class InstalledEntryPoint:
    """One entry point of an installed distribution (what parsel needs of
    :class:`importlib.metadata.EntryPoint`)."""

    name: str
    value: str        # "module.path:attribute.path", perhaps with " [extras]"
    group: str
    distribution: str | None
    version: str | None

    def load(self) -> Any:
        """The object the entry point names, imported (as ``EntryPoint.load``)."""
        target = self.value.split("[", 1)[0].strip()
        module_name, _, attribute = target.partition(":")
        obj = importlib.import_module(module_name.strip())
        for name in filter(None, attribute.strip().split(".")):
            obj = getattr(obj, name)
        return obj


def cache_dir(environ: Mapping[str, str] = os.environ) -> Path | None:
    """Where parsel keeps its caches; ``None`` when ``PARSEL_CACHE_DIR`` is set empty."""
    chosen = environ.get("PARSEL_CACHE_DIR")
    if chosen is not None:
        return Path(chosen) if chosen else None
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "parsel"


def _stamp(path: str) -> list[int] | None:
    """Modification time and size (a file system with coarse times still sees most edits)."""
    try:
        stat = os.stat(path)
    except OSError:
        return None
    return [stat.st_mtime_ns, stat.st_size]


def fingerprint(path: Sequence[str]) -> list:
    """What the installed entry points depend on, as JSON-ready lists (see the module):
    per import-path folder, its ``*.dist-info`` and ``*.egg-info`` with their stamps (an
    install, removal or upgrade changes the names or a folder's stamp; writing anything
    else there changes nothing); per zip file or missing folder, its own stamp."""
    out: list = []
    for entry in path:
        folder = entry or "."
        try:
            with os.scandir(folder) as listing:
                infos = sorted([item.name, _stamp(item.path), _stamp(os.path.join(item.path, "entry_points.txt"))]
                               for item in listing if item.name.endswith(_INFO_SUFFIXES))
        except OSError:  # a zip file, or a folder that is not there
            out.append([entry, _stamp(folder)])
        else:
            out.append([entry, infos])
    return out


def _read_installed(groups: Iterable[str]) -> dict[str, list[InstalledEntryPoint]]:
    """The groups as :mod:`importlib.metadata` finds them now."""
    from importlib import metadata

    selected = metadata.entry_points()
    out: dict[str, list[InstalledEntryPoint]] = {}
    for group in groups:
        found = []
        for ep in selected.select(group=group):
            dist = getattr(ep, "dist", None)
            found.append(InstalledEntryPoint(ep.name, ep.value, group, dist.name if dist is not None else None,
                                             dist.version if dist is not None else None))
        out[group] = sorted(found, key=lambda e: e.name)
    return out


def _cache_file(folder: Path) -> Path:
    # One file per interpreter, environment and import path (the ``parsel`` script's and
    # ``python -c``'s differ in their first entry): they do not overwrite each other's.
    tag = zlib.crc32("\0".join([sys.executable, sys.version, *sys.path]).encode())
    return folder / f"entry-points-{tag:08x}.json"


def _load_cached(file: Path, key: list, groups: list[str]) -> dict[str, list[InstalledEntryPoint]] | None:
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
        if data["format"] != FORMAT or data["fingerprint"] != key or sorted(data["groups"]) != groups:
            return None
        return {group: [InstalledEntryPoint(*row[:2], group, *row[2:4]) for row in rows]
                for group, rows in data["groups"].items()}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _store(file: Path, key: list, found: dict[str, list[InstalledEntryPoint]]) -> None:
    import tempfile

    data = {"format": FORMAT, "fingerprint": key,
            "groups": {g: [[e.name, e.value, e.distribution, e.version] for e in eps] for g, eps in found.items()}}
    try:
        file.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=".entry-points-", suffix=".tmp", dir=file.parent)
        try:
            with os.fdopen(handle, "w", encoding="utf-8") as out:
                json.dump(data, out)
            os.replace(temporary, file)
        except BaseException:
            os.unlink(temporary)
            raise
    except OSError:  # a read-only home, a full disk: the next process reads the metadata again
        pass


def installed_entry_points(groups: Iterable[str], folder: Path | None | str = "default",
                           ) -> dict[str, list[InstalledEntryPoint]]:
    """The installed entry points of each group, by name; from the cache when the import
    path has not changed since it was written (``folder``: the cache folder, ``None`` for
    none, ``"default"`` for :func:`cache_dir`)."""
    groups = sorted(set(groups))
    folder = cache_dir() if folder == "default" else folder
    if folder is None:
        return _read_installed(groups)
    file = _cache_file(Path(folder))
    key = fingerprint(sys.path)
    found = _load_cached(file, key, groups)
    if found is None:
        found = _read_installed(groups)
        _store(file, key, found)
    return found
