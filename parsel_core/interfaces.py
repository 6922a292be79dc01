"""Interfaces that plugins implement, one per kind of contribution (see hookspecs.py).

They are small abstract classes rather than protocols so that a plugin author gets a
clear ``TypeError`` at registration time when a method is missing.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parsel_core.graph import ShapeGraph
from parsel_core.program import Evaluation, Program
from parsel_core.relations import Relation


class ShapeLoader(ABC):
    """Reads a file (or directory) into a :class:`ShapeGraph`."""

    name: str = ""
    #: Lower-case suffixes this loader reads, e.g. ``(".glb", ".gltf")``.
    extensions: tuple[str, ...] = ()

    def can_load(self, path: Path) -> bool:
        """Whether this loader reads ``path``; by default, by suffix."""
        name = path.name.lower()
        return any(name.endswith(ext) for ext in self.extensions)

    @abstractmethod
    def load(self, path: Path) -> ShapeGraph:
        """Parts (and any relations the file declares); raise ``ParselError`` naming the file."""


class RelationDetector(ABC):
    """Finds relations of one family in a shape (reference section 2)."""

    name: str = ""

    @abstractmethod
    def detect(self, shape: ShapeGraph, tolerance: float) -> list[Relation]:
        """Relations found; ``tolerance`` is absolute (a fraction of ``shape.size``)."""


@dataclass
class Completion:
    """One reply of a language model, with accounting."""

    text: str
    prompt_tokens: int = 0
    completion_tokens: int = 0
    cost: float = 0.0
    meta: dict[str, Any] = field(default_factory=dict)


class LLMProvider(ABC):
    """Answers prompts: a hosted model, a local server, recorded replies or rules."""

    name: str = ""

    @abstractmethod
    def complete(self, prompt: str, *, task: str, samples: int = 1, **options: Any) -> list[Completion]:
        """``samples`` independent replies to ``prompt`` for ``task`` (``seed_edit``, ...)."""


class Deformer(ABC):
    """Moves part meshes with their edited hexahedra."""

    name: str = ""

    @abstractmethod
    def deform(self, shape: ShapeGraph, evaluation: Evaluation) -> Mapping[str, Any]:
        """Deformed mesh per part id (and per instance for groups whose count changed)."""


class Exporter(ABC):
    """Writes an edited shape to a file format."""

    name: str = ""
    #: Lower-case suffixes this exporter writes, e.g. ``(".glb",)``.
    extensions: tuple[str, ...] = ()

    @abstractmethod
    def export(self, shape: ShapeGraph, evaluation: Evaluation, path: Path) -> None:
        """Write the shape as edited; write to a temporary file and rename (no partial output)."""


@dataclass
class SolveRequest:
    """What a solver gets: the shape, a seed program, hints and relations allowed to break."""

    shape: ShapeGraph
    seed: Program
    hints: Mapping[str, str] = field(default_factory=dict)
    breaks: Sequence[str] = ()
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass
class SolveResult:
    """A solver's program with what it learned on the way: relations it could not keep
    (``rejected``) and statistics (times per stage, candidate counts) for the report."""

    program: Program
    rejected: list[str] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)


class Solver(ABC):
    """Turns a seed edit into a complete program (edit propagation)."""

    name: str = ""

    @abstractmethod
    def solve(self, request: SolveRequest) -> Program:
        """A program that contains the seed edit and keeps as many relations as it can."""

    def run(self, request: SolveRequest) -> SolveResult:
        """``solve`` with statistics; solvers that gather them override this."""
        return SolveResult(self.solve(request))
