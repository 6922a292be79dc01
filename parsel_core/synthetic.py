"""Synthetic large assemblies, for measuring how edit propagation scales with parts and relations.

Real assets have up to a few hundred parts (PartNet); the bundled ones have 6 to 13.
These generators build furniture of any size from axis-aligned boxes with every
relation written by hand from exact contacts (as :mod:`parsel_core.examples` does for
``tiny_table``), so they load instantly, hold exactly at rest and grow in a known way:

* :func:`bookcase` ``(n)``: two side panels, a back panel and ``n`` boards stacked between
  them in one translation group; ``n + 3`` parts, ``3n + 5`` relations.
* :func:`stadium` ``(n)``: a platform and a row of ``n`` chairs, each a seat and a back;
  seats and backs are two translation groups; ``2n + 1`` parts, ``2n + 3`` relations.
* :func:`long_table` ``(n)``: a top on ``n`` legs in two mirrored rows (``n`` even), each
  row a translation group; ``n + 1`` parts, ``2n + n/2 + 2`` relations.

:data:`GENERATORS` maps the names to ``(generator, parts -> n)`` so benchmarks can ask for
a part count; :data:`SEEDS` gives each a seed edit that moves most of the shape.
"""

from __future__ import annotations

from collections.abc import Callable

from parsel_core.examples import attachment, box, ground, reflection
from parsel_core.graph import ShapeGraph
from parsel_core.part import Part
from parsel_core.relations import TranslationSymmetry


def _row(rid: str, parts: list[Part], step: tuple[float, float, float]) -> TranslationSymmetry:
    return TranslationSymmetry(rid, tuple(p.id for p in parts), step=step,
                               correspondence=tuple(tuple(range(8)) for _ in parts))


def _count(n: int, least: int, what: str) -> None:
    if not isinstance(n, int) or n < least:
        raise ValueError(f"{what} needs n >= {least}, got {n!r}")


def bookcase(n: int) -> ShapeGraph:
    """Two sides, a back and ``n`` boards 0.3 apart: boards touch both sides and the back."""
    _count(n, 2, "bookcase")
    pitch, thick = 0.3, 0.02
    height = n * pitch + thick
    left = Part("side_0", "side", box((-0.52, 0.0, -0.15), (-0.5, height, 0.15)))
    right = Part("side_1", "side", box((0.5, 0.0, -0.15), (0.52, height, 0.15)))
    back = Part("back", "back", box((-0.5, 0.0, -0.17), (0.5, height, -0.15)))
    boards = [Part(f"board_{i}", "board", box((-0.5, i * pitch + 0.1, -0.15), (0.5, i * pitch + 0.1 + thick, 0.15)))
              for i in range(n)]
    relations = [reflection("reflect_sides", left, right, (0, 0, 0), (1, 0, 0)),
                 _row("boards", boards, (0.0, pitch, 0.0)),
                 ground("ground_side_0", left), ground("ground_side_1", right), ground("ground_back", back)]
    for board in boards:  # a board's end meets a side's inner face; its back edge meets the back's face
        relations += [attachment(f"attach_{board.id}_{side.id}", board, side, "face") for side in (left, right)]
        relations.append(attachment(f"attach_{board.id}_back", board, back, "face"))
    return ShapeGraph([left, right, back, *boards], relations, name=f"bookcase_{n}", source=f"synthetic:bookcase:{n}")


def stadium(n: int) -> ShapeGraph:
    """A platform with ``n`` chairs 0.6 apart along x; each seat sits on it, each back on its seat."""
    _count(n, 2, "stadium")
    pitch = 0.6
    span = n * pitch
    platform = Part("platform", "platform", box((0.0, 0.0, -0.4), (span, 0.2, 0.4)))
    seats = [Part(f"seat_{i}", "seat", box((i * pitch + 0.05, 0.2, -0.25), (i * pitch + 0.55, 0.45, 0.25)))
             for i in range(n)]
    backs = [Part(f"back_{i}", "back", box((i * pitch + 0.05, 0.45, -0.25), (i * pitch + 0.55, 0.95, -0.2)))
             for i in range(n)]
    relations = [ground("ground_platform", platform), _row("seats", seats, (pitch, 0.0, 0.0)),
                 _row("backs", backs, (pitch, 0.0, 0.0))]
    relations += [attachment(f"attach_{s.id}_platform", s, platform, "face") for s in seats]
    relations += [attachment(f"attach_{b.id}_{s.id}", b, s, "face") for b, s in zip(backs, seats)]
    return ShapeGraph([platform, *seats, *backs], relations, name=f"stadium_{n}", source=f"synthetic:stadium:{n}")


def long_table(n: int) -> ShapeGraph:
    """A top on ``n`` legs: two rows of ``n / 2`` along x, mirrored front to back."""
    _count(n, 4, "long_table")
    if n % 2:
        raise ValueError(f"long_table needs an even number of legs, got {n}")
    per_row, pitch = n // 2, 0.5
    length = (per_row - 1) * pitch + 0.2
    top = Part("top", "top", box((-0.1, 0.7, -0.4), (length - 0.1, 0.75, 0.4)))
    rows = [[Part(f"leg_{side}_{i}", "leg",
                  box((i * pitch - 0.025, 0.0, z - 0.025), (i * pitch + 0.025, 0.7, z + 0.025)))
             for i in range(per_row)] for side, z in (("back", -0.3), ("front", 0.3))]
    relations = [_row("legs_back", rows[0], (pitch, 0.0, 0.0)), _row("legs_front", rows[1], (pitch, 0.0, 0.0))]
    relations += [reflection(f"reflect_{a.id}", a, b, (0, 0, 0), (0, 0, 1)) for a, b in zip(*rows)]
    legs = rows[0] + rows[1]
    relations += [attachment(f"attach_top_{leg.id}", top, leg) for leg in legs]
    relations += [ground(f"ground_{leg.id}", leg) for leg in legs]
    return ShapeGraph([top, *legs], relations, name=f"long_table_{n}", source=f"synthetic:long_table:{n}")


#: name -> (generator, the ``n`` that gives about ``parts`` parts)
GENERATORS: dict[str, tuple[Callable[[int], ShapeGraph], Callable[[int], int]]] = {
    "bookcase": (bookcase, lambda parts: max(2, parts - 3)),
    "stadium": (stadium, lambda parts: max(2, (parts - 1) // 2)),
    "long_table": (long_table, lambda parts: max(4, (parts - 1) // 2 * 2)),
}

#: name -> a seed edit (program text) that widens the shape, moving most of its parts.
SEEDS: dict[str, str] = {
    "bookcase": "scale_1d(back, origin=(0, 0, -0.16), dir=(1, 0, 0), amount=x)",
    "stadium": "scale_1d(platform, origin=(0, 0, 0), dir=(0, 1, 0), amount=x)",
    "long_table": "scale_1d(top, origin=(0, 0.725, 0), dir=(0, 0, 1), amount=x)",
}


def assembly(name: str, parts: int) -> ShapeGraph:
    """The ``name`` assembly with about ``parts`` parts."""
    if name not in GENERATORS:
        raise ValueError(f"unknown synthetic assembly {name!r} (known: {', '.join(GENERATORS)})")
    generator, size = GENERATORS[name]
    return generator(size(parts))
