"""The arrays every detector reads: part ids, labels, corners and boxes of one shape."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from parsel_core.graph import ShapeGraph
from parsel_relations.geometry import Boxes, boxes_of


@dataclass(frozen=True)
class PartTable:
    """A shape's real parts as parallel arrays, in part-id order (so results are deterministic)."""

    ids: tuple[str, ...]
    labels: tuple[str, ...]
    corners: np.ndarray  # (n, 8, 3), canonical corner order

    @classmethod
    def from_shape(cls, shape: ShapeGraph) -> PartTable:
        parts = sorted(shape.parts.values(), key=lambda p: p.id)
        corners = np.array([p.hexahedron.corners for p in parts], dtype=float).reshape(-1, 8, 3)
        return cls(tuple(p.id for p in parts), tuple(p.label for p in parts), corners)

    def __len__(self) -> int:
        return len(self.ids)

    @cached_property
    def boxes(self) -> Boxes:
        return boxes_of(self.corners)

    @cached_property
    def centers(self) -> np.ndarray:
        """Corner means (n, 3): mirrored or moved copies have mirrored or moved centres."""
        return self.corners.mean(axis=1)

    @cached_property
    def extents(self) -> np.ndarray:
        """Sorted full box extents (n, 3): equal for congruent parts whatever their pose."""
        return np.sort(2.0 * self.boxes.halves, axis=1)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The shape's axis-aligned bounds over all corners."""
        flat = self.corners.reshape(-1, 3)
        return flat.min(axis=0), flat.max(axis=0)

    def label_groups(self, minimum: int = 2) -> list[np.ndarray]:
        """Indices of parts sharing a label, for labels with at least ``minimum`` parts."""
        groups: dict[str, list[int]] = {}
        for i, label in enumerate(self.labels):
            groups.setdefault(label, []).append(i)
        return [np.array(g) for _, g in sorted(groups.items()) if len(g) >= minimum]

    def congruent(self, idx: np.ndarray, tol: float) -> np.ndarray:
        """(m, m) whether parts ``idx`` have the same sorted extents within ``tol``."""
        e = self.extents[idx]
        return np.abs(e[:, None, :] - e[None, :, :]).max(axis=2) <= tol
