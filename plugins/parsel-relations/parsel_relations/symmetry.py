"""Reflection, translation and rotation symmetry between same-label parts (reference section 2).

The paper runs ICP between sampled parts; on hexahedra an exact test is faster and finds
the same relations: a candidate transformation is read off the parts' centres, applied
to one part's 8 corners, and the corners must land on the other part's corners (under
some permutation) within the tolerance. Conflicts are then resolved jointly:

1. Translation and rotation groups (more than 2 parts) are found first; a part joins at
   most one group, larger groups first (translation before rotation on ties).
2. A closed or open rotation by a multiple of 90 degrees whose members all have a mirror
   partner in the group is dropped: four square legs on a square read as two mirror
   planes, which is how the paper's shapes are annotated.
3. Reflections are only about axis-aligned planes and never pair two members of the
   same group (no nested groups). Planes are taken in order of how many pairs they
   explain (the shape's global symmetry plane first), so a row mirrored onto another
   row pairs instance i with its mirror image rather than with whichever copy happens
   to be equidistant. A part mirrored about one plane gets another partner on the same
   axis only within one half of that plane (a reflected sub-assembly that is itself
   symmetric), never across it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsel_core.relations import ReflectionSymmetry, RotationSymmetry, TranslationSymmetry
from parsel_relations.geometry import clusters_1d, match_corners, rotation_matrix
from parsel_relations.table import PartTable

AXES = np.eye(3)
GROUP_RANK = {"translation": 0, "rotation": 1}
#: Parts whose centres are closer than this fraction of the tolerance are duplicates, not mirror images.
COINCIDENT = 1e-3


@dataclass(frozen=True)
class Mirror:
    """Part ``j`` is the mirror image of part ``i`` about the plane ``x[axis] = offset``."""

    i: int
    j: int
    axis: int
    offset: float
    perm: tuple[int, ...]
    error: float


@dataclass(frozen=True)
class Group:
    """A candidate translation or rotation group: members (table indices) in order."""

    kind: str
    members: tuple[int, ...]
    perms: tuple[tuple[int, ...], ...]
    step: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    angle: float = 0.0
    closed: bool = False


@dataclass(frozen=True)
class Symmetries:
    """Resolved symmetry relations of one shape, each family in id order."""

    reflections: tuple[ReflectionSymmetry, ...] = ()
    translations: tuple[TranslationSymmetry, ...] = ()
    rotations: tuple[RotationSymmetry, ...] = ()


# -- reflection candidates -------------------------------------------------------------


def mirror_candidates(table: PartTable, tol: float) -> list[Mirror]:
    """Every same-label, congruent pair mirrored about an axis-aligned plane at their midpoint.

    The plane's normal is the axis along which the centres are furthest apart (so a pair
    closer than the tolerance, such as two stacked thin panels, is still mirrored about
    one plane only); the other two centre coordinates must agree within the tolerance.
    """
    out: list[Mirror] = []
    for idx in table.label_groups(2):
        ii, jj = np.nonzero(np.triu(table.congruent(idx, tol), 1))
        if not len(ii):
            continue
        a_all, b_all = idx[ii], idx[jj]
        delta = table.centers[b_all] - table.centers[a_all]
        for axis in range(3):
            others = [k for k in range(3) if k != axis]
            along = np.abs(delta[:, axis])
            keep = (np.abs(delta[:, others]).max(axis=1) <= tol) & (along >= np.abs(delta).max(axis=1)) & (
                along > COINCIDENT * tol)
            if not keep.any():
                continue
            a, b = a_all[keep], b_all[keep]
            offset = (table.centers[a, axis] + table.centers[b, axis]) / 2.0
            mirrored = table.corners[a].copy()
            mirrored[:, :, axis] = 2.0 * offset[:, None] - mirrored[:, :, axis]
            perm, error = match_corners(mirrored, table.corners[b])
            out.extend(Mirror(int(a[p]), int(b[p]), axis, float(offset[p]), tuple(int(k) for k in perm[p]),
                              float(error[p]))
                       for p in np.flatnonzero(error <= tol))
    return out


def self_symmetric(table: PartTable, part: int, axis: int, offset: float, tol: float) -> bool:
    """Whether a part is its own mirror image about the plane ``x[axis] = offset``."""
    if abs(table.centers[part, axis] - offset) > tol:
        return False
    mirrored = table.corners[part].copy()
    mirrored[:, axis] = 2.0 * offset - mirrored[:, axis]
    return bool(match_corners(mirrored, table.corners[part])[1][0] <= tol)


def _nested(table: PartTable, pair: Mirror, planes: dict[int, list[float]], tol: float) -> bool:
    """Whether a pair may be added next to the planes its parts are already mirrored about:
    only inside one half of each such plane (a reflection nested in a reflected half)."""
    x = table.centers[[pair.i, pair.j], pair.axis]
    for part in (pair.i, pair.j):
        for offset in planes.get(part, ()):
            side = x - offset
            if abs(offset - pair.offset) <= tol or np.abs(side).min() <= tol or side[0] * side[1] < 0:
                return False
    return True


def resolve_mirrors(table: PartTable, candidates: list[Mirror], groups: list[Group], tol: float) -> list[Mirror]:
    """Mirror pairs kept after the group rule and the plane order (module docstring).

    Per axis, planes are taken by how many pairs they explain; a part already mirrored
    about a plane (or lying on it, its own mirror image) only gets another partner on the
    same axis when the new pair lies within one half of that plane: the nested
    reflections of a reflected sub-assembly, never a pair straddling the shape's plane.
    """
    group_of = {m: g for g, group in enumerate(groups) for m in group.members}
    candidates = [c for c in candidates
                  if group_of.get(c.i, -1) != group_of.get(c.j, -2)]
    lo, hi = table.bounds
    kept: list[Mirror] = []
    for axis in range(3):
        on_axis = [c for c in candidates if c.axis == axis]
        if not on_axis:
            continue
        offsets = np.array([c.offset for c in on_axis])
        middle = (lo[axis] + hi[axis]) / 2.0
        planes = []
        for members in clusters_1d(offsets, tol):
            offset = float(offsets[members].mean())
            planes.append((-len(members), abs(offset - middle), offset, [on_axis[k] for k in members]))
        planes.sort(key=lambda p: p[:3])
        mirrored_about: dict[int, list[float]] = {}
        for _, _, offset, pairs in planes:
            labels = {table.labels[c.i] for c in pairs}
            accepted, used = [], set()
            for c in sorted(pairs, key=lambda c: (c.error, c.i, c.j)):
                if c.i not in used and c.j not in used and _nested(table, c, mirrored_about, tol):
                    accepted.append(c)
                    used.update((c.i, c.j))
            for c in accepted:
                mirrored_about.setdefault(c.i, []).append(c.offset)
                mirrored_about.setdefault(c.j, []).append(c.offset)
            kept.extend(accepted)
            for p in range(len(table)):
                if table.labels[p] in labels and self_symmetric(table, p, axis, offset, tol):
                    mirrored_about.setdefault(p, []).append(offset)
    return sorted(kept, key=lambda c: (c.i, c.j, c.axis))


# -- translation groups ----------------------------------------------------------------


def _find(centers: np.ndarray, point: np.ndarray, allowed: np.ndarray, tol: float) -> int | None:
    """Index of an allowed centre within ``tol`` of ``point`` (the nearest), else None."""
    distances = np.where(allowed, np.linalg.norm(centers - point, axis=1), np.inf)
    k = int(distances.argmin())
    return k if distances[k] <= tol else None


def translation_chains(centers: np.ndarray, equivalent: np.ndarray, tol: float) -> set[tuple[int, ...]]:
    """Maximal evenly stepped chains (3 or more) of mutually translated parts (local indices)."""
    chains: set[tuple[int, ...]] = set()
    m = len(centers)
    for i in range(m):
        for j in np.flatnonzero(equivalent[i]):
            step = centers[j] - centers[i]
            if np.linalg.norm(step) <= tol or _find(centers, centers[i] - step, equivalent[i], tol) is not None:
                continue
            chain = [i, int(j)]
            while (k := _find(centers, centers[chain[-1]] + step, equivalent[i], tol)) is not None and k not in chain:
                chain.append(k)
            if len(chain) >= 3:
                chains.add(tuple(chain) if chain[0] < chain[-1] else tuple(reversed(chain)))
    return chains


def translation_candidates(table: PartTable, tol: float) -> list[Group]:
    """Rows of more than 2 same-label parts, each a translated copy of the first, evenly stepped."""
    out: list[Group] = []
    for idx in table.label_groups(3):
        ii, jj = np.nonzero(np.triu(table.congruent(idx, tol), 1))
        if not len(ii):
            continue
        centers, corners = table.centers[idx], table.corners[idx]
        shift = centers[jj] - centers[ii]
        _, error = match_corners(corners[ii] + shift[:, None, :], corners[jj])
        equivalent = np.zeros((len(idx), len(idx)), dtype=bool)
        equivalent[ii, jj] = equivalent[jj, ii] = error <= tol
        for chain in sorted(translation_chains(centers, equivalent, tol)):
            group = _translation_group(table, idx[list(chain)], tol)
            if group is not None:
                out.append(group)
    return out


def _translation_group(table: PartTable, members: np.ndarray, tol: float) -> Group | None:
    centers, corners = table.centers[members], table.corners[members]
    moved = corners[0][None] + (centers - centers[0])[:, None, :]
    perms, errors = match_corners(moved, corners)
    if errors.max() > tol:
        return None
    step = tuple(float(v) for v in centers[1] - centers[0])
    group = Group("translation", tuple(int(m) for m in members), tuple(tuple(int(k) for k in p) for p in perms),
                  step=step)
    return group if _group_error(table, group) <= tol else None


# -- rotation groups -------------------------------------------------------------------


def _plane_basis(axis: int) -> tuple[int, int]:
    """In-plane coordinates (b1, b2) for a rotation about world ``axis``: +angle turns b1 to b2."""
    return (axis + 1) % 3, (axis + 2) % 3


def _circumcentre(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """Centre of the circle through three 2-d points (None when they are collinear)."""
    d = 2.0 * (p[0] * (q[1] - r[1]) + q[0] * (r[1] - p[1]) + r[0] * (p[1] - q[1]))
    if abs(d) < 1e-12:
        return None
    sp, sq, sr = p @ p, q @ q, r @ r
    return np.array([sp * (q[1] - r[1]) + sq * (r[1] - p[1]) + sr * (p[1] - q[1]),
                     sp * (r[0] - q[0]) + sq * (p[0] - r[0]) + sr * (q[0] - p[0])]) / d


def candidate_centres(points: np.ndarray, shape_centre: np.ndarray, tol: float) -> list[np.ndarray]:
    """Where a rotation axis may pierce the plane: the points' centroid (closed loops), the
    shape's centre and the circles through each point and its two nearest neighbours (arcs)."""
    centres = [points.mean(axis=0), shape_centre]
    distances = np.linalg.norm(points[:, None] - points[None], axis=2)
    for i in range(len(points)):
        near = np.argsort(distances[i])[1:3]
        c = _circumcentre(points[i], points[near[0]], points[near[1]])
        if c is not None:
            centres.append(c)
    unique: list[np.ndarray] = []
    for c in centres:
        if all(np.linalg.norm(c - u) > tol for u in unique):
            unique.append(c)
    return unique


def arrangement(angles: np.ndarray, radius: float, tol: float) -> tuple[np.ndarray, float, bool] | None:
    """Order, angle step and closedness of points at ``angles`` on a circle, if evenly spaced.

    Closed: all n cyclic gaps are 2 pi / n. Open arc: after cutting the largest gap the
    remaining gaps are equal.
    """
    n = len(angles)
    order = np.argsort(angles, kind="stable")
    gaps = np.diff(np.r_[angles[order], angles[order[0]] + 2.0 * np.pi])
    angular_tol = tol / radius
    if np.all(np.abs(gaps - 2.0 * np.pi / n) <= angular_tol):
        return order, 2.0 * np.pi / n, True
    cut = int(gaps.argmax()) + 1
    order, gaps = np.roll(order, -cut), np.roll(gaps, -cut)[:-1]
    step = float(gaps.mean())
    if step > angular_tol and np.all(np.abs(gaps - step) <= angular_tol):
        return order, step, False
    return None


def _congruence_classes(congruent: np.ndarray) -> list[np.ndarray]:
    """Greedy classes of parts congruent to a class's first member."""
    free = np.ones(len(congruent), dtype=bool)
    classes = []
    for i in range(len(congruent)):
        if free[i]:
            members = np.flatnonzero(congruent[i] & free)
            free[members] = False
            classes.append(members)
    return classes


def rotation_candidates(table: PartTable, tol: float) -> list[Group]:
    """Rings and arcs of more than 2 same-label parts, rotated copies about an axis-aligned axis."""
    out: dict[frozenset[int], Group] = {}
    lo, hi = table.bounds
    shape_centre = (lo + hi) / 2.0
    for idx in table.label_groups(3):
        congruent = table.congruent(idx, tol)
        for cls in _congruence_classes(congruent):
            if len(cls) < 3:
                continue
            members = idx[cls]
            for axis in range(3):
                b1, b2 = _plane_basis(axis)
                for layer in clusters_1d(table.centers[members, axis], tol):
                    if len(layer) < 3:
                        continue
                    ring_parts = members[layer]
                    points = table.centers[ring_parts][:, [b1, b2]]
                    height = float(table.centers[ring_parts, axis].mean())
                    for centre in candidate_centres(points, shape_centre[[b1, b2]], tol):
                        offsets = points - centre
                        radii = np.linalg.norm(offsets, axis=1)
                        angles = np.arctan2(offsets[:, 1], offsets[:, 0])
                        for ring in clusters_1d(radii, tol):
                            radius = float(radii[ring].mean())
                            if len(ring) < 3 or radius <= tol:
                                continue
                            found = arrangement(angles[ring], radius, tol)
                            if found is None:
                                continue
                            order, angle, closed = found
                            centre3 = np.zeros(3)
                            centre3[[b1, b2]], centre3[axis] = centre, height
                            group = _rotation_group(table, ring_parts[ring][order], centre3, axis, angle, closed, tol)
                            if group is not None:
                                out.setdefault(frozenset(group.members), group)
    return list(out.values())


def _rotation_group(table: PartTable, members: np.ndarray, centre: np.ndarray, axis: int, angle: float,
                    closed: bool, tol: float) -> Group | None:
    """Verify a ring by rotating the first member's corners; start at the smallest id."""
    members = [int(m) for m in members]
    if closed:
        start = members.index(min(members))
        members = members[start:] + members[:start]
    elif members[-1] < members[0]:
        members, angle = members[::-1], -angle
    corners = table.corners[members]
    rotated = np.array([centre + (corners[0] - centre) @ rotation_matrix(AXES[axis], j * angle).T
                        for j in range(len(members))])
    perms, errors = match_corners(rotated, corners)
    if errors.max() > tol:
        return None
    group = Group("rotation", tuple(members), tuple(tuple(int(k) for k in p) for p in perms),
                  center=tuple(float(v) for v in centre), axis=tuple(float(v) for v in AXES[axis]),
                  angle=float(angle), closed=closed)
    return group if _group_error(table, group) <= tol else None


def mirror_explained(group: Group, mirrors: list[Mirror]) -> bool:
    """Whether a quarter-turn ring is better read as axis-aligned mirror pairs."""
    quarter = np.pi / 2.0
    if abs(group.angle / quarter - round(group.angle / quarter)) > 1e-3:
        return False
    members = set(group.members)
    partnered = {m for c in mirrors if c.i in members and c.j in members for m in (c.i, c.j)}
    return partnered == members


# -- assembly --------------------------------------------------------------------------


def _relation(table: PartTable, group: Group, rid: str) -> TranslationSymmetry | RotationSymmetry:
    members = tuple(table.ids[m] for m in group.members)
    if group.kind == "translation":
        return TranslationSymmetry(rid, members, step=group.step, correspondence=group.perms)
    return RotationSymmetry(rid, members, center=group.center, axis=group.axis, angle=group.angle,
                            correspondence=group.perms)


def _group_error(table: PartTable, group: Group) -> float:
    corners = {table.ids[m]: table.corners[m] for m in group.members}
    return float(_relation(table, group, "check").error(corners))


def _reflection(table: PartTable, mirror: Mirror, rid: str) -> ReflectionSymmetry:
    origin = np.zeros(3)
    origin[mirror.axis] = mirror.offset
    return ReflectionSymmetry(rid, (table.ids[mirror.i], table.ids[mirror.j]), tuple(float(v) for v in origin),
                              tuple(float(v) for v in AXES[mirror.axis]), mirror.perm)


def resolve_groups(candidates: list[Group], table: PartTable) -> list[Group]:
    """Disjoint groups, larger first, translation before rotation, then by member ids."""
    ordered = sorted(candidates, key=lambda g: (-len(g.members), GROUP_RANK[g.kind],
                                                tuple(table.ids[m] for m in g.members)))
    used: set[int] = set()
    kept = []
    for group in ordered:
        if used.isdisjoint(group.members):
            kept.append(group)
            used.update(group.members)
    return kept


def detect_symmetries(table: PartTable, tol: float) -> Symmetries:
    """All symmetry relations of a shape's parts, conflicts resolved (module docstring)."""
    mirrors = mirror_candidates(table, tol)
    rotations = [g for g in rotation_candidates(table, tol) if not mirror_explained(g, mirrors)]
    groups = resolve_groups(translation_candidates(table, tol) + rotations, table)
    kept = resolve_mirrors(table, mirrors, groups, tol)

    def by_members(group: Group) -> tuple[str, ...]:
        return tuple(table.ids[m] for m in group.members)

    translations = sorted((g for g in groups if g.kind == "translation"), key=by_members)
    rings = sorted((g for g in groups if g.kind == "rotation"), key=by_members)
    return Symmetries(
        reflections=tuple(_reflection(table, m, f"reflection_{k}") for k, m in enumerate(kept)),
        translations=tuple(_relation(table, g, f"translation_{k}") for k, g in enumerate(translations)),
        rotations=tuple(_relation(table, g, f"rotation_{k}") for k, g in enumerate(rings)),
    )
