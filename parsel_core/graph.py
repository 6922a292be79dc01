"""The shape graph G(N, L): parts as nodes, relations as edges (reference section 1).

There is no part hierarchy, except one *virtual parent part* per translation or
rotation symmetry group: a hexahedron that contains all the group's instances, so the
group can be edited as a whole and its count or spacing changed.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from functools import cached_property
from typing import Any

import numpy as np

from parsel_core.errors import ParselError, UnknownPartError
from parsel_core.hexahedron import CORNER_BITS, Hexahedron
from parsel_core.part import Part
from parsel_core.relations import Relation, RotationSymmetry, TranslationSymmetry, relation_from_dict

SHAPE_FORMAT = "parsel.shape"
SHAPE_VERSION = 1
GROUP_KINDS = (TranslationSymmetry.kind, RotationSymmetry.kind)


def enclosing_hexahedron(points: np.ndarray, axes: np.ndarray) -> Hexahedron:
    """The smallest box with the given (orthonormal rows) axes containing ``points``."""
    local = points @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    return Hexahedron((lo + CORNER_BITS * (hi - lo)) @ axes)


def orthonormal_axes(hexahedron: Hexahedron) -> np.ndarray:
    """The rotation nearest to the hexahedron's axes (polar decomposition), as rows."""
    u, _, vt = np.linalg.svd(hexahedron.axis_vectors)
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:
        rotation = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    return rotation


def group_parent_hexahedron(relation: Relation, parts: Mapping[str, Part]) -> Hexahedron:
    """The virtual parent's box: all members' corners, in the first member's frame.

    For the usual group of copies stepped along one of their own axes this is the
    tight box around the row, with u, v, w matching the members'.
    """
    points = np.concatenate([parts[m].hexahedron.corners for m in relation.members])
    return enclosing_hexahedron(points, orthonormal_axes(parts[relation.members[0]].hexahedron))


class ShapeGraph:
    """Parts and relations of one shape, with a networkx multigraph over them.

    Built once from its parts and relations (validated), then read. Group relations
    (translation, rotation) get a virtual parent part with the relation's id, joined to
    each member by a ``contains`` edge. The edges are kept as plain lists; the networkx
    view (:attr:`graph`) is built on first use, so loading a shape does not import networkx.
    """

    def __init__(self, parts: Iterable[Part], relations: Iterable[Relation] = (), name: str = "shape",
                 source: str | None = None, metadata: Mapping[str, Any] | None = None) -> None:
        self.name = name
        self.source = source
        self.metadata = dict(metadata or {})
        self.parts: dict[str, Part] = {}
        parts = list(parts)
        from parsel_core.config import check_limit

        check_limit("max_parts", f"shape {name!r}: parts", sum(not p.virtual for p in parts))  # before detection
        for part in parts:
            if part.virtual:
                continue
            if part.id in self.parts:
                raise ParselError(f"shape {name!r}: duplicate part id {part.id!r}")
            self.parts[part.id] = part
        self.relations: dict[str, Relation] = {}
        self.virtual_parents: dict[str, Part] = {}
        self._nodes: list[tuple[str, dict[str, Any]]] = [(pid, {}) for pid in self.parts]
        self._edges: list[tuple[str, str, str, dict[str, Any]]] = []  # (a, b, key, attributes)
        self._adjacent: dict[str, set[str]] = {pid: set() for pid in self.parts}
        for relation in relations:
            self._add_relation(relation)

    def _add_relation(self, relation: Relation) -> None:
        if relation.id in self.relations:
            raise ParselError(f"shape {self.name!r}: duplicate relation id {relation.id!r}")
        for member in relation.members:
            if member not in self.parts:
                raise UnknownPartError(f"relation {relation.id!r} names unknown part {member!r}")
        # Every relation holds exactly at rest: its residual is its drift from the rest shape.
        relation = relation.anchored({m: self.parts[m].hexahedron.corners for m in relation.members})
        self.relations[relation.id] = relation
        if relation.kind in GROUP_KINDS:
            if relation.id in self.parts:
                raise ParselError(f"group {relation.id!r} has the same id as a part")
            parent = Part(relation.id, label=f"{self.parts[relation.members[0]].label}_group",
                          hexahedron=group_parent_hexahedron(relation, self.parts), virtual=True)
            self.virtual_parents[relation.id] = parent
            self._nodes.append((relation.id, {"virtual": True}))
            self._adjacent[relation.id] = set()
            for member in relation.members:
                self._add_edge(relation.id, member, relation.id, "contains")
        else:
            members = relation.members
            if len(members) == 1:
                self._add_edge(members[0], members[0], relation.id, relation.kind)
            for i, a in enumerate(members):
                for b in members[i + 1:]:
                    self._add_edge(a, b, relation.id, relation.kind)

    def _add_edge(self, a: str, b: str, key: str, kind: str) -> None:
        self._edges.append((a, b, key, {"kind": kind}))
        self._adjacent[a].add(b)
        self._adjacent[b].add(a)

    @cached_property
    def graph(self):
        """The shape graph as a ``networkx.MultiGraph`` (nodes: parts and virtual parents;
        edges keyed by relation id, with the relation's ``kind``)."""
        import networkx as nx

        graph = nx.MultiGraph()
        graph.add_nodes_from(self._nodes)
        graph.add_edges_from(self._edges)
        return graph

    # -- reading -----------------------------------------------------------------------

    def part(self, part_id: str) -> Part:
        """A real or virtual part by id; raises :class:`UnknownPartError` naming it."""
        if part_id in self.parts:
            return self.parts[part_id]
        if part_id in self.virtual_parents:
            return self.virtual_parents[part_id]
        raise UnknownPartError(f"shape {self.name!r} has no part {part_id!r}")

    def relation(self, relation_id: str) -> Relation:
        try:
            return self.relations[relation_id]
        except KeyError:
            raise UnknownPartError(f"shape {self.name!r} has no relation {relation_id!r}") from None

    @property
    def all_parts(self) -> dict[str, Part]:
        """Real parts followed by virtual parents."""
        return {**self.parts, **self.virtual_parents}

    def rest_corners(self) -> dict[str, np.ndarray]:
        """Corners of every part (virtual parents included) before any edit."""
        return {pid: part.hexahedron.corners for pid, part in self.all_parts.items()}

    def relations_of(self, part_id: str) -> list[Relation]:
        """Relations a part is a member of, in id order."""
        self.part(part_id)
        return [r for r in self.relations.values() if part_id in r.members]

    def neighbours(self, part_id: str) -> list[str]:
        """Parts sharing a relation with this one (virtual parents included)."""
        self.part(part_id)
        return sorted(n for n in self._adjacent[part_id] if n != part_id)

    def groups_of(self, part_id: str) -> list[str]:
        """Ids of the translation / rotation groups a part belongs to."""
        return [r.id for r in self.relations_of(part_id) if r.kind in GROUP_KINDS]

    @property
    def size(self) -> float:
        """Diagonal of the shape's bounding box: the scale that tolerances are relative to."""
        points = np.concatenate([p.hexahedron.corners for p in self.parts.values()])
        return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))

    def with_relations(self, relations: Iterable[Relation]) -> ShapeGraph:
        """The same parts with another relation set (e.g. after dropping broken-on-purpose ones)."""
        return ShapeGraph(self.parts.values(), relations, self.name, self.source, self.metadata)

    # -- JSON form ---------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The ``parsel.shape`` JSON form (docs/formats.md): parts with corners, relations."""
        return {
            "format": SHAPE_FORMAT,
            "version": SHAPE_VERSION,
            "name": self.name,
            "parts": [
                {"id": p.id, "name": p.name, "label": p.label, "corners": p.hexahedron.corners.tolist()}
                for p in self.parts.values()
            ],
            "relations": [r.to_dict() for r in self.relations.values()],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<shape>") -> ShapeGraph:
        """Read the ``parsel.shape`` JSON form; errors name the source and the field."""
        if not isinstance(data, Mapping) or data.get("format") != SHAPE_FORMAT:
            raise ParselError(f"{source}: not a parsel shape (expected \"format\": \"{SHAPE_FORMAT}\")")
        if type(data.get("version")) is not int or data.get("version") != SHAPE_VERSION:  # true is not 1
            raise ParselError(f"{source}: unsupported shape version {data.get('version')!r} "
                              f"(this parsel reads {SHAPE_VERSION})")
        parts = []
        for i, item in enumerate(data.get("parts") or []):
            try:
                parts.append(Part(str(item["id"]), str(item.get("label", item["id"])),
                                  Hexahedron(item["corners"]), name=item.get("name")))
            except (KeyError, TypeError, ValueError, OverflowError) as exc:
                raise ParselError(f"{source}: parts[{i}]: {exc}") from None
        from parsel_core.config import limit

        bound = limit("max_magnitude")
        for i, part in enumerate(parts):
            if not np.all(np.abs(part.hexahedron.corners) <= bound):  # also refuses NaN
                raise ParselError(f"{source}: parts[{i}]: corners must be finite and within max_magnitude = {bound:g} "
                                  "(raise it with PARSEL_MAX_MAGNITUDE)")
        if not parts:
            raise ParselError(f"{source}: shape has no parts")
        relations = []
        for i, item in enumerate(data.get("relations") or []):
            try:
                relations.append(relation_from_dict(item, where=f"relations[{i}]"))
            except (KeyError, TypeError, ValueError) as exc:
                raise ParselError(f"{source}: relations[{i}]: {exc}") from None
        return cls(parts, relations, name=str(data.get("name", "shape")), source=source)

    def __repr__(self) -> str:
        return f"ShapeGraph({self.name!r}, {len(self.parts)} parts, {len(self.relations)} relations)"
