"""The Chamfer distance between two point sets (nearest neighbours by scipy's k-d tree)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class ChamferTarget:
    """A fixed target point set with its k-d tree built once, for many distance queries."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = np.asarray(points, dtype=float)
        self.tree = cKDTree(self.points)

    def distance(self, points: np.ndarray) -> float:
        """Symmetric mean nearest-neighbour distance: the mean over both sets of each point's
        distance to the other set, averaged over the two directions (in the shape's units)."""
        points = np.asarray(points, dtype=float)
        to_target, _ = self.tree.query(points, workers=1)
        to_points, _ = cKDTree(points).query(self.points, workers=1)
        return 0.5 * (float(to_target.mean()) + float(to_points.mean()))


def chamfer_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric mean nearest-neighbour distance between point sets ``a`` and ``b``."""
    return ChamferTarget(b).distance(a)
