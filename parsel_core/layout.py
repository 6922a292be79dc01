"""Instance layouts of symmetry groups under ChangeCount / ChangeDelta (reference section 3).

A group's instances are copies of its first member (as edited). Where they go depends
on the mode:

* ``top_down``: the first and last instance anchors are held by cage coordinates in the
  virtual parent, so editing the parent moves them. ChangeCount fills the span between
  them with ``n`` evenly spaced instances; ChangeDelta keeps the span and sets the step,
  and the count is however many instances fit (so scaling the parent changes the count).
* ``bottom_up``: the first instance and the step are explicit. ChangeCount adds or
  removes instances at the end; ChangeDelta scales the step and keeps the count; the
  parent's box is derived from the instances.

Rotation groups work the same way with the angle as step; a closed loop (count x angle
= 2 pi) stays closed under ChangeCount.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from parsel_core.cage import point_weights
from parsel_core.errors import ParselError
from parsel_core.ops import ChangeCount, ChangeDelta, GroupOp
from parsel_core.relations import Relation, RotationSymmetry, TranslationSymmetry, rotation_matrix


def _round_half_up(value: float) -> int:
    if not math.isfinite(value) or abs(value) > 1e15:
        raise ParselError(f"a count change of {value!r} is not a usable number of instances")
    return int(math.floor(value + 0.5))


def _checked_count(relation: Relation, count: float, max_count: float | None = None) -> int:
    """The instance count, refused (before any array is made) when over the ``max_instances``
    limit (``max_count``: its value, when the caller has read it once for many samples)."""
    from parsel_core.config import check_limit

    if not math.isfinite(count):
        raise ParselError(f"group {relation.id!r}: the edit asks for {count!r} instances")
    check_limit("max_instances", f"group {relation.id!r}: instances", count, max_count)
    return int(count)


def _fitting(length: float, size: float) -> float:
    """How many steps of ``size`` fit in ``length`` (as a float: it may be huge)."""
    return math.floor(length / size + 1e-9) if math.isfinite(length / size) else math.inf


def translation_deviations(rest_members: Sequence[np.ndarray]) -> np.ndarray:
    """How far each rest member is from a perfect copy of the first one step along (k, 8, 3).

    Detected rows are rarely perfect (a ShapeAssembly shelf 1% shallower than the one
    below it); a re-laid-out member keeps its own deviation, so a row laid out again at
    its rest spacing is the rest row, and every member keeps its contacts.
    """
    rest = np.asarray(rest_members, dtype=float)
    if len(rest) < 2:
        return np.zeros_like(rest)
    step = rest[1].mean(axis=0) - rest[0].mean(axis=0)
    return rest - rest[0][None] - np.arange(len(rest))[:, None, None] * step


@dataclass(frozen=True)
class RestLayout:
    """What a group's layout reads of the rest shape alone, worked out once per group and
    program (a slider step, or every sample of a batch, lays the group out again).

    ``anchor_weights``: cage coordinates in the rest parent of the top-down anchors (the
    first and last members' centres of a row, a ring's centre), ``None`` bottom-up;
    ``rest_step`` and ``deviations`` (:func:`translation_deviations`): a row's, ``None``
    for a ring."""

    anchor_weights: np.ndarray | None
    rest_step: np.ndarray | None = None
    deviations: np.ndarray | None = None

    def __post_init__(self) -> None:
        for array in (self.anchor_weights, self.rest_step, self.deviations):
            if array is not None:
                array.flags.writeable = False  # (shared by every layout of the group)


def rest_layout(relation: Relation, rest_parent: np.ndarray, rest_members: Sequence[np.ndarray],
                top_down: bool) -> RestLayout:
    """The :class:`RestLayout` of a translation or rotation group."""
    if isinstance(relation, TranslationSymmetry):
        k = len(rest_members)
        rest_step = np.asarray(rest_members[1].mean(axis=0) - rest_members[0].mean(axis=0)) if k > 1 else np.zeros(3)
        weights = None
        if top_down:
            anchors = np.array([rest_members[0].mean(axis=0), rest_members[-1].mean(axis=0)])
            weights = point_weights(rest_parent, anchors)
        return RestLayout(weights, rest_step, translation_deviations(rest_members))
    if isinstance(relation, RotationSymmetry):
        center = np.asarray(relation.center, dtype=float)
        return RestLayout(point_weights(rest_parent, center[None]) if top_down else None)
    raise TypeError(f"relation {relation.id!r} of kind {relation.kind!r} is not a group")


def translation_layout(relation: TranslationSymmetry, rest_parent: np.ndarray, rest_members: Sequence[np.ndarray],
                       parent: np.ndarray, members: Sequence[np.ndarray],
                       ops: Sequence[tuple[GroupOp, float]], rest: RestLayout | None = None,
                       max_count: float | None = None) -> np.ndarray:
    """Instances (n, 8, 3) of a translation group after its group ops; instance j < k carries
    member j's own deviation from the perfect row (:func:`translation_deviations`).
    ``rest``: the group's :func:`rest_layout`, when already made; ``max_count``: the
    ``max_instances`` limit, when already read (:func:`group_instances`)."""
    top_down = ops[0][0].mode == "top_down"
    rest = rest or rest_layout(relation, rest_parent, rest_members, top_down)
    k = len(rest_members)
    first = members[0]
    template = first - first.mean(axis=0)
    rest_step = rest.rest_step
    count = k
    if top_down:
        start, end = rest.anchor_weights @ parent
        span = end - start
        step = span / (k - 1) if k > 1 else np.zeros(3)
        for op, amount in ops:
            if isinstance(op, ChangeCount):
                count = max(1, k + _round_half_up(amount))
                step = span / (count - 1) if count > 1 else np.zeros(3)
            elif isinstance(op, ChangeDelta):
                length = float(np.linalg.norm(span))
                direction = span / length if length > 0 else rest_step / max(np.linalg.norm(rest_step), 1e-300)
                step = direction * np.linalg.norm(rest_step) * (1.0 + amount)
                size = float(np.linalg.norm(step))
                count = _fitting(length, size) + 1 if size > 1e-12 else 1
    else:
        start = first.mean(axis=0)
        step = members[1].mean(axis=0) - start if k > 1 else np.zeros(3)
        for op, amount in ops:
            if isinstance(op, ChangeCount):
                count = max(1, k + _round_half_up(amount))
            elif isinstance(op, ChangeDelta):
                step = step * (1.0 + amount)
    count = _checked_count(relation, count, max_count)
    offsets = start + np.arange(count)[:, None] * step
    instances = template[None] + offsets[:, None, :]
    kept = min(count, k)
    instances[:kept] += rest.deviations[:kept]
    return instances


def rotation_layout(relation: RotationSymmetry, rest_parent: np.ndarray, parent: np.ndarray,
                    members: Sequence[np.ndarray], ops: Sequence[tuple[GroupOp, float]],
                    rest: RestLayout | None = None, max_count: float | None = None) -> np.ndarray:
    """Instances (n, 8, 3) of a rotation group after its group ops (``rest`` and
    ``max_count``: as in :func:`translation_layout`)."""
    k = len(relation.members)
    angle = relation.angle
    closed = relation.closed
    center = np.asarray(relation.center, dtype=float)
    count = k
    top_down = ops[0][0].mode == "top_down"
    if top_down:
        rest = rest or rest_layout(relation, rest_parent, (), top_down)
        center = (rest.anchor_weights @ parent)[0]
    span = angle * (k - 1)
    for op, amount in ops:
        if isinstance(op, ChangeCount):
            count = max(1, k + _round_half_up(amount))
            if closed:
                angle = math.copysign(2 * math.pi / count, relation.angle)
            elif top_down and count > 1:
                angle = span / (count - 1)
        elif isinstance(op, ChangeDelta):
            angle = relation.angle * (1.0 + amount)
            if top_down and abs(angle) > 1e-12:
                full = 2 * math.pi if closed else abs(span)
                count = max(1, _fitting(full, abs(angle)) + (0 if closed else 1))
    count = _checked_count(relation, count, max_count)
    template = members[0] - center
    return np.stack([center + template @ rotation_matrix(relation.axis, j * angle).T for j in range(count)])


def group_instances(relation: Relation, rest_parent: np.ndarray, rest_members: Sequence[np.ndarray],
                    parent: np.ndarray, members: Sequence[np.ndarray],
                    ops: Sequence[tuple[GroupOp, float]], rest: RestLayout | None = None,
                    max_count: float | None = None) -> np.ndarray:
    """Dispatch on the group kind; ``ops`` are the group's ops with numeric amounts, in order;
    ``rest`` the group's :func:`rest_layout`, when already made; ``max_count`` the
    ``max_instances`` limit, when already read (a caller laying out many samples reads
    it once: with a parsel.toml, each read parses the file)."""
    if isinstance(relation, TranslationSymmetry):
        return translation_layout(relation, rest_parent, rest_members, parent, members, ops, rest, max_count)
    if isinstance(relation, RotationSymmetry):
        return rotation_layout(relation, rest_parent, parent, members, ops, rest, max_count)
    raise TypeError(f"relation {relation.id!r} of kind {relation.kind!r} is not a group")
