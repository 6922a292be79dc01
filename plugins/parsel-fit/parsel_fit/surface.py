"""Surface samples of an edited shape, held by cage coordinates so an edit moves them.

Points are drawn once on each part's rest surface (its mesh when it has one, else its
hexahedron's faces), area-weighted and from a fixed seed, and stored as trilinear
weights in the part's rest hexahedron, as the cage deformer holds mesh vertices. The
edited shape's samples are then one ``(m, 8) @ (8, 3)`` product per part: the same
points of the surface at every parameter value, so the Chamfer distance changes
smoothly with the parameters instead of jumping with a fresh random draw. Instances of
a group whose count an edit changed reuse their first member's samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsel_core.cage import cage_weights, point_weights
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import FACE_TRIANGLES
from parsel_core.program import Evaluation

DEFAULT_SAMPLES = 8192


def _triangle_samples(triangles: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` points spread evenly over triangles (t, 3, 3): a scrambled Halton sequence
    picks the triangle (by cumulative area) and the point in it, so the samples cover the
    surface without the clumps and holes of independent draws, which would otherwise
    dominate the Chamfer distance between two samplings of the same surface."""
    from scipy.stats import qmc

    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = float(areas.sum())
    if count <= 0 or total <= 0:
        return np.zeros((0, 3))
    u = qmc.Halton(d=3, scramble=True, seed=rng).random(count)
    cumulative = np.cumsum(areas) / total
    which = np.minimum(np.searchsorted(cumulative, u[:, 0], side="right"), len(triangles) - 1)
    r1, r2 = u[:, 1].copy(), u[:, 2].copy()
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    return a[which] + r1[:, None] * (b[which] - a[which]) + r2[:, None] * (c[which] - a[which])


def part_triangles(shape: ShapeGraph, part_id: str) -> np.ndarray:
    """A part's rest surface as triangles: its mesh's, else its hexahedron's 12."""
    part = shape.parts[part_id]
    mesh = part.mesh
    if mesh is not None and getattr(mesh, "faces", None) is not None and len(mesh.faces):
        return np.asarray(mesh.vertices, dtype=float)[np.asarray(mesh.faces)]
    return part.hexahedron.corners[FACE_TRIANGLES]


def triangles_area(triangles: np.ndarray) -> float:
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


@dataclass(frozen=True)
class SurfaceSampler:
    """Fixed surface samples of every part as cage weights (``weights[part]``: (m, 8))."""

    weights: dict[str, np.ndarray]

    @classmethod
    def of(cls, shape: ShapeGraph, count: int = DEFAULT_SAMPLES, seed: int = 0) -> SurfaceSampler:
        """About ``count`` samples spread over the parts by rest surface area (at least 8 per part)."""
        rng = np.random.default_rng(seed)
        triangles = {pid: part_triangles(shape, pid) for pid in shape.parts}
        areas = {pid: triangles_area(t) for pid, t in triangles.items()}
        total = sum(areas.values()) or 1.0
        weights = {}
        for pid, tris in triangles.items():
            n = max(8, int(round(count * areas[pid] / total)))
            corners = shape.parts[pid].hexahedron.corners
            points = _triangle_samples(tris, n, rng)
            if len(points) == 0:  # a degenerate part: its corners stand for it
                weights[pid] = cage_weights(np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)],
                                                     dtype=float))
            else:
                weights[pid] = point_weights(corners, points)
        return cls(weights)

    def points(self, shape: ShapeGraph, evaluation: Evaluation) -> np.ndarray:
        """The samples (n, 3) of the edited shape (members of re-laid-out groups as their instances)."""
        replaced = {m for group in evaluation.instances for m in shape.relation(group).members}
        out = [self.weights[pid] @ np.asarray(evaluation.parts[pid], dtype=float)
               for pid in self.weights if pid not in replaced and pid not in evaluation.removed]
        for group, instances in evaluation.instances.items():
            first = shape.relation(group).members[0]
            stacked = self.weights[first] @ np.asarray(instances, dtype=float)
            out.append(stacked.reshape(-1, 3))
        points = np.concatenate(out) if out else np.zeros((0, 3))
        return points[np.all(np.isfinite(points), axis=1)]
