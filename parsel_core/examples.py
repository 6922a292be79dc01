"""A small built-in shape of hexahedra, for the demo, the docs and plugin authors' tests.

``tiny_table`` is a table with a top, four legs on the floor, two rails between the
legs and a row of four slats resting on the rails, with all of its relations built by
hand from exact contacts, so tests can state what must hold.
"""

from __future__ import annotations

import itertools

import numpy as np

from parsel_core.cage import point_weights
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import Hexahedron
from parsel_core.part import Part
from parsel_core.relations import Attachment, GroundContact, ReflectionSymmetry, TranslationSymmetry


def box(lo, hi) -> Hexahedron:
    return Hexahedron.from_bounds(lo, hi)


def box_contact_points(a: Hexahedron, b: Hexahedron, tol: float = 1e-9) -> np.ndarray:
    """Corners of the intersection of two axis-aligned boxes: 1, 2, 4 or 8 points.

    The intersection's flat directions decide the kind (reference section 2): flat in
    all three -> a point, two -> a line, one -> a face, none -> a volume.
    """
    lo = np.maximum(a.corners.min(axis=0), b.corners.min(axis=0))
    hi = np.minimum(a.corners.max(axis=0), b.corners.max(axis=0))
    if np.any(hi < lo - tol):
        raise ValueError("boxes do not touch")
    ranges = [[lo[i]] if hi[i] - lo[i] <= tol else [lo[i], hi[i]] for i in range(3)]
    return np.array(list(itertools.product(*ranges)))


def attachment(rid: str, a: Part, b: Part, contact: str = "point", axis: int = 0) -> Attachment:
    """The attachment of two touching axis-aligned parts, with exact cage coordinates.

    ``contact`` is the kind the symmetry order gives (reference section 2): a point
    attachment holds the centre of the contact region, a line attachment the two ends
    of the region's centre line along world ``axis``, a face or volume attachment all
    of the region's corners.
    """
    region = box_contact_points(a.hexahedron, b.hexahedron)
    centre = region.mean(axis=0)
    if contact == "point":
        points = centre[None]
    elif contact == "line":
        lo, hi = centre.copy(), centre.copy()
        lo[axis], hi[axis] = region[:, axis].min(), region[:, axis].max()
        points = np.array([lo, hi])
    else:
        points = region
    wa = point_weights(a.hexahedron.corners, points)
    wb = point_weights(b.hexahedron.corners, points)
    return Attachment(rid, (a.id, b.id), tuple(map(tuple, np.round(wa, 12))), tuple(map(tuple, np.round(wb, 12))))


def corner_correspondence(source: np.ndarray, target: np.ndarray) -> tuple[int, ...]:
    """For each source corner, the nearest target corner (a permutation for true copies)."""
    distances = np.linalg.norm(source[:, None, :] - target[None, :, :], axis=2)
    perm = tuple(int(i) for i in distances.argmin(axis=1))
    if len(set(perm)) != 8:
        raise ValueError("corners do not correspond one to one")
    return perm


def reflection(rid: str, a: Part, b: Part, origin, normal) -> ReflectionSymmetry:
    """Reflection of a onto b about plane (origin, normal), corners matched at rest."""
    relation = ReflectionSymmetry(rid, (a.id, b.id), tuple(map(float, origin)), tuple(map(float, normal)))
    mirrored = relation.reflect(a.hexahedron.corners)
    # correspondence[k]: the corner of b that mirrors corner k of a
    perm = corner_correspondence(mirrored, b.hexahedron.corners)
    return ReflectionSymmetry(rid, (a.id, b.id), relation.origin, relation.normal, perm)


def ground(rid: str, part: Part, height: float = 0.0) -> GroundContact:
    """Ground contact of a part's lowest face (the face at minimum y)."""
    corners = part.hexahedron.corners
    points = corners[np.abs(corners[:, 1] - corners[:, 1].min()) < 1e-12]
    weights = point_weights(corners, points)
    return GroundContact(rid, (part.id,), tuple(map(tuple, np.round(weights, 12))), height)


def tiny_table() -> ShapeGraph:
    """Top, 4 legs, 2 rails and a row of 4 slats: 11 parts, 26 relations."""
    top = Part("top", "top", box((-0.5, 0.7, -0.3), (0.5, 0.75, 0.3)))
    legs = [
        Part(f"leg_{name}", "leg", box((x - 0.025, 0.0, z - 0.025), (x + 0.025, 0.7, z + 0.025)))
        for name, (x, z) in {"bl": (-0.45, -0.25), "br": (0.45, -0.25), "fl": (-0.45, 0.25),
                             "fr": (0.45, 0.25)}.items()
    ]
    rails = [Part(f"rail_{side}", "rail", box((-0.425, 0.2, z - 0.01), (0.425, 0.24, z + 0.01)))
             for side, z in (("back", -0.25), ("front", 0.25))]
    slats = [Part(f"slat_{i}", "slat", box((x - 0.03, 0.24, -0.26), (x + 0.03, 0.26, 0.26)))
             for i, x in enumerate((-0.3, -0.1, 0.1, 0.3))]
    parts = [top, *legs, *rails, *slats]
    bl, br, fl, fr = legs
    relations = [
        reflection("reflect_legs_back", bl, br, (0, 0, 0), (1, 0, 0)),
        reflection("reflect_legs_front", fl, fr, (0, 0, 0), (1, 0, 0)),
        reflection("reflect_legs_left", bl, fl, (0, 0, 0), (0, 0, 1)),
        reflection("reflect_legs_right", br, fr, (0, 0, 0), (0, 0, 1)),
        reflection("reflect_rails", rails[0], rails[1], (0, 0, 0), (0, 0, 1)),
        TranslationSymmetry("slat_row", tuple(s.id for s in slats), step=(0.2, 0.0, 0.0),
                            correspondence=tuple(tuple(range(8)) for _ in slats)),
    ]
    # Contact kinds follow the symmetry order (reference section 2): a leg's top sits
    # off-centre on the table top (order 0: a point); a rail's end is centred on its leg
    # in z, and a slat crosses a rail centred in x (order 1: a line).
    relations += [attachment(f"attach_top_{leg.id}", top, leg) for leg in legs]
    relations += [ground(f"ground_{leg.id}", leg) for leg in legs]
    relations += [attachment(f"attach_{rail.id}_{leg.id}", rail, leg, "line", axis=2)
                  for rail, pair in ((rails[0], (bl, br)), (rails[1], (fl, fr))) for leg in pair]
    relations += [attachment(f"attach_{slat.id}_{rail.id}", slat, rail, "line", axis=2)
                  for slat in slats for rail in rails]
    return ShapeGraph(parts, relations, name="tiny_table", source="builtin:tiny_table")


#: A hand-written "widen the table" program for ``tiny_table`` that keeps all 26 relations:
#: the top stretches, the legs move out (mirrored), the rails stretch to meet the legs
#: and the slats spread so they stay on the rails.
WIDEN_TINY_TABLE = """\
param x in [0, 0.5] default 0.25
scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)
translate(leg_br, dir=(1, 0, 0), amount=0.45 * x)
translate(leg_fr, dir=(1, 0, 0), amount=0.45 * x)
translate(leg_bl, dir=(-1, 0, 0), amount=0.45 * x)
translate(leg_fl, dir=(-1, 0, 0), amount=0.45 * x)
scale_1d(rail_back, origin=(0, 0.22, -0.25), dir=(1, 0, 0), amount=18 * x / 17)
scale_1d(rail_front, origin=(0, 0.22, 0.25), dir=(1, 0, 0), amount=18 * x / 17)
translate(slat_0, dir=(-1, 0, 0), amount=0.3 * 18 * x / 17)
translate(slat_1, dir=(-1, 0, 0), amount=0.1 * 18 * x / 17)
translate(slat_2, dir=(1, 0, 0), amount=0.1 * 18 * x / 17)
translate(slat_3, dir=(1, 0, 0), amount=0.3 * 18 * x / 17)
"""
