"""Part names and labels: how a node called ``leg.003`` becomes a part labelled ``leg``.

Asset files name parts after what they are plus an index that only makes the name
unique (Blender's ``.003``, ``_2``, ``-01``). The label is the part's kind, which is
what relation detection and the language layer reason about, so the index and the
separators around it are dropped. A sidecar ``<stem>.labels.json`` overrides labels
where the names are not descriptive.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from pathlib import Path

from parsel_core.errors import ParselError
from parsel_core.io import read_json

_TRAILING_INDEX = re.compile(r"(?:[\s._\-#]*\d+)+[\s._\-#]*$")
_INNER_SEPARATORS = re.compile(r"[\s\-]+")
_GENERATED = re.compile(r"geometry(?:_\d+)?")
_NATURAL_CHUNK = re.compile(r"(\d+)")
SIDECAR_SUFFIX = ".labels.json"


def label_of(name: str) -> str:
    """The semantic label of a part name: trailing indices and separators removed, lower-case.

    ``leg.003`` -> ``leg``, ``back_slat_2`` -> ``back_slat``, ``Leg-01`` -> ``leg``; inner
    runs of spaces or hyphens become ``_`` (``Back Slat 2`` -> ``back_slat``) so labels read
    as identifiers. A name that is all index keeps its digits rather than becoming empty.
    """
    stripped = name.strip()
    stem = _TRAILING_INDEX.sub("", stripped).strip(" ._-#")
    stem = _INNER_SEPARATORS.sub("_", stem).lower()
    return stem or stripped.lower() or "part"


def is_generated_name(name: str, path: Path | None = None) -> bool:
    """Whether a name was made up by the reader rather than stored in the file.

    trimesh names unnamed geometry ``geometry_N`` or after the file; such names say
    nothing about the part, so a scene that has only those has no named parts.
    """
    name = name.strip()
    if not name or _GENERATED.fullmatch(name):
        return True
    return path is not None and name in (path.name, path.stem)


def natural_key(name: str) -> tuple:
    """Sort key that orders ``leg.2`` before ``leg.10`` and ignores case (ties broken by the name)."""
    chunks = tuple(int(chunk) if chunk.isdigit() else chunk.lower() for chunk in _NATURAL_CHUNK.split(name))
    return chunks, name


def sidecar_path(path: Path) -> Path:
    """``chair.glb`` -> ``chair.labels.json`` beside it (a directory ``d`` -> ``d.labels.json``)."""
    stem = path.name if path.is_dir() else path.stem
    return path.with_name(stem + SIDECAR_SUFFIX)


def read_sidecar(path: Path) -> dict[str, str] | None:
    """The label overrides stored beside ``path``, or ``None`` when there is no sidecar."""
    sidecar = sidecar_path(path)
    if not sidecar.is_file():
        return None
    data = read_json(sidecar, "labels")
    if not isinstance(data, Mapping):
        raise ParselError(f"{sidecar}: labels file must be a JSON object mapping part names to labels")
    labels = {}
    for name, label in data.items():
        if not isinstance(label, str) or not label.strip():
            raise ParselError(f"{sidecar}: label of part {name!r} must be a non-empty string, got {label!r}")
        labels[str(name)] = label.strip()
    return labels


def resolve_labels(names: Iterable[str], overrides: Mapping[str, str] | None = None, source: str = "<labels>",
                   defaults: Mapping[str, str] | None = None) -> dict[str, str]:
    """Label per part name: the override where given, else ``defaults`` or :func:`label_of`.

    An override naming a part the shape does not have is an error, since it is almost
    always a typo that would otherwise silently leave a part mislabelled.
    """
    names = list(names)
    overrides = dict(overrides or {})
    defaults = dict(defaults or {})
    unknown = sorted(set(overrides) - set(names), key=natural_key)
    if unknown:
        known = sorted(names, key=natural_key)
        listed = ", ".join(known[:12]) + (f", ... ({len(known)} in all)" if len(known) > 12 else "")
        raise ParselError(f"{source}: labels file names unknown part(s) {', '.join(map(repr, unknown))} "
                          f"(parts: {listed})")
    return {name: overrides.get(name) or defaults.get(name) or label_of(name) for name in names}
