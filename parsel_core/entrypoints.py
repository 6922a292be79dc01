"""Installed entry points, remembered between processes.

Every ``parsel`` command reads the ``parsel`` and ``parsel.commands`` entry-point groups.
Asking :mod:`importlib.metadata` costs a fresh process about 60 ms of CPU (importing it
parses package metadata with the :mod:`email` package, then every installed
distribution's ``entry_points.txt`` is read), more than any plugin's import. The answer
only changes when distributions are installed, removed or edited, so it is kept in a
small JSON file, as stevedore (OpenStack's plugin loader) does for the same reason.

An answer is valid for a :func:`fingerprint` of the import path: ``sys.path`` itself,
the ``*.dist-info`` and ``*.egg-info`` in each of its folders and the ``EGG-INFO`` of
an egg on it, each with the modification time and size of the folder and of its
``entry_points.txt`` (an edit in place). Any difference, or a file that cannot be read,
is a miss: the groups are read with :mod:`importlib.metadata` again and the file
rewritten (to a temporary name, then renamed). One file per interpreter keeps the
answers for the last :data:`KEPT` import paths (the ``parsel`` script's differs from
``python -c``'s in its first entry). A cache that cannot be read or written is no error:
the process reads the metadata. Distributions that a custom ``sys.meta_path`` finder
provides without files on the import path are not seen changing; ``PARSEL_CACHE_DIR=``
(empty) turns the cache off.

The folder is ``$PARSEL_CACHE_DIR``, else ``$XDG_CACHE_HOME/parsel`` (when absolute, as
the XDG specification asks), else ``~/.cache/parsel``.
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
FORMAT = 2
#: Import paths remembered per interpreter (most recent first).
KEPT = 8
_INFO_SUFFIXES = (".dist-info", ".egg-info")
#: ``installed_entry_points``'s folder when none is given: :func:`cache_dir`.
DEFAULT_FOLDER: Any = object()


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
        return Path(chosen).expanduser() if chosen else None
    xdg = environ.get("XDG_CACHE_HOME", "")
    base = Path(xdg) if os.path.isabs(xdg) else Path(os.path.expanduser("~")) / ".cache"
    return base / "parsel"


def _stamp(path: str) -> list[int] | None:
    """Modification time and size (a file system with coarse times still sees most edits)."""
    try:
        stat = os.stat(path)
    except OSError:
        return None
    return [stat.st_mtime_ns, stat.st_size]


def _info_stamps(folder: str) -> list[list[Any]]:
    """``[name, folder stamp, entry_points.txt stamp]`` of each distribution's metadata in ``folder``."""
    out = []
    with os.scandir(folder) as listing:
        for item in listing:
            if item.name.lower().endswith(_INFO_SUFFIXES):
                out.append([item.name, _stamp(item.path), _stamp(os.path.join(item.path, "entry_points.txt"))])
    egg = os.path.join(folder, "EGG-INFO")  # the folder is an egg itself
    if os.path.isdir(egg):
        out.append(["EGG-INFO", _stamp(egg), _stamp(os.path.join(egg, "entry_points.txt"))])
    return sorted(out)


def import_path(path: Sequence[Any] | None = None) -> list[str]:
    """``sys.path`` (or ``path``) as text: ``Path`` entries written out, others left out
    (importlib.metadata skips what is not a path as well)."""
    out = []
    for entry in sys.path if path is None else path:
        if isinstance(entry, (str, bytes, os.PathLike)):
            out.append(os.fsdecode(entry))
    return out


def fingerprint(path: Sequence[str]) -> list[list[Any]]:
    """What the installed entry points depend on, as JSON-ready lists (see the module):
    per import-path folder, its distributions' metadata folders with their stamps (an
    install, removal or upgrade changes the names or a stamp; writing anything else
    there changes nothing); per zip file or missing folder, its own stamp."""
    out: list[list[Any]] = []
    for entry in path:
        folder = entry or "."
        try:
            out.append([entry, _info_stamps(folder)])
        except OSError:  # a zip file, or a folder that is not there
            out.append([entry, _stamp(folder)])
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
    # (bytes: a folder name that is not valid UTF-8 still names one file)
    tag = zlib.crc32(b"\0".join([os.fsencode(sys.executable), sys.version.encode()]))
    return folder / f"entry-points-{tag:08x}.json"


def _valid_row(row: Any) -> bool:
    return (isinstance(row, list) and len(row) == 4 and all(isinstance(v, str) for v in row[:2])
            and all(v is None or isinstance(v, str) for v in row[2:]))


def _read_file(file: Path) -> list[Any]:
    """The file's entries (``[fingerprint, groups]``, most recent first); none when it is
    missing, damaged or of another format."""
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return []
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("entries"), list):
        return []
    return [e for e in data["entries"] if isinstance(e, list) and len(e) == 2 and isinstance(e[1], dict)]


def _answer(entries: list[Any], key: list[list[Any]], groups: list[str]) -> dict[str, list[InstalledEntryPoint]] | None:
    """The remembered groups for ``key``, if every one of them is there and well formed."""
    for fingerprint_, stored in entries:
        if fingerprint_ != key:
            continue
        if sorted(stored) != groups or not all(isinstance(rows, list) and all(map(_valid_row, rows))
                                               for rows in stored.values()):
            return None
        return {group: [InstalledEntryPoint(row[0], row[1], group, row[2], row[3]) for row in rows]
                for group, rows in stored.items()}
    return None


def _store(file: Path, entries: list[Any], key: list[list[Any]], found: dict[str, list[InstalledEntryPoint]]) -> None:
    from parsel_core.errors import ParselError
    from parsel_core.io import atomic_write_text

    stored = {g: [[e.name, e.value, e.distribution, e.version] for e in eps] for g, eps in found.items()}
    kept = [[key, stored]] + [e for e in entries if e[0] != key][:KEPT - 1]
    try:
        file.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(file, json.dumps({"format": FORMAT, "entries": kept}))
    except (OSError, ParselError):  # a read-only home, a full disk: the metadata is read next time
        pass


def installed_entry_points(groups: Iterable[str], folder: str | os.PathLike | None = DEFAULT_FOLDER,
                           ) -> dict[str, list[InstalledEntryPoint]]:
    """The installed entry points of each group, by name; from the cache when the import
    path has not changed since it was written (``folder``: the cache folder, by default
    :func:`cache_dir`; ``None``: no cache)."""
    groups = sorted(set(groups))
    folder = cache_dir() if folder is DEFAULT_FOLDER else folder
    if folder is None:
        return _read_installed(groups)
    file = _cache_file(Path(folder))
    key = fingerprint(import_path())
    entries = _read_file(file)
    found = _answer(entries, key, groups)
    if found is None:
        found = _read_installed(groups)
        _store(file, entries, key, found)
    return found
