"""Signed distance fields of part meshes, sampled once per part in the part's rest cage.

A part's field is stored on a lattice of cube coordinates ``(u, v, w)`` of its rest
hexahedron (padded by a margin), because that is where the remesher looks it up: a
world point of the edited shape is mapped back to cube coordinates by the inverse cage
map of the part's edited hexahedron, and the field is interpolated there. One sampling
therefore serves every edit and every slider value.

* Sign: ray parity along lattice lines, in cube coordinates (the rest cage map is a
  homeomorphism, so inside stays inside); each line is cast along all three axes and
  the majority wins, which tolerates a small crack in an imperfect mesh.
* Distance: exact point-to-triangle distances, but only in a narrow band around the
  surface (a Euclidean distance transform of the inside mask finds it), with candidate
  triangles pruned by bounding boxes per small block of points. Beyond the band the
  field is clamped to +-band, which is all marching cubes needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsel_core.cage import cage_weights, inverse_trilinear


@dataclass(frozen=True)
class PartField:
    """A part's signed distance (negative inside) on a lattice of its rest cube coordinates.

    ``values[i, j, k]`` is at cube point ``lo + (i, j, k) * step``; distances are in the
    rest shape's units and clamped to ``[-band, band]``."""

    values: np.ndarray
    lo: np.ndarray
    step: np.ndarray
    band: float

    def sample(self, uvw: np.ndarray) -> np.ndarray:
        """Trilinear interpolation at cube points (n, 3); ``band`` (outside) beyond the lattice."""
        from scipy.ndimage import map_coordinates

        coords = ((np.asarray(uvw, dtype=float) - self.lo) / self.step).T
        return map_coordinates(self.values, coords, order=1, mode="constant", cval=self.band)


def point_triangle_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from each point to each triangle: points (n, 1, 3), corners (1, t, 3) -> (n, t)."""
    ab, ac, ap = b - a, c - a, points - a
    normal = np.cross(ab, ac)
    area2 = np.einsum("...i,...i", normal, normal)
    bp, cp = points - b, points - c
    # The projection lies inside when it is on the inner side of all three edges.
    inside = ((np.einsum("...i,...i", np.cross(ab, ap), normal) >= 0)
              & (np.einsum("...i,...i", np.cross(c - b, bp), normal) >= 0)
              & (np.einsum("...i,...i", np.cross(a - c, cp), normal) >= 0) & (area2 > 1e-30))
    plane = np.abs(np.einsum("...i,...i", ap, normal)) / np.sqrt(np.maximum(area2, 1e-300))

    def segment(p, start, edge):
        t = np.clip(np.einsum("...i,...i", p, edge) / np.maximum(np.einsum("...i,...i", edge, edge), 1e-300), 0, 1)
        return np.linalg.norm(p - t[..., None] * edge, axis=-1)

    edges = np.minimum(np.minimum(segment(ap, a, ab), segment(bp, b, c - b)), segment(cp, c, a - c))
    return np.where(inside, plane, edges)


def unsigned_distance(points: np.ndarray, triangles: np.ndarray, cutoff: float, block: int = 256) -> np.ndarray:
    """Distance (clamped to ``cutoff``) of each point to the nearest triangle.

    Points should come in spatially coherent order (the caller sorts them by lattice
    block); each block of ``block`` points only meets the triangles whose boxes come
    within ``cutoff`` of the block's box."""
    out = np.full(len(points), float(cutoff))
    lo_t, hi_t = triangles.min(axis=1), triangles.max(axis=1)
    for start in range(0, len(points), block):
        p = points[start:start + block]
        lo, hi = p.min(axis=0) - cutoff, p.max(axis=0) + cutoff
        near = np.all((hi_t >= lo) & (lo_t <= hi), axis=1)
        if not near.any():
            continue
        tri = triangles[near]
        d = point_triangle_distance(p[:, None, :], tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
        out[start:start + block] = np.minimum(cutoff, d.min(axis=1))
    return out


def _parity(grid_axes: list[np.ndarray], tri_uvw: np.ndarray, axis: int) -> np.ndarray:
    """Inside mask of lattice points by counting crossings of rays cast along ``axis``."""
    others = [a for a in range(3) if a != axis]
    p_axis, q_axis = others
    shape = [len(g) for g in grid_axes]
    # Nudge the rays off lattice values: mesh vertices often sit exactly on them.
    jitter = np.array([1.234567e-7, 7.654321e-8])
    pq = np.stack(np.meshgrid(grid_axes[p_axis] + jitter[0], grid_axes[q_axis] + jitter[1], indexing="ij"),
                  axis=-1).reshape(-1, 2)
    a, b, c = (tri_uvw[:, i, :] for i in range(3))
    ab, ac = b[:, others] - a[:, others], c[:, others] - a[:, others]
    det = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    keep = np.abs(det) > 1e-18
    a, b, c, ab, ac, det = a[keep], b[keep], c[keep], ab[keep], ac[keep], det[keep]
    inside = np.zeros((len(pq), shape[axis]), dtype=bool)
    coords = grid_axes[axis]
    tri_lo, tri_hi = np.minimum(np.minimum(a, b), c)[:, others], np.maximum(np.maximum(a, b), c)[:, others]
    for start in range(0, len(pq), 2048):
        rays = pq[start:start + 2048]
        near = np.all((rays[:, None, :] >= tri_lo[None]) & (rays[:, None, :] <= tri_hi[None]), axis=2)
        ray_i, tri_i = np.nonzero(near)
        if len(ray_i) == 0:
            continue
        d = rays[ray_i] - a[tri_i][:, others]
        s = (d[:, 0] * ac[tri_i, 1] - d[:, 1] * ac[tri_i, 0]) / det[tri_i]
        t = (ab[tri_i, 0] * d[:, 1] - ab[tri_i, 1] * d[:, 0]) / det[tri_i]
        hit = (s >= 0) & (t >= 0) & (s + t <= 1)
        ray_i, tri_i, s, t = ray_i[hit], tri_i[hit], s[hit], t[hit]
        crossing = (a[tri_i, axis] + s * (b[tri_i, axis] - a[tri_i, axis]) + t * (c[tri_i, axis] - a[tri_i, axis]))
        # Points with an odd number of crossings beyond them (along +axis) are inside.
        counts = np.zeros((len(rays), len(coords) + 1), dtype=np.int64)
        np.add.at(counts, (ray_i, np.searchsorted(coords, crossing)), 1)
        beyond = counts[:, ::-1].cumsum(axis=1)[:, ::-1][:, 1:]
        inside[start:start + len(rays)] = beyond % 2 == 1
    # rows are (p, q) pairs, columns the axis coordinate: back to (u, v, w) order
    inside = inside.reshape(shape[p_axis], shape[q_axis], shape[axis])
    order = np.argsort([p_axis, q_axis, axis])
    return np.transpose(inside, order)


def part_field(corners: np.ndarray, vertices: np.ndarray, faces: np.ndarray, spacing: float,
               band_cells: float = 3.0) -> PartField:
    """The signed distance field of a closed triangle mesh, on a lattice of its cage's cube coordinates.

    ``spacing`` is the wanted lattice spacing in world units; the lattice covers the
    rest hexahedron padded by the band plus one cell on every side."""
    corners = np.asarray(corners, dtype=float)
    band = band_cells * spacing
    edges = np.linalg.norm(np.stack([corners[4] - corners[0], corners[2] - corners[0], corners[1] - corners[0]]),
                           axis=1)
    edges = np.maximum(edges, 1e-12)
    pad = (band + spacing) / edges
    counts = np.maximum(2, np.ceil(edges * (1 + 2 * pad) / spacing).astype(int) + 1)
    lo = -pad
    step = (1 + 2 * pad) / (counts - 1)
    grid_axes = [lo[i] + step[i] * np.arange(counts[i]) for i in range(3)]
    tri_uvw = inverse_trilinear(corners, np.asarray(vertices, dtype=float))[np.asarray(faces)]
    votes = sum(_parity(grid_axes, tri_uvw, axis).astype(int) for axis in range(3))
    inside = votes >= 2
    from scipy.ndimage import distance_transform_edt

    world_step = step * edges
    depth = np.where(inside, distance_transform_edt(inside, sampling=world_step),
                     distance_transform_edt(~inside, sampling=world_step))
    values = np.where(inside, -band, band)
    near = depth <= band + 2 * world_step.max()
    index = np.argwhere(near)
    if len(index):
        blocks = index // 6
        order = np.lexsort((blocks[:, 2], blocks[:, 1], blocks[:, 0]))
        index = index[order]
        uvw = lo + index * step
        points = cage_weights(uvw) @ corners
        triangles = np.asarray(vertices, dtype=float)[np.asarray(faces)]
        distance = unsigned_distance(points, triangles, band)
        sign = np.where(inside[tuple(index.T)], -1.0, 1.0)
        values[tuple(index.T)] = sign * distance
    return PartField(values, lo, step, band)
