"""Seed edits a designer would ask for, written by rule from a shape's part labels.

Used by ``bench_aep.py`` (and usable on any labelled shape): for every shape it gives
the edits people ask of chairs, tables and storage furniture — widen or deepen the seat
or top, lengthen or thicken the legs, raise or tilt the back, scale the top in 2D, move
a shelf, add shelves — each as a seed program in the text form with the relations the
request itself breaks (moving one shelf of an evenly spaced row breaks the row). The
rules only read labels and boxes, so they cover every val-split shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.part import Part

X, Y, Z = (1, 0, 0), (0, 1, 0), (0, 0, 1)


@dataclass(frozen=True)
class DesignerSeed:
    kind: str                   # e.g. "widen-seat"
    seed: str                   # the seed program's text form
    breaks: tuple[str, ...] = ()


def _point(p) -> str:
    return "(" + ", ".join(repr(round(float(c), 9) + 0.0) for c in p) + ")"


def _volume(part: Part) -> float:
    return float(np.prod(part.hexahedron.extents))


def _largest(parts: list[Part]) -> Part | None:
    return max(parts, key=lambda p: (_volume(p), p.id), default=None)


def _bottom_centre(part: Part) -> np.ndarray:
    corners = part.hexahedron.corners
    centre = corners.mean(axis=0)
    return np.array([centre[0], corners[:, 1].min(), centre[2]])


def _with_label(shape: ShapeGraph, *labels: str) -> list[Part]:
    return sorted((p for p in shape.parts.values() if p.label in labels), key=lambda p: p.id)


def _group_of(shape: ShapeGraph, part: Part) -> tuple[str, ...]:
    return tuple(shape.groups_of(part.id))


def designer_seeds(shape: ShapeGraph) -> list[DesignerSeed]:
    """The designer requests that apply to ``shape``, by its category and part labels."""
    category = shape.metadata.get("category", "")
    out: list[DesignerSeed] = []
    flat = _largest(_with_label(shape, "seat") if category == "chair" else _with_label(shape, "top"))
    if flat is None:
        flat = _largest([p for p in shape.parts.values() if p.label not in ("leg",)]) or _largest(
            list(shape.parts.values()))
    name = "seat" if category == "chair" else "top"
    c = flat.hexahedron.center
    out.append(DesignerSeed(f"widen-{name}", f"scale_1d({flat.id!r}, origin={_point(c)}, dir={X}, amount=0.5*x)"))
    out.append(DesignerSeed(f"deepen-{name}", f"scale_1d({flat.id!r}, origin={_point(c)}, dir={Z}, amount=0.4*x)"))
    if category != "chair":
        out.append(DesignerSeed(f"scale-{name}-2d",
                                f"scale_2d({flat.id!r}, origin={_point(c)}, normal={Y}, amount=0.4*x)"))
    legs = _with_label(shape, "leg")
    if legs:
        leg = legs[0]
        out.append(DesignerSeed("lengthen-legs", f"scale_1d({leg.id!r}, origin={_point(_bottom_centre(leg))}, "
                                                 f"dir={Y}, amount=0.5*x)"))
        out.append(DesignerSeed("thicken-legs", f"scale_2d({leg.id!r}, origin={_point(leg.hexahedron.center)}, "
                                                f"normal={Y}, amount=0.5*x)"))
    if category == "chair":
        back = _largest(_with_label(shape, "back"))
        if back is not None:
            bottom = _bottom_centre(back)
            out.append(DesignerSeed("raise-back", f"scale_1d({back.id!r}, origin={_point(bottom)}, dir={Y}, "
                                                  f"amount=0.4*x)"))
            # Tilt about the bottom edge, backwards (the back of a chair faces -z here or +z:
            # the axis follows from where the back sits relative to the seat).
            sign = 1.0 if back.hexahedron.center[2] < c[2] else -1.0
            out.append(DesignerSeed("tilt-back", f"rotate({back.id!r}, origin={_point(bottom)}, "
                                                 f"axis=({sign}, 0.0, 0.0), amount=0.25*x)"))
    if category == "storage":
        sides = _with_label(shape, "side", "body")
        if sides:
            side = _largest(sides)
            out.append(DesignerSeed("raise-storage", f"scale_1d({side.id!r}, origin={_point(_bottom_centre(side))}, "
                                                     f"dir={Y}, amount=0.3*x)"))
    shelves = _with_label(shape, "shelf")
    if shelves:
        shelf = shelves[len(shelves) // 2]
        groups = _group_of(shape, shelf)
        out.append(DesignerSeed("move-shelf", f"translate({shelf.id!r}, dir={Y}, amount=0.05*x)", groups))
        for group in groups:
            relation = shape.relations[group]
            if relation.kind == "translation":
                out.append(DesignerSeed("add-shelves", f"change_count({group!r}, amount=2*x, mode='bottom_up')"))
    return out
