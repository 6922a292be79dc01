"""Directional labels: words that tell apart parts sharing a label (reference section 1).

Parts that share a label get directional words relative to one another, so a prompt can
say "the front-left leg" instead of an id. Conventions: +x is right, +y is up, +z is
front. Words are chosen by arrangement:

* a single part keeps its label (``top``);
* parts on a line (their centres vary along one axis only) are named by rank along it:
  ``left``/``right``, ``left``/``center``/``right``, ``left``/``left-center``/
  ``right-center``/``right`` and, for 5, ``left``/``left-center``/``center``/
  ``right-center``/``right`` (``bottom``..``top`` along y, ``back``..``front`` along z);
* parts in a rotational arrangement (a rotation group of the shape, or parts on a
  circle whose per-axis words would not tell them apart) are named by the compass
  direction of their centre from the ring's centre, x word first: ``left-back``,
  ``front``, ``right-front``;
* other arrangements (a rectangle of legs) by the side of the group's centre each part
  lies on, along each axis the group spreads over, in y, z, x order: ``back-left``,
  ``top-front-right``; a part at the centre of the group is ``center``;
* groups of more than 5 parts get numeric indices ``(1 of 8)`` in order along the row
  (or around the ring).

Words that still collide get an index appended. Labels only help the language model
(:mod:`parsel_core.language.describe` puts them in prompts); nothing in the engine
depends on them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_core.relations import RotationSymmetry

SIDE_WORDS = (("left", "right"), ("bottom", "top"), ("back", "front"))
AXIS_NAMES = ("x", "y", "z")
#: Most parts per label that get words; larger groups get numeric indices.
MAX_WORDED = 5
#: An axis along which a group's centres spread less than this fraction of the shape's
#: size does not count as a direction of the arrangement.
SPREAD_FRACTION = 0.02


def _line_words(axis: int, count: int) -> tuple[str, ...]:
    low, high = SIDE_WORDS[axis]
    return {
        2: (low, high),
        3: (low, "center", high),
        4: (low, f"{low}-center", f"{high}-center", high),
        5: (low, f"{low}-center", "center", f"{high}-center", high),
    }[count]


def _spread_axes(offsets: np.ndarray, threshold: float) -> list[int]:
    return [a for a in range(3) if np.ptp(offsets[:, a]) > threshold]


def _side_words(offsets: np.ndarray, axes: Sequence[int]) -> list[str]:
    """Per part, the side of the group centre it lies on along each spread axis (y, z, x)."""
    words = []
    for offset in offsets:
        parts = []
        for axis in sorted(axes, key=lambda a: (1, 2, 0).index(a)):
            reach = np.abs(offsets[:, axis]).max()
            if abs(offset[axis]) > 0.25 * reach:
                parts.append(SIDE_WORDS[axis][int(offset[axis] > 0)])
        words.append("-".join(parts) or "center")
    return words


def _plane_axes(axis: int) -> tuple[int, int]:
    """The two axes of the plane normal to ``axis``, x before z before y in the words."""
    others = [a for a in range(3) if a != axis]
    return tuple(sorted(others, key=lambda a: (0, 2, 1).index(a)))


def _compass_words(offsets: np.ndarray, axis: int) -> list[str]:
    """Direction of each offset in the plane normal to ``axis``, to the nearest 45 degrees."""
    first, second = _plane_axes(axis)
    words = []
    for offset in offsets:
        angle = np.arctan2(offset[second], offset[first])
        snapped = np.round(angle / (np.pi / 4.0)) * (np.pi / 4.0)
        parts = []
        for a, component in ((first, np.cos(snapped)), (second, np.sin(snapped))):
            if abs(component) > 1e-6:
                parts.append(SIDE_WORDS[a][int(component > 0)])
        words.append("-".join(parts))
    return words


def _ring_axis(centres: np.ndarray, threshold: float) -> int | None:
    """The axis about which 3 or more centres lie on a circle around their centroid, if any."""
    if len(centres) < 3:
        return None
    offsets = centres - centres.mean(axis=0)
    for axis in range(3):
        if np.ptp(offsets[:, axis]) > threshold:
            continue
        plane = [a for a in range(3) if a != axis]
        radii = np.linalg.norm(offsets[:, plane], axis=1)
        if radii.min() > threshold and np.ptp(radii) <= threshold:
            return axis
    return None


def _rotation_of(shape: ShapeGraph, ids: Sequence[str]) -> RotationSymmetry | None:
    for relation in shape.relations.values():
        if isinstance(relation, RotationSymmetry) and set(ids) <= set(relation.members):
            return relation
    return None


def _dominant_axis(relation: RotationSymmetry) -> int:
    return int(np.abs(np.asarray(relation.axis)).argmax())


def _numbered(ids: Sequence[str], centres: np.ndarray, ring: RotationSymmetry | None) -> list[str]:
    """``(k of n)`` indices: around the ring in its order, else along the widest axis."""
    n = len(ids)
    if ring is not None:
        order = [ring.members.index(i) for i in ids]
    else:
        spread = np.ptp(centres, axis=0)
        primary = int(spread.argmax())
        keys = [(round(float(c[primary]), 9), *(round(float(c[a]), 9) for a in range(3) if a != primary))
                for c in centres]
        order = _ranks(keys, ids)
    return [f"{k + 1} of {n}" for k in order]


def _ranks(keys: Sequence[tuple], ids: Sequence[str]) -> list[int]:
    order = sorted(range(len(ids)), key=lambda i: (keys[i], ids[i]))
    ranks = [0] * len(ids)
    for rank, i in enumerate(order):
        ranks[i] = rank
    return ranks


def _unique(words: list[str], ids: Sequence[str]) -> list[str]:
    """Append an index to words shared by several parts (in id order)."""
    out = list(words)
    for word in set(words):
        holders = [k for k, w in enumerate(words) if w == word]
        if len(holders) > 1:
            for n, k in enumerate(sorted(holders, key=lambda k: ids[k]), start=1):
                out[k] = f"{word} {n}" if word else str(n)
    return out


def group_words(shape: ShapeGraph, ids: Sequence[str], threshold: float) -> list[str]:
    """Directional words for parts ``ids`` that share a label (module docstring)."""
    centres = np.array([shape.parts[i].hexahedron.center for i in ids])
    ring = _rotation_of(shape, ids)
    if len(ids) > MAX_WORDED:
        return _numbered(ids, centres, ring)
    offsets = centres - centres.mean(axis=0)
    axes = _spread_axes(offsets, threshold)
    if not axes:
        return _unique(["" for _ in ids], ids)
    if ring is not None:
        return _unique(_compass_words(centres - np.asarray(ring.center), _dominant_axis(ring)), ids)
    if len(axes) == 1:
        axis = axes[0]
        ranks = _ranks([(float(c[axis]),) for c in centres], ids)
        values = np.sort(centres[:, axis])
        if np.all(np.diff(values) > threshold):
            words = _line_words(axis, len(ids))
            return [words[r] for r in ranks]
    side = _side_words(offsets, axes)
    ring_axis = _ring_axis(centres, threshold)
    if len(set(side)) < len(side) and ring_axis is not None:
        return _unique(_compass_words(offsets, ring_axis), ids)
    return _unique(side, ids)


def position_words(shape: ShapeGraph) -> dict[str, str]:
    """``part id -> directional words`` among the parts sharing its label (``front-left``).

    Empty for a part whose label is unique; parts that share a label but do not spread
    out (stacked in one place) are numbered ``1``, ``2``, ...
    """
    by_label: dict[str, list[str]] = {}
    for pid in sorted(shape.parts):
        by_label.setdefault(shape.parts[pid].label, []).append(pid)
    threshold = SPREAD_FRACTION * shape.size if shape.parts else 0.0
    out = dict.fromkeys(shape.parts, "")
    for ids in by_label.values():
        if len(ids) > 1:
            out.update(zip(ids, group_words(shape, ids, threshold)))
    return out


def directional_labels(shape: ShapeGraph) -> dict[str, str]:
    """``part id -> label with directional words``, e.g. ``leg (front-left)``; unique labels unchanged."""
    words = position_words(shape)
    return {pid: f"{part.label} ({words[pid]})" if words[pid] else part.label for pid, part in shape.parts.items()}
