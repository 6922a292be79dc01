"""Running the detectors: one per relation family, and all of them at once.

The symmetry families are resolved jointly (a reflection must not pair two members of a
group), so each symmetry detector runs the joint analysis and returns its own family;
a small cache keyed by the shape's content makes running the five detectors one after
the other (as ``parsel_core.detection`` does) cost one analysis.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import RelationDetector
from parsel_core.relations import Relation
from parsel_relations.contact import attachments, ground_contacts
from parsel_relations.symmetry import Symmetries, detect_symmetries
from parsel_relations.table import PartTable

FAMILIES = ("reflection", "translation", "rotation", "attachment", "ground")
#: Used when parsel_core has no configured value (``relation_tolerance`` in parsel.toml).
DEFAULT_RELATIVE_TOLERANCE = 0.01
_CACHE_SIZE = 8


def relative_tolerance() -> float:
    """The configured tolerance as a fraction of the shape's size (parsel.toml ``relation_tolerance``)."""
    try:
        from parsel_core.detection import relative_tolerance as configured
    except ImportError:
        return DEFAULT_RELATIVE_TOLERANCE
    return float(configured())


def absolute_tolerance(shape: ShapeGraph, relative: float | None = None) -> float:
    """``relative`` (default: the configured one) times the shape's bounding-box diagonal."""
    relative = relative_tolerance() if relative is None else relative
    return relative * shape.size


@dataclass(frozen=True)
class _Key:
    ids: tuple[str, ...]
    labels: tuple[str, ...]
    corners: bytes
    tolerance: float
    family: str


_cache: OrderedDict[_Key, tuple[Relation, ...]] = OrderedDict()


def _cached(table: PartTable, tolerance: float, family: str, compute: Callable[[], tuple[Relation, ...]]):
    key = _Key(table.ids, table.labels, np.ascontiguousarray(table.corners).tobytes(), float(tolerance), family)
    if key in _cache:
        _cache.move_to_end(key)
        return _cache[key]
    value = compute()
    _cache[key] = value
    while len(_cache) > _CACHE_SIZE:
        _cache.popitem(last=False)
    return value


def _symmetries(table: PartTable, tolerance: float) -> Symmetries:
    found = _cached(table, tolerance, "symmetry", lambda: (detect_symmetries(table, tolerance),))
    return found[0]


def detect_family(shape: ShapeGraph, family: str, tolerance: float, table: PartTable | None = None) -> list[Relation]:
    """Relations of one family (``reflection``, ``translation``, ``rotation``, ``attachment``, ``ground``)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown relation family {family!r} (known: {', '.join(FAMILIES)})")
    table = PartTable.from_shape(shape) if table is None else table
    if not len(table):
        return []
    if family in ("reflection", "translation", "rotation"):
        found = _symmetries(table, tolerance)
        return list({"reflection": found.reflections, "translation": found.translations,
                     "rotation": found.rotations}[family])
    size = shape.size
    if family == "attachment":
        return list(_cached(table, tolerance, family, lambda: tuple(attachments(table, tolerance, size))))
    return list(_cached(table, tolerance, family, lambda: tuple(ground_contacts(table, tolerance, size))))


def detect_all(shape: ShapeGraph, tolerance: float | None = None,
               families: Iterable[str] | None = None) -> list[Relation]:
    """Relations of the given families (default: all), in family order then id order.

    ``families`` only selects what is returned: symmetry conflicts are always resolved
    against every symmetry family, so a family's relations do not depend on the others
    being asked for.
    """
    tolerance = absolute_tolerance(shape) if tolerance is None else float(tolerance)
    wanted = FAMILIES if families is None else tuple(families)
    table = PartTable.from_shape(shape)
    relations: list[Relation] = []
    for family in FAMILIES:
        if family in wanted:
            relations.extend(detect_family(shape, family, tolerance, table))
    unknown = set(wanted) - set(FAMILIES)
    if unknown:
        raise ValueError(f"unknown relation families {sorted(unknown)} (known: {', '.join(FAMILIES)})")
    return relations


def detect_relations(shape: ShapeGraph, tolerance: float | None = None,
                     families: Iterable[str] | None = None) -> ShapeGraph:
    """The shape with the detected relations in place of its own.

    ``tolerance`` is absolute (default: the configured relative tolerance, 0.01, times
    ``shape.size``); ``families`` limits which families are detected. Pure: the input
    shape is not changed.
    """
    return shape.with_relations(detect_all(shape, tolerance, families))


class FamilyDetector(RelationDetector):
    """A ``RelationDetector`` for one family; its ``name`` is the family's."""

    name = ""

    def detect(self, shape: ShapeGraph, tolerance: float) -> list[Relation]:
        return detect_family(shape, self.name, float(tolerance))

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class ReflectionDetector(FamilyDetector):
    """Mirror pairs about axis-aligned planes."""

    name = "reflection"


class TranslationDetector(FamilyDetector):
    """Evenly stepped rows of more than 2 copies."""

    name = "translation"


class RotationDetector(FamilyDetector):
    """Rings and arcs of more than 2 copies about an axis-aligned axis."""

    name = "rotation"


class AttachmentDetector(FamilyDetector):
    """Touching parts, with point, line, face or volume contacts."""

    name = "attachment"


class GroundDetector(FamilyDetector):
    """Parts standing on the shape's floor."""

    name = "ground"


def detectors() -> list[FamilyDetector]:
    """One detector per family, in family order."""
    return [ReflectionDetector(), TranslationDetector(), RotationDetector(), AttachmentDetector(), GroundDetector()]
