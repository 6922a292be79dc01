"""An example plugin: ``twist``, an analytic edit operator that is not in the paper's DSL.

A twist rotates each point about an axis by an angle proportional to the point's
height along that axis: ``p -> o + R(amount * ((p - o) . n)) (p - o)``. Applied to a
whole part it turns a straight leg into a twisted one; like every operator it works
unchanged on floats and on CAS expressions, because it only uses arithmetic and
``math.sin`` / ``math.cos``, which work entry by entry on floats, arrays and CAS
expressions (:mod:`parsel_core.opmath`). docs/plugins.md walks through this file.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from parsel_core import hookimpl
from parsel_core.ops import EditOp, Vector


@dataclass(frozen=True)
class Twist(EditOp):
    """Rotate points about axis (origin, axis) by ``amount`` radians per unit of height."""

    name: ClassVar[str] = "twist"
    #: Words that ask for this operator in a request ("twist the legs"): the offline provider
    #: reads them (docs/plugins.md, "Words for the offline provider").
    words: ClassVar[tuple[str, ...]] = ("twist", "twirl", "wring")
    unit_fields: ClassVar[tuple[str, ...]] = ("axis",)
    point_fields: ClassVar[tuple[str, ...]] = ("origin",)
    origin: Vector = (0.0, 0.0, 0.0)
    axis: Vector = (0.0, 1.0, 0.0)

    def transform(self, points, amount, math):
        o, n = np.asarray(self.origin), np.asarray(self.axis)
        centred = points - o
        height = centred[..., 0:1] * n[0] + centred[..., 1:2] * n[1] + centred[..., 2:3] * n[2]
        angle = height * amount  # one angle per point: (..., m, 1)
        cos, sin = math.cos(angle), math.sin(angle)  # elementwise on every path (parsel_core.opmath)
        x, y, z = centred[..., 0:1], centred[..., 1:2], centred[..., 2:3]
        cross = np.concatenate([n[1] * z - n[2] * y, n[2] * x - n[0] * z, n[0] * y - n[1] * x], axis=-1)
        # Rodrigues' rotation of each point by its own angle.
        return o + centred * cos + cross * sin + height * n * (1 - cos)

    def mirrored(self, origin, normal, operand, feature_map=None):
        """In a mirror the twist turns the other way: heights along the reflected axis are
        unchanged, but a reflection reverses every rotation's sense, so the amount flips."""
        op = super().mirrored(origin, normal, operand, feature_map)
        return dataclasses.replace(op, amount=f"-({self.amount})")


@hookimpl
def parsel_edit_operators():
    return [Twist]
