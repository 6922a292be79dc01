"""File helpers: atomic writes, so a failure never leaves half a file behind; JSON reads with one-line errors."""

from __future__ import annotations

import json
import os
import tempfile
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
