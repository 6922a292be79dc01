"""Output folders (``-o OUTDIR``): parsel never deletes or replaces a file it did not write.

An OUTDIR parsel wrote holds a manifest (``.parsel-manifest.json``) naming the files it
wrote there. Writing into a folder:

* a missing folder is filled in a hidden staging folder beside it and renamed into place,
  so it appears whole or not at all;
* a folder with a manifest (an earlier parsel output) gets the new files; the files the
  earlier manifest names and this run does not write are removed; every other file stays;
* an empty folder is used as it is; a non-empty folder without a manifest is refused
  unless ``force``, and even then only the files parsel writes are replaced;
* the working directory (``-o .``), one of its ancestors and ``-o ""`` are refused.

New files are staged first; the files they replace are set aside and put back if any
step fails, so a failed run leaves the folder as it was.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError

MANIFEST = ".parsel-manifest.json"
#: Staging folders carry the writer's process id, so a later run can remove those a killed run left.
STAGING_INSIDE = ".parsel-staging-"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def _remove_dead_staging(folder: Path, prefix: str) -> None:
    """Remove staging folders named ``<prefix><pid>-...`` whose writer is no longer running."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return
    for entry in entries:
        if not entry.name.startswith(prefix) or not entry.is_dir() or entry.is_symlink():
            continue
        pid = entry.name[len(prefix):].split("-", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            shutil.rmtree(entry, ignore_errors=True)


def _sibling_prefix(target: Path) -> str:
    return f".{target.name}.parsel-"


def read_manifest(folder: Path) -> set[str] | None:
    """The file names an earlier parsel run wrote in ``folder``; ``None`` without a usable manifest."""
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict) or data.get("format") != "parsel.output" or not isinstance(data.get("files"), list):
        return None
    return {name for name in data["files"] if _plain_name(name)}


def _plain_name(name: object) -> bool:
    return (isinstance(name, str) and name not in ("", ".", "..", MANIFEST) and "/" not in name
            and "\\" not in name and "\0" not in name)


def check_output_dir(outdir: str, force: bool = False) -> Path:
    """Refuse an OUTDIR parsel may not write (before any expensive work); the path to write."""
    if not isinstance(outdir, str) or not outdir.strip():
        raise ParselError('-o "": an output directory is needed')
    target = Path(outdir)
    try:
        resolved = target.resolve()
        cwd = Path.cwd().resolve()
    except (OSError, RuntimeError) as exc:
        raise ParselError(f"{outdir}: cannot resolve the output directory: {exc}") from None
    if resolved == cwd or resolved in cwd.parents:
        raise ParselError(f"-o {outdir}: is the working directory or one of its parents; name a folder of its own")
    if not resolved.parent.is_dir():
        raise ParselError(f"{outdir}: parent directory {resolved.parent} does not exist")
    if target.exists() and not target.is_dir():
        raise ParselError(f"{outdir}: exists and is not a directory")
    if target.is_dir() and read_manifest(target) is None and not force:
        try:
            others = [e.name for e in target.iterdir() if not e.name.startswith(STAGING_INSIDE)]
        except OSError as exc:
            raise ParselError(f"{outdir}: cannot read the output directory: {exc.strerror}") from None
        if others:
            raise ParselError(f"{outdir}: holds files parsel did not write ({len(others)} entries, e.g. "
                              f"{sorted(others)[0]!r}); choose another folder, or --force to write parsel's "
                              "files beside them")
    return target


def _manifest_text(names: list[str]) -> str:
    return json.dumps({"format": "parsel.output", "version": 1, "files": sorted(names)}, indent=1) + "\n"


def write_outdir(outdir: str, files: dict[str, str], force: bool = False) -> None:
    """Write ``files`` (name -> text) into OUTDIR as the module docstring says: all or nothing."""
    target = check_output_dir(outdir, force)
    for name in files:
        if not _plain_name(name):
            raise ParselError(f"{outdir}: {name!r} is not a plain file name")
    if target.is_dir():
        _write_into_existing(outdir, target, files)
    else:
        _write_new(outdir, target, files)


def _write_new(outdir: str, target: Path, files: dict[str, str]) -> None:
    parent = target.resolve().parent
    _remove_dead_staging(parent, _sibling_prefix(target))
    try:
        staging = Path(tempfile.mkdtemp(prefix=f"{_sibling_prefix(target)}{os.getpid()}-", dir=parent))
    except OSError as exc:
        raise ParselError(f"{outdir}: cannot write: {exc.strerror}") from None
    try:
        os.chmod(staging, 0o777 & ~_umask())  # mkdtemp makes 0700 folders; give the usual permissions
        for name, text in files.items():
            (staging / name).write_text(text, encoding="utf-8")
        (staging / MANIFEST).write_text(_manifest_text(list(files)), encoding="utf-8")
        os.replace(staging, target)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise ParselError(f"{outdir}: cannot write: {exc.strerror}") from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _write_into_existing(outdir: str, target: Path, files: dict[str, str]) -> None:
    previous = read_manifest(target) or set()
    names = [*files, MANIFEST]  # the manifest last: it names only files that are in place
    for name in names:
        if (target / name).is_dir() and not (target / name).is_symlink():
            raise ParselError(f"{target / name}: is a directory; parsel writes a file of that name")
    _remove_dead_staging(target, STAGING_INSIDE)
    try:
        staging = Path(tempfile.mkdtemp(prefix=f"{STAGING_INSIDE}{os.getpid()}-", dir=target))
    except OSError as exc:
        raise ParselError(f"{outdir}: cannot write: {exc.strerror}") from None
    new, old = staging / "new", staging / "old"
    moved: list[str] = []
    kept: list[str] = []  # names whose previous file was set aside in ``old``
    current = target

    def roll_back() -> None:
        for name in moved:
            (target / name).unlink(missing_ok=True)
        for name in kept:
            os.replace(old / name, target / name)

    try:
        new.mkdir()
        old.mkdir()
        for name, text in files.items():
            current = target / name
            (new / name).write_text(text, encoding="utf-8")
        (new / MANIFEST).write_text(_manifest_text(list(files)), encoding="utf-8")
        for name in names:
            current = target / name
            if os.path.lexists(target / name):
                os.replace(target / name, old / name)
                kept.append(name)
            os.replace(new / name, target / name)
            moved.append(name)
    except OSError as exc:
        roll_back()
        shutil.rmtree(staging, ignore_errors=True)
        raise ParselError(f"{current}: cannot write: {exc.strerror}") from None
    except BaseException:
        roll_back()
        shutil.rmtree(staging, ignore_errors=True)
        raise
    shutil.rmtree(staging, ignore_errors=True)
    for name in sorted(previous - set(names)):  # files an earlier run wrote and this one does not
        stale = target / name
        if stale.is_file() and not stale.is_symlink():
            stale.unlink(missing_ok=True)


# -- single files and standard output ------------------------------------------------------

#: ``-o -``: the output goes to standard output instead of a file.
STDOUT = "-"


def to_stdout(output: str | Path | None) -> bool:
    """Whether a single-file ``-o`` means standard output (``-o -``, or no ``-o`` where that is allowed)."""
    return output is None or str(output) == STDOUT


def stdout_suffix(option: str, output: str | Path | None, fmt: str | None, known: Iterable[str]) -> str | None:
    """The file suffix that picks the format: ``--format`` with ``-o -``, else the output's own.

    Writing to standard output leaves no suffix to read, so ``--format`` names it; a
    ``--format`` that disagrees with a file's suffix is refused rather than guessed at.
    """
    known = sorted(known)
    if fmt is not None:
        suffix = "." + fmt.lower().lstrip(".")
        if suffix not in known:
            raise ParselError(f"--format {fmt!r}: unknown format (known: {', '.join(s[1:] for s in known)})")
        if not to_stdout(output) and not str(output).lower().endswith(suffix):
            raise ParselError(f"{option} {output}: --format {fmt} is for {option} - (standard output); "
                              "a file's suffix names its format")
        return suffix
    if output is None:
        raise ParselError(f"no {option} FILE: name an output file, or the format of standard output with --format "
                          f"(one of {', '.join(s[1:] for s in known)})")
    if to_stdout(output):
        raise ParselError(f"{option} -: name the format with --format (one of {', '.join(s[1:] for s in known)})")
    return None


def write_single(output: str | Path | None, data: str | bytes) -> None:
    """One output file written atomically, or ``data`` on standard output for ``-o -``."""
    if to_stdout(output):
        stream = sys.stdout
        if isinstance(data, bytes):
            stream.flush()
            stream.buffer.write(data)
            stream.buffer.flush()
        else:
            stream.write(data)
            stream.flush()
        return
    from parsel_core.io import atomic_write_bytes

    atomic_write_bytes(output, data.encode("utf-8") if isinstance(data, str) else data)


def written_by(suffix: str, write: Callable[[Path], Any]) -> bytes:
    """The bytes ``write(path)`` puts in a file ending in ``suffix``, for writers that only take
    paths (exporters, matplotlib) when the output is standard output; the scratch file is removed."""
    with tempfile.TemporaryDirectory(prefix="parsel-stdout-") as scratch:
        path = Path(scratch) / f"output{suffix}"
        write(path)
        return path.read_bytes()
