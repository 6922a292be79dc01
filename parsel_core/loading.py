"""Resolving what users type: example names or paths to shapes, files to programs."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError, ProgramFormatError
from parsel_core.graph import ShapeGraph
from parsel_core.program import Program


def load_shape(spec: str, detect: bool = True) -> ShapeGraph:
    """A bundled example by name (``tiny_table``, ``chair``) or a file any loader reads.

    A shape that arrives without relations (a mesh file) gets those the installed
    detectors find, unless ``detect`` is false.
    """
    from parsel_core.detection import detect_relations
    from parsel_core.plugins import example_shapes, shape_loaders

    shape = _read_shape(spec, example_shapes(), shape_loaders())
    if detect and not shape.relations:
        from parsel_core.config import check_limit

        check_limit("max_detect_parts", f"{spec}: parts to detect relations among", len(shape.parts))
        shape = detect_relations(shape)
    return shape


def _read_shape(spec: str, examples, loaders) -> ShapeGraph:
    if spec in examples and not Path(spec).exists():
        source = examples[spec]
        return source() if callable(source) else _read_shape(str(source), {}, loaders)
    path = Path(spec)
    if not path.exists():
        names = ", ".join(sorted(examples)) or "none"
        raise ParselError(f"{spec}: no such file, and not an example shape (examples: {names})")
    check_file_size(path, "shape")
    for loader in loaders:
        if loader.can_load(path):
            return loader.load(path)
    raise ParselError(f"{spec}: no installed loader reads this kind of file (suffix {path.suffix!r})")


def check_file_size(path: Path, what: str) -> None:
    """Refuse a file over the ``max_file_mb`` limit before reading it (folders are not checked)."""
    from parsel_core.config import check_limit

    try:
        size = path.stat().st_size if path.is_file() else 0
    except OSError:
        return  # the reader names the problem
    check_limit("max_file_mb", f"{path}: {what} file size in MiB", round(size / 2**20, 1))


def load_program(path: str | Path) -> Program:
    """A program from its JSON form (``.json``) or its text form (anything else)."""
    path = Path(path)
    check_file_size(path, "program")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ProgramFormatError(f"{path}: cannot read program: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise ProgramFormatError(f"{path}: program is not UTF-8 text") from None
    if path.suffix.lower() == ".json":
        return Program.from_json(text, source=str(path))
    return Program.from_text(text, source=str(path))


def parse_assignments(items: list[str] | None) -> dict[str, float]:
    """``["x=0.3", "y=1"]`` -> ``{"x": 0.3, "y": 1.0}``, with a clear error naming the item."""
    values: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            if not sep or not name.strip():
                raise ValueError
            values[name.strip()] = float(value)
            if not math.isfinite(values[name.strip()]):
                raise ValueError
        except ValueError:
            raise ParselError(f"--set {item!r}: expected NAME=NUMBER") from None
    return values


def parse_options(items: list[str] | None, flag: str) -> dict[str, Any]:
    """``["joint=0", "backend=sympy"]`` -> ``{"joint": 0, "backend": "sympy"}``: a JSON
    number, ``true``, ``false``, ``null`` or string is that value, anything else the text
    itself (a name); whoever takes the options checks names and values. ``flag`` names
    the option in the error."""
    options: dict[str, Any] = {}
    for item in items or []:
        name, sep, text = item.partition("=")
        if not sep or not name.strip() or not text.strip():
            raise ParselError(f"{flag} {item!r}: expected NAME=VALUE, e.g. joint=0")
        try:
            value = json.loads(text)
        except ValueError:
            value = text
        options[name.strip()] = text if isinstance(value, (list, dict)) else value
    return options
