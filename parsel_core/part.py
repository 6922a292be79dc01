"""Parts: a labelled hexahedron, optionally carrying the mesh it is the cage of."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from parsel_core.hexahedron import Hexahedron


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
        if not isinstance(self.hexahedron, Hexahedron):
            object.__setattr__(self, "hexahedron", Hexahedron(self.hexahedron))
        if self.name is None:
            object.__setattr__(self, "name", self.id)
