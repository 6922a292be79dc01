"""Running the installed relation detectors over a shape (reference section 2).

Detectors are plugins (``parsel_relation_detectors``); this module only runs them in
order, with a tolerance relative to the shape's size, and gives the shape their
relations. Each detector is responsible for its own family's rules.
"""

from __future__ import annotations

from collections.abc import Iterable

from parsel_core.graph import ShapeGraph

#: Default tolerance as a fraction of the shape's bounding-box diagonal.
DEFAULT_RELATIVE_TOLERANCE = 0.01


def relative_tolerance() -> float:
    """The configured relative tolerance (``relation_tolerance`` in the ``[parsel]`` table of parsel.toml)."""
    import math

    from parsel_core.config import config_path, load_settings
    from parsel_core.errors import ParselError

    value = load_settings().get("relation_tolerance", DEFAULT_RELATIVE_TOLERANCE)
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not math.isfinite(number) or number <= 0:
        raise ParselError(f"{config_path()}: [parsel] relation_tolerance must be a positive number "
                          f"(a fraction of the shape's diagonal), got {value!r}")
    return number


def detect_relations(shape: ShapeGraph, tolerance: float | None = None,
                     families: Iterable[str] | None = None) -> ShapeGraph:
    """The shape with every installed detector's relations added to its own.

    ``tolerance`` is absolute; by default it is the relative tolerance times
    ``shape.size``. ``families`` limits which detectors (by name) run.
    """
    from parsel_core.plugins import relation_detectors

    tolerance = relative_tolerance() * shape.size if tolerance is None else tolerance
    wanted = None if families is None else set(families)
    relations = list(shape.relations.values())
    taken = set(shape.relations)
    for name, detector in relation_detectors().items():
        if wanted is not None and name not in wanted:
            continue
        for relation in detector.detect(shape, tolerance):
            if relation.id in taken:
                raise ValueError(f"relation detector {name!r} returned duplicate relation id {relation.id!r}")
            taken.add(relation.id)
            relations.append(relation)
    return shape.with_relations(relations)
