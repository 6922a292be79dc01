"""Parts: a labelled hexahedron, optionally carrying the mesh it is the cage of."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from parsel_core.errors import ParselError
from parsel_core.hexahedron import Hexahedron

#: Longest part id or label: names travel into prompts, pages and program lines.
MAX_NAME_CHARS = 200


def check_name(text: object, where: str) -> None:
    """A part id or label is one line of printable text (no newline, tab or other control
    character), so it can never start a new line in a prompt, a program or a page."""
    if not isinstance(text, str) or not text:
        raise ParselError(f"{where} must be a non-empty string, got {text!r}")
    if len(text) > MAX_NAME_CHARS:
        raise ParselError(f"{where} has {len(text)} characters (at most {MAX_NAME_CHARS})")
    bad = next((c for c in text if not c.isprintable()), None)
    if bad is not None:
        raise ParselError(f"{where} {text[:60]!r} holds the control character {bad!r}; names are one line of "
                          "printable text")


@dataclass(frozen=True)
class Part:
    """A leaf part of a shape (or the virtual parent of a symmetry group).

    ``label`` is the semantic label (``leg``); ``name`` is the name the part had in its
    file (``leg.003``), kept for export; ``mesh`` is whatever the loader produced
    (a ``trimesh.Trimesh`` for mesh files) and is never inspected by the core.
    """

    id: str
    label: str
    hexahedron: Hexahedron
    name: str | None = None
    mesh: Any = field(default=None, compare=False, repr=False)
    virtual: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise ValueError(f"part id must be a non-empty string, got {self.id!r}")
        for key in ("id", "label"):
            check_name(getattr(self, key), f"part {self.id[:60]!r}: {key}")
        if not isinstance(self.hexahedron, Hexahedron):
            object.__setattr__(self, "hexahedron", Hexahedron(self.hexahedron))
        if self.name is None:
            object.__setattr__(self, "name", self.id)
