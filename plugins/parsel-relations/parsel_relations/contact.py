"""Attachments between touching parts and contacts with the ground (reference section 2).

Two parts are attached when their boxes touch or overlap, or leave a gap of at most the
tolerance. The contact region is the intersection polytope of the two boxes (exact,
from clipping each box's edges against the other), computed without growth first and,
only for parts that do not quite touch, with each box grown by half the tolerance.

The attachment kind is the region's *symmetry order*: for each part, count the part's
intrinsic symmetry planes (``Hexahedron.intrinsic_symmetry_planes``) about which the
region is also symmetric; the order is the smaller count of the two parts, and 0, 1, 2,
3 give a point, line, face or volume attachment (1, 2, 4, 8 point pairs). A part inside
the other is a volume attachment whatever its position.

Contact points. Let ``p`` be the part that sets the order (the one with fewer matching
planes; on a tie the larger part, whose layout the smaller one was placed against). In
``p``'s frame, take the region's box and its centre. The points are that centre moved
to both ends of the region along the normal of each plane ``p`` shares with the region:
a point is the centre; a line joins the two ends of the region across ``p``'s one
shared plane; a face has the 4 corners spanned by the two shared normals; a volume the
region's 8 box corners. The pairs are thus mirror images about ``p``'s shared planes,
and they span the whole contact along those directions: a back standing across the
full width of a seat is held at both ends, so widening the seat widens the back, while
an edit of ``p`` that keeps those planes moves the points symmetrically. A contained
part is held by its own 8 corners.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from parsel_core.cage import point_weights
from parsel_core.hexahedron import Hexahedron
from parsel_core.relations import Attachment, GroundContact
from parsel_relations.geometry import contains, contains_point, intersection_vertices, symmetric_about
from parsel_relations.table import PartTable

KIND_BY_ORDER = ("point", "line", "face", "volume")
#: Growth of the boxes when looking for an exact contact, relative to the shape's size:
#: enough for rounding in the corners, far below any tolerance.
TOUCH_EPSILON = 1e-7
#: A region counts as symmetric about a part's plane within this fraction of the part's
#: thickness across the plane (and within the tolerance).
SYMMETRY_SHARE = 0.25
#: Ground contact points are the corners this close (relative to size) to a part's lowest one.
LEVEL_EPSILON = 1e-6


@dataclass(frozen=True)
class Contact:
    """Parts ``a`` < ``b`` (table indices) touch; ``points`` are the contact points."""

    a: int
    b: int
    kind: str
    points: np.ndarray
    orders: tuple[int, int]


def candidate_pairs(table: PartTable, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs whose world bounds overlap within ``tol`` (a cheap filter before clipping)."""
    lo, hi = table.boxes.world_bounds()
    near = np.all((lo[:, None, :] <= hi[None, :, :] + tol) & (lo[None, :, :] <= hi[:, None, :] + tol), axis=2)
    return np.nonzero(np.triu(near, 1))


def contact_regions(table: PartTable, tol: float, size: float) -> list[tuple[int, int, np.ndarray]]:
    """Touching pairs with the vertices of their contact region."""
    a, b = candidate_pairs(table, tol)
    if not len(a):
        return []
    points, valid = intersection_vertices(table.boxes, a, b, TOUCH_EPSILON * size)
    touching = valid.any(axis=1)
    near = np.flatnonzero(~touching)
    if len(near):
        near_points, near_valid = intersection_vertices(table.boxes, a[near], b[near], tol / 2.0)
        points[near], valid[near] = near_points, near_valid
    return [(int(a[p]), int(b[p]), points[p][valid[p]]) for p in np.flatnonzero(valid.any(axis=1))]


def shared_planes(planes: list[tuple[np.ndarray, np.ndarray]], corners: np.ndarray, region: np.ndarray,
                  tol: float) -> list[np.ndarray]:
    """Normals of the part's symmetry planes about which the region is symmetric too.

    The mismatch allowed is the tolerance, but at most a quarter of the part's thickness
    across the plane: otherwise every plane across a part thinner than the tolerance
    would count, and a panel touched on one face would look symmetrically held.
    """
    shared = []
    for origin, normal in planes:
        thickness = float(np.ptp(corners @ normal))
        if symmetric_about(region, origin, normal, min(tol, SYMMETRY_SHARE * thickness)):
            shared.append(normal)
    return shared


def contact_points(region: np.ndarray, axes: np.ndarray, normals: list[np.ndarray]) -> np.ndarray:
    """The 1, 2, 4 or 8 points of the module docstring: the region's box in the frame
    ``axes`` (rows), its centre pushed to both ends along each shared normal."""
    local = region @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    centre, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    spread = sorted({int(np.abs(axes @ n).argmax()) for n in normals})
    points = []
    for signs in itertools.product((-1.0, 1.0), repeat=len(spread)):
        point = centre.copy()
        for axis, sign in zip(spread, signs):
            point[axis] += sign * half[axis]
        points.append(point)
    return np.array(points) @ axes


def classify(table: PartTable, planes: list[list[tuple[np.ndarray, np.ndarray]]], a: int, b: int,
             region: np.ndarray, tol: float) -> Contact:
    """Kind and points of the contact between parts a and b (module docstring)."""
    for inner, outer in ((a, b), (b, a)):
        if contains(table.boxes, inner, outer, tol) and contains_point(table.boxes, outer, table.centers[inner]):
            return Contact(a, b, "volume", table.corners[inner].copy(), (3, 3))
    shared = [shared_planes(planes[p], table.corners[p], region, tol) for p in (a, b)]
    orders = (len(shared[0]), len(shared[1]))
    volumes = table.boxes.volumes
    if orders[0] != orders[1]:
        setter = 0 if orders[0] < orders[1] else 1
    else:
        setter = 0 if volumes[a] >= volumes[b] else 1
    part = (a, b)[setter]
    points = contact_points(region, table.boxes.axes[part], shared[setter])
    return Contact(a, b, KIND_BY_ORDER[len(points).bit_length() - 1], points, orders)


def symmetry_planes(table: PartTable) -> list[list[tuple[np.ndarray, np.ndarray]]]:
    """Each part's intrinsic symmetry planes (origin, unit normal)."""
    return [Hexahedron(c).intrinsic_symmetry_planes() for c in table.corners]


def detect_contacts(table: PartTable, tol: float, size: float) -> list[Contact]:
    """Every attached pair, in part-id order."""
    regions = contact_regions(table, tol, size)
    if not regions:
        return []
    planes = symmetry_planes(table)
    return [classify(table, planes, a, b, region, tol) for a, b, region in regions]


def _weights(corners: np.ndarray, points: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(v) for v in row) for row in np.round(point_weights(corners, points), 12))


def attachments(table: PartTable, tol: float, size: float) -> list[Attachment]:
    """Attachment relations ``attachment_k``, ordered by member ids, cage weights in both parts."""
    out = []
    for k, contact in enumerate(detect_contacts(table, tol, size)):
        wa = _weights(table.corners[contact.a], contact.points)
        wb = _weights(table.corners[contact.b], contact.points)
        out.append(Attachment(f"attachment_{k}", (table.ids[contact.a], table.ids[contact.b]), wa, wb))
    return out


def ground_contacts(table: PartTable, tol: float, size: float) -> list[GroundContact]:
    """Parts whose lowest corner is within ``tol`` of the shape's floor (lowest y of all parts).

    The contact points are the part's lowest corners (a level bottom face gives 4, a
    tilted one an edge or a corner), and ``height`` is the floor's: a part detected a
    little above the floor has that gap as its rest error, which anchoring turns into its
    allowance (it may drift by as much as detection let it be off), as for every other
    relation detected less exact than the check (docs/relations.md).
    """
    if not len(table):
        return []
    floor = table.bounds[0][1]
    out = []
    for p in range(len(table)):
        heights = table.corners[p][:, 1]
        lowest = heights.min()
        if lowest > floor + tol:
            continue
        chosen = np.flatnonzero(heights <= lowest + LEVEL_EPSILON * max(size, 1e-12))
        weights = tuple(tuple(1.0 if k == c else 0.0 for k in range(8)) for c in chosen)
        out.append(GroundContact(f"ground_{len(out)}", (table.ids[p],), weights, height=float(floor)))
    return out
