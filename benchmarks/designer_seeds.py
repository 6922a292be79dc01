"""Seed edits a designer would ask for, written by rule from a shape's part labels.

Used by ``bench_aep.py`` (and usable on any labelled shape): for every shape it gives
the edits people ask of chairs, tables and storage furniture — widen or deepen the seat
or top, lengthen or thicken the legs, raise or tilt the back, scale the top in 2D, move
a shelf, add shelves — each as a seed program in the text form with the relations the
request itself breaks (moving one shelf of an evenly spaced row breaks the row; tilting a
back that stands on the floor lifts it off). The rules only read labels, boxes and the
detected groups and floor contacts, so they cover every val-split shape.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.part import Part

X, Y, Z = (1, 0, 0), (0, 1, 0), (0, 0, 1)


CATEGORIES = ("chair", "table", "storage")


def sample_programs(data: Path, count: int, seed: int = 0) -> list[Path]:
    """``count`` val-split ShapeAssembly programs spread evenly over the three categories."""
    rng = np.random.default_rng(seed)
    per = [count // 3 + (1 if i < count % 3 else 0) for i in range(3)]
    out = []
    for category, n in zip(CATEGORIES, per):
        ids = (data / "splits" / category / "val.txt").read_text().split()
        out += [data / category / f"{i}.txt" for i in rng.choice(ids, size=min(n, len(ids)), replace=False)]
    return out


def seed_of(seeds: list[DesignerSeed], *prefixes: str) -> DesignerSeed:
    """The first seed whose kind starts with one of ``prefixes`` (in their order), else the first seed."""
    for prefix in prefixes:
        for seed in seeds:
            if seed.kind.startswith(prefix):
                return seed
    return seeds[0]


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


def designer_seeds(shape: ShapeGraph, centre: float | None = None) -> list[DesignerSeed]:
    """The designer requests that apply to ``shape``, by its category and part labels.

    Amounts are ``k*x``: the rest shape at the lower end of the range, so a slider only
    widens, raises, ... With ``centre`` they are ``k*(x - centre)``: the rest shape at
    ``x = centre`` inside the range, and the slider goes both ways (narrower and wider),
    which is what fitting to other shapes needs.
    """
    category = shape.metadata.get("category", "")

    def a(k: float) -> str:
        return f"{k}*x" if centre is None else f"{k}*(x - {centre})"

    out: list[DesignerSeed] = []
    flat = _largest(_with_label(shape, "seat") if category == "chair" else _with_label(shape, "top"))
    if flat is None:
        flat = _largest([p for p in shape.parts.values() if p.label not in ("leg",)]) or _largest(
            list(shape.parts.values()))
    name = "seat" if category == "chair" else "top"
    c = flat.hexahedron.center
    out.append(DesignerSeed(f"widen-{name}", f"scale_1d({flat.id!r}, origin={_point(c)}, dir={X}, amount={a(0.5)})"))
    out.append(DesignerSeed(f"deepen-{name}", f"scale_1d({flat.id!r}, origin={_point(c)}, dir={Z}, amount={a(0.4)})"))
    if category != "chair":
        out.append(DesignerSeed(f"scale-{name}-2d",
                                f"scale_2d({flat.id!r}, origin={_point(c)}, normal={Y}, amount={a(0.4)})"))
    legs = _with_label(shape, "leg")
    if legs:
        leg = legs[0]
        out.append(DesignerSeed("lengthen-legs", f"scale_1d({leg.id!r}, origin={_point(_bottom_centre(leg))}, "
                                                 f"dir={Y}, amount={a(0.5)})"))
        out.append(DesignerSeed("thicken-legs", f"scale_2d({leg.id!r}, origin={_point(leg.hexahedron.center)}, "
                                                f"normal={Y}, amount={a(0.5)})"))
    if category == "chair":
        back = _largest(_with_label(shape, "back"))
        if back is not None:
            bottom = _bottom_centre(back)
            out.append(DesignerSeed("raise-back", f"scale_1d({back.id!r}, origin={_point(bottom)}, dir={Y}, "
                                                  f"amount={a(0.4)})"))
            # Recline: turn about the bottom edge on the seat's side, the top away from the
            # seat (a back behind the seat, at -z, turns about -x: its top goes to -z).
            behind = back.hexahedron.center[2] < c[2]
            sign = -1.0 if behind else 1.0
            zs = back.hexahedron.corners[:, 2]
            edge = np.array([bottom[0], bottom[1], zs.max() if behind else zs.min()])
            # A back that stands on the floor (a sofa's) leaves it when tilted: the request
            # itself breaks that contact, as moving one shelf breaks its row.
            floor = tuple(rid for rid, r in sorted(shape.relations.items())
                          if r.kind == "ground" and tuple(r.members) == (back.id,))
            out.append(DesignerSeed("tilt-back", f"rotate({back.id!r}, origin={_point(edge)}, "
                                                 f"axis=({sign}, 0.0, 0.0), amount={a(0.25)})", floor))
    if category == "storage":
        sides = _with_label(shape, "side", "body")
        if sides:
            side = _largest(sides)
            out.append(DesignerSeed("raise-storage", f"scale_1d({side.id!r}, origin={_point(_bottom_centre(side))}, "
                                                     f"dir={Y}, amount={a(0.3)})"))
    shelves = _with_label(shape, "shelf")
    if shelves:
        shelf = shelves[len(shelves) // 2]
        groups = _group_of(shape, shelf)
        out.append(DesignerSeed("move-shelf", f"translate({shelf.id!r}, dir={Y}, amount={a(0.05)})", groups))
        for group in groups:
            relation = shape.relations[group]
            if relation.kind == "translation":
                out.append(DesignerSeed("add-shelves", f"change_count({group!r}, amount={a(2)}, mode='bottom_up')"))
    return out
