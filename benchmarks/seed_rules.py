"""Rule-based designer edits for the round-trip and fitting benchmarks, chosen from part labels.

A designer widens the seat (chair), the top (table) or the body/top (storage) about its
centre, or lengthens the legs from their bottom; shapes without such parts get the
same edit on their largest part.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

CATEGORIES = ("chair", "table", "storage")
WIDEN = {"chair": ("seat",), "table": ("top",), "storage": ("body", "top")}


def sample_programs(data: Path, count: int, seed: int = 0) -> list[Path]:
    """``count`` val-split programs spread evenly over the three categories."""
    rng = np.random.default_rng(seed)
    per = [count // 3 + (1 if i < count % 3 else 0) for i in range(3)]
    out = []
    for category, n in zip(CATEGORIES, per):
        ids = (data / "splits" / category / "val.txt").read_text().split()
        out += [data / category / f"{i}.txt" for i in rng.choice(ids, size=n, replace=False)]
    return out


def _largest(parts):
    return max(parts, key=lambda p: (float(np.prod(p.hexahedron.extents)), p.id))


def widen_seed(shape, amount: str = "x") -> str:
    """Scale the seat/top/body along x about its centre."""
    category = shape.metadata.get("category")
    wanted = WIDEN.get(category, ())
    parts = sorted(shape.parts.values(), key=lambda p: p.id)
    chosen = [p for p in parts if p.label in wanted] or parts
    part = _largest(chosen)
    c = [float(v) for v in part.hexahedron.center]
    return f"scale_1d({part.id!r}, origin=({c[0]!r}, {c[1]!r}, {c[2]!r}), dir=(1, 0, 0), amount={amount})"


def lengthen_seed(shape, amount: str = "0.5 * x") -> str:
    """Scale a leg (else the largest part) along y from its bottom."""
    parts = sorted(shape.parts.values(), key=lambda p: p.id)
    legs = [p for p in parts if p.label == "leg"]
    part = legs[0] if legs else _largest(parts)
    c = [float(v) for v in part.hexahedron.center]
    bottom = float(part.hexahedron.corners[:, 1].min())
    return f"scale_1d({part.id!r}, origin=({c[0]!r}, {bottom!r}, {c[2]!r}), dir=(0, 1, 0), amount={amount})"


def designer_seed(shape, index: int) -> str:
    """Alternate the two edits over a sample so both are measured."""
    return widen_seed(shape) if index % 2 == 0 else lengthen_seed(shape)
