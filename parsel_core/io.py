"""File helpers: atomic writes, so a failure never leaves half a file behind; JSON reads with one-line errors."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError


def atomic_write_bytes(path: Path | str, data: bytes) -> None:
    """Write to a temporary file beside ``path``, then rename over it."""
    path = Path(path)
    if not path.parent.is_dir():
        raise ParselError(f"{path}: directory {path.parent} does not exist")
    if path.is_dir():
        raise ParselError(f"{path}: is a directory")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as exc:
        raise ParselError(f"{path}: cannot write: {exc.strerror}") from None
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files; give the usual permissions
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise ParselError(f"{path}: cannot write: {exc.strerror}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: Path | str, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def read_json(path: Path | str, what: str = "") -> Any:
    """The JSON document in ``path``.

    An unreadable file or malformed JSON raises a one-line :class:`ParselError` naming the
    file (and ``what`` it was meant to hold: ``labels``).
    """
    path = Path(path)
    file_is = f"{what} file is " if what else ""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ParselError(f"{path}: cannot read{' ' + what if what else ''}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ParselError(f"{path}: {file_is}not valid JSON: {exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParselError(f"{path}: {file_is}not valid JSON: {exc}") from None
    except (ValueError, RecursionError) as exc:  # a number too long to convert, nesting too deep
        raise ParselError(f"{path}: {file_is}not usable JSON: {' '.join(str(exc).split()) or type(exc).__name__}") \
            from None


def write_outdir(outdir: str | Path, files: dict[str, str], force: bool = False) -> None:
    """Write an OUTDIR: :func:`parsel_core.outputs.write_outdir` (a manifest of parsel's own
    files, never a user's file replaced or removed, all files or none)."""
    from parsel_core.outputs import write_outdir as write

    write(str(outdir), files, force)


def write_all(paths: list[Path], write: Callable[[int, Path], None]) -> None:
    """Write every file or none: ``write(i, staging_path)`` fills a staging folder beside the
    files, which are then moved into place, files they replace set aside; on a failure the
    new files are removed and the old ones put back."""
    folder = paths[0].parent
    if not folder.is_dir():
        raise ParselError(f"{paths[0]}: directory {folder} does not exist")
    for path in paths:
        if path.is_dir():
            raise ParselError(f"{path}: is a directory")
    try:
        staging = Path(tempfile.mkdtemp(prefix=".parsel-", dir=folder))
    except OSError as exc:
        raise ParselError(f"{paths[0]}: cannot write: {exc.strerror}") from None
    new, old = staging / "new", staging / "old"
    moved: list[Path] = []
    kept: list[Path] = []  # targets whose previous file was set aside in ``old``
    current = paths[0]

    def roll_back() -> None:
        for path in moved:
            path.unlink(missing_ok=True)
        for path in kept:
            os.replace(old / path.name, path)

    try:
        new.mkdir()
        old.mkdir()
        for i, path in enumerate(paths):
            current = path
            write(i, new / path.name)
        for path in paths:
            current = path
            if path.exists():
                os.replace(path, old / path.name)
                kept.append(path)
            os.replace(new / path.name, path)
            moved.append(path)
    except OSError as exc:
        roll_back()
        raise ParselError(f"{current}: cannot write: {exc.strerror}") from None
    except BaseException:
        roll_back()
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
