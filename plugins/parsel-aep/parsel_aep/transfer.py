"""Restoring symmetry analytically: E* = T(E) (paper 5.3).

When one member of a symmetry relation is edited, the others get the same edit seen
through the symmetry: mirrored for a reflection, shifted by the step for a translation
group, rotated about the axis for a rotation group. Features are carried over with the
relation's corner correspondence, so a taper of the left leg's top face becomes a
taper of the right leg's top face.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from parsel_core.hexahedron import CORNER_NAMES, EDGE_NAMES, FACE_NAMES, feature_corners
from parsel_core.ops import EditOp, Rotate
from parsel_core.relations import ReflectionSymmetry, Relation, RotationSymmetry, TranslationSymmetry, rotation_matrix

_FEATURE_BY_CORNERS = {frozenset(feature_corners(n)): n for n in FACE_NAMES + EDGE_NAMES + CORNER_NAMES}


def map_feature(feature: str | None, perm: Sequence[int]) -> str | None:
    """The feature whose corners are the images of ``feature``'s corners under ``perm``."""
    if feature is None:
        return None
    image = frozenset(perm[k] for k in feature_corners(feature))
    if image not in _FEATURE_BY_CORNERS:
        raise ValueError(f"feature {feature!r} has no counterpart under the correspondence")
    return _FEATURE_BY_CORNERS[image]


def _inverse(perm: Sequence[int]) -> list[int]:
    out = [0] * len(perm)
    for k, v in enumerate(perm):
        out[v] = k
    return out


def _clean(vector: np.ndarray) -> tuple[float, float, float]:
    """Round-off below 1e-12 and negative zeros removed, so transferred ops print cleanly."""
    v = np.where(np.abs(vector) < 1e-12, 0.0, np.round(vector, 12)) + 0.0
    return tuple(float(c) for c in v)


def _conjugate(op: EditOp, target: str, point: Callable, vector: Callable, feature: str | None,
               flips_orientation: bool) -> EditOp:
    changes: dict = {"operand": target, "feature": feature}
    for name in op.point_fields:
        changes[name] = _clean(point(np.asarray(getattr(op, name))))
    for name in op.unit_fields:
        changes[name] = _clean(vector(np.asarray(getattr(op, name))))
    if flips_orientation and isinstance(op, Rotate):  # an axis is a pseudo-vector
        changes["axis"] = _clean(-np.asarray(changes["axis"]))
    return dataclasses.replace(op, **changes)


def member_correspondence(relation: Relation, source: str, target: str) -> list[int]:
    """Corner of ``target`` that corresponds to each corner of ``source``."""
    if isinstance(relation, ReflectionSymmetry):
        perm = list(relation.correspondence)
        return perm if relation.members[0] == source else _inverse(perm)
    identity = tuple(range(8))
    corr = relation.correspondence or tuple(identity for _ in relation.members)
    i, j = relation.members.index(source), relation.members.index(target)
    to_zero = _inverse(corr[i])
    return [corr[j][to_zero[k]] for k in range(8)]


def transfer(ops: Sequence[EditOp], relation: Relation, source: str, target: str) -> list[EditOp]:
    """``source``'s ops carried to ``target`` through the symmetry ``relation``."""
    perm = member_correspondence(relation, source, target)
    out = []
    for op in ops:
        feature = map_feature(op.feature, perm)
        if isinstance(relation, ReflectionSymmetry):
            o, n = np.asarray(relation.origin), np.asarray(relation.normal)

            def point(p, o=o, n=n):
                return p - 2.0 * np.dot(p - o, n) * n

            def vector(d, n=n):
                return d - 2.0 * np.dot(d, n) * n

            out.append(_conjugate(op, target, point, vector, feature, True))
        elif isinstance(relation, TranslationSymmetry):
            shift = (relation.members.index(target) - relation.members.index(source)) * np.asarray(relation.step)
            out.append(_conjugate(op, target, lambda p, s=shift: p + s, lambda d: d, feature, False))
        elif isinstance(relation, RotationSymmetry):
            steps = relation.members.index(target) - relation.members.index(source)
            r = rotation_matrix(relation.axis, steps * relation.angle)
            c = np.asarray(relation.center)
            out.append(_conjugate(op, target, lambda p, r=r, c=c: c + r @ (p - c), lambda d, r=r: r @ d, feature,
                                  False))
        else:
            raise TypeError(f"relation {relation.id!r} is not a symmetry")
    return out
