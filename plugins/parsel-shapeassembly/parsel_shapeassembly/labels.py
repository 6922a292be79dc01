"""A geometric labeller for ShapeAssembly shapes, which carry no semantic labels.

PartNet's chairs, tables and storage furniture are built from a few kinds of parts
whose roles follow from where they sit (y up, +z front): a chair's seat is the broad
flat part at mid height, its legs stand below it, its back rises behind it; a table's
top is the highest broad flat part; storage furniture has panels, shelves, doors and
drawers. The rules below assign those labels; a ``<program>.labels.json`` sidecar
(part name -> label) replaces them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

CATEGORIES = ("chair", "table", "storage")


def _boxes(corners: Mapping[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {name: (c.min(axis=0), c.max(axis=0)) for name, c in corners.items()}


def _flat(lo: np.ndarray, hi: np.ndarray) -> bool:
    size = hi - lo
    return size[1] < 0.5 * min(size[0], size[2])


def _area(lo: np.ndarray, hi: np.ndarray) -> float:
    size = hi - lo
    return float(size[0] * size[2])


def _footprint_overlap(lo: np.ndarray, hi: np.ndarray, other_lo: np.ndarray, other_hi: np.ndarray) -> float:
    """The share of the box's footprint (x, z) that lies over the other box's footprint."""
    width = np.clip(np.minimum(hi, other_hi) - np.maximum(lo, other_lo), 0.0, None)
    return float(width[0] * width[2]) / max(_area(lo, hi), 1e-300)


def label_chair(boxes) -> dict[str, str]:
    flat = [n for n, (lo, hi) in boxes.items() if _flat(lo, hi)]
    seat = max(flat or boxes, key=lambda n: (_area(*boxes[n]), n))
    seat_lo, seat_hi = boxes[seat]
    seat_centre = (seat_lo + seat_hi) / 2
    thickness = seat_hi[1] - seat_lo[1]
    out = {}
    for name, (lo, hi) in boxes.items():
        centre = (lo + hi) / 2
        if name == seat:
            out[name] = "seat"
        elif _flat(lo, hi) and lo[1] <= seat_hi[1] + thickness and hi[1] > seat_lo[1] and \
                _footprint_overlap(lo, hi, seat_lo, seat_hi) > 0.5 and _area(lo, hi) > 0.25 * _area(seat_lo, seat_hi):
            out[name] = "seat"  # a cushion lying on the seat, or a seat frame around it
        elif hi[1] <= seat_lo[1] + 0.25 * (seat_hi[1] - seat_lo[1]) + 1e-9 or centre[1] < seat_lo[1]:
            out[name] = "leg"
        elif centre[2] < seat_centre[2] - 0.25 * (seat_hi[2] - seat_lo[2]) and centre[1] > seat_hi[1]:
            out[name] = "back"
        elif centre[1] > seat_hi[1] and abs(centre[0] - seat_centre[0]) > 0.3 * (seat_hi[0] - seat_lo[0]):
            out[name] = "arm"
        elif centre[1] > seat_hi[1]:
            out[name] = "back"
        else:
            out[name] = "seat_support"
    return out


def label_table(boxes) -> dict[str, str]:
    flat = [n for n, (lo, hi) in boxes.items() if _flat(lo, hi)]
    top = max(flat or boxes, key=lambda n: (boxes[n][1][1], _area(*boxes[n]), n))
    top_lo, top_hi = boxes[top]
    floor = min(lo[1] for lo, _ in boxes.values())
    height = top_hi[1] - floor
    out = {}
    for name, (lo, hi) in boxes.items():
        size = hi - lo
        if name == top:
            out[name] = "top"
        elif lo[1] <= floor + 0.05 * height and size[1] > 0.4 * height:
            out[name] = "leg"
        elif _flat(lo, hi) and _area(lo, hi) > 0.3 * _area(top_lo, top_hi):
            out[name] = "shelf"
        elif hi[1] >= top_lo[1] - 0.2 * height and size[1] < 0.3 * height:
            out[name] = "apron"
        else:
            out[name] = "support"
    return out


def label_storage(boxes) -> dict[str, str]:
    lo_all = np.min([lo for lo, _ in boxes.values()], axis=0)
    hi_all = np.max([hi for _, hi in boxes.values()], axis=0)
    extent = hi_all - lo_all
    out = {}
    for name, (lo, hi) in boxes.items():
        size = hi - lo
        front = hi[2] >= hi_all[2] - 0.05 * extent[2]
        if size[2] < 0.25 * min(size[0], size[1]) and front:
            out[name] = "door"
        elif front and size[2] >= 0.25 * min(size[0], size[1]) and size[1] < 0.5 * extent[1] and \
                size[0] < 0.95 * extent[0]:
            out[name] = "drawer"
        elif _flat(lo, hi) and hi[1] >= hi_all[1] - 0.05 * extent[1]:
            out[name] = "top"
        elif _flat(lo, hi) and lo[1] <= lo_all[1] + 0.05 * extent[1]:
            out[name] = "base"
        elif _flat(lo, hi):
            out[name] = "shelf"
        elif size[0] < 0.25 * min(size[1], size[2]):
            out[name] = "side"
        elif size[2] < 0.25 * min(size[0], size[1]):
            out[name] = "back"
        else:
            out[name] = "body"
    return out


LABELLERS = {"chair": label_chair, "table": label_table, "storage": label_storage}


def label_parts(category: str | None, corners: Mapping[str, np.ndarray]) -> dict[str, str]:
    """Labels by the category's rules; ``part`` for every part when the category is unknown."""
    if category not in LABELLERS:
        return {name: "part" for name in corners}
    return LABELLERS[category](_boxes(corners))
