"""Hexahedra: corner order, feature points, axes and intrinsic symmetry planes."""

import numpy as np
import pytest

from parsel_core.cage import cage_weights, inverse_trilinear, point_weights
from parsel_core.hexahedron import (
    CORNER_NAMES,
    EDGE_NAMES,
    FACE_NAMES,
    FEATURE_POINT_NAMES,
    Hexahedron,
    canonical_feature_name,
    corner_jacobians,
    feature_corners,
)


def test_canonical_corner_order_is_bits_of_u_v_w():
    h = Hexahedron.from_bounds((0, 0, 0), (2, 3, 4))
    expected = [(0, 0, 0), (0, 0, 4), (0, 3, 0), (0, 3, 4), (2, 0, 0), (2, 0, 4), (2, 3, 0), (2, 3, 4)]
    assert h.corners.tolist() == [list(map(float, c)) for c in expected]


def test_27_feature_points_of_a_box():
    h = Hexahedron.from_bounds((0, 0, 0), (2, 2, 2))
    assert len(FEATURE_POINT_NAMES) == 27 and len(FACE_NAMES) == 6 and len(EDGE_NAMES) == 12
    assert np.allclose(h.feature_point("center"), (1, 1, 1))
    assert np.allclose(h.feature_point("v+"), (1, 2, 1))
    assert np.allclose(h.feature_point("u-w+"), (0, 1, 2))
    assert np.allclose(h.feature_point("u+v-w+"), (2, 0, 2))
    assert len({tuple(p) for p in h.feature_points.round(9)}) == 27


def test_feature_names_and_corners():
    assert feature_corners("u+") == (4, 5, 6, 7)
    assert feature_corners("v-") == (0, 1, 4, 5)
    assert feature_corners("u+v-") == (4, 5)
    assert feature_corners("w+v+") == (3, 7)
    assert canonical_feature_name("w+v+") == "v+w+"
    assert [feature_corners(n) for n in CORNER_NAMES] == [(k,) for k in range(8)]
    with pytest.raises(ValueError):
        feature_corners("x+")
    with pytest.raises(ValueError):
        feature_corners("u+u-")


def test_axes_extents_volume_and_rotated_box():
    rotation = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    h = Hexahedron.from_box((1, 2, 3), (2, 4, 6), axes=rotation)
    assert np.allclose(h.extents, (2, 4, 6))
    assert np.allclose(h.local_axes, rotation)
    assert np.isclose(h.volume, 48)
    assert np.allclose(h.center, (1, 2, 3))
    assert np.allclose(h.face_normal("u-"), -rotation[0])


def test_intrinsic_symmetry_planes_drop_with_tapers():
    h = Hexahedron.from_bounds((0, 0, 0), (1, 2, 3))
    assert len(h.intrinsic_symmetry_planes()) == 3
    one_sided = h.corners.copy()
    one_sided[[6, 7]] += (0.3, 0, 0)  # the top u+ edge slides out: only the w plane survives
    assert len(Hexahedron(one_sided).intrinsic_symmetry_planes()) == 1
    symmetric = h.corners.copy()
    symmetric[[6, 7]] += (0.3, 0, 0)
    symmetric[[2, 3]] -= (0.3, 0, 0)  # a symmetric taper keeps the u and w planes
    assert len(Hexahedron(symmetric).intrinsic_symmetry_planes()) == 2


def test_invalid_corners_are_rejected():
    with pytest.raises(ValueError):
        Hexahedron(np.zeros((7, 3)))
    with pytest.raises(ValueError):
        Hexahedron(np.full((8, 3), np.nan))


def test_cage_coordinates_reproduce_points_in_boxes_and_tapers():
    rng = np.random.default_rng(0)
    h = Hexahedron.from_box((0.3, -1, 2), (1, 2, 0.5), axes=np.linalg.qr(rng.normal(size=(3, 3)))[0].T)
    points = h.point_at(rng.uniform(0, 1, size=(40, 3)))
    weights = point_weights(h.corners, points)
    assert np.allclose(weights.sum(axis=1), 1)
    assert np.allclose(weights @ h.corners, points, atol=1e-12)
    tapered = h.corners.copy()
    tapered[[2, 3, 6, 7]] = h.center + 0.6 * (tapered[[2, 3, 6, 7]] - h.center)
    uvw = rng.uniform(0, 1, size=(40, 3))
    points = cage_weights(uvw) @ tapered
    assert np.allclose(inverse_trilinear(tapered, points), uvw, atol=1e-10)


def test_canonical_box_matches_axes_to_world_and_mirrors_to_k_xor_4():
    turned = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    h = Hexahedron.canonical_box((0, 0, 0), (1, 2, 3), turned)
    assert np.allclose(h.local_axes, np.eye(3)) and np.allclose(h.extents, (3, 2, 1))
    tilt = np.linalg.qr(np.array([[1.0, 0.2, 0.1], [-0.2, 1.0, 0.05], [-0.1, -0.05, 1.0]]))[0].T
    tilt *= np.sign(np.diag(tilt))[:, None]
    a = Hexahedron.canonical_box((1.0, 0.5, 0.2), (0.2, 1.0, 0.3), tilt)
    mirror = np.diag([-1.0, 1.0, 1.0])
    b = Hexahedron.canonical_box((-1.0, 0.5, 0.2), (0.2, 1.0, 0.3), tilt @ mirror)
    assert np.allclose(b.corners, (a.corners @ mirror)[[k ^ 4 for k in range(8)]])


def _enclosed_volume(corners: np.ndarray, triangles: np.ndarray) -> float:
    """Signed volume by the divergence theorem: positive when every triangle winds outward."""
    a, b, c = (corners[triangles[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


@pytest.mark.parametrize("axes", [np.eye(3), np.diag([-1.0, 1.0, 1.0]), np.array([[0, 0, 1.0], [1, 0, 0], [0, 1, 0]])])
def test_triangles_wind_outward_for_either_handedness(axes):
    box = Hexahedron.from_box((0.3, -1.0, 2.0), (1.0, 2.0, 3.0), axes)
    triangles = box.triangles()
    assert triangles.shape == (12, 3) and sorted(set(triangles.ravel())) == list(range(8))
    assert _enclosed_volume(box.corners, triangles) == pytest.approx(6.0)


def test_corner_jacobians_of_boxes_mirrors_and_folds():
    box = Hexahedron.from_box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    np.testing.assert_allclose(corner_jacobians(box.corners), np.full(8, 6.0))
    mirrored = Hexahedron.from_box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0), np.diag([-1.0, 1.0, 1.0]))
    np.testing.assert_allclose(corner_jacobians(mirrored.corners), np.full(8, -6.0))
    folded = box.corners.copy()
    folded[7, 1] -= 3.0  # corner u+v+w+ pushed below its v- neighbour (2 lower): its v edge points down
    jacobians = corner_jacobians(folded)
    assert jacobians[7] == pytest.approx(1.0 * -1.0 * 3.0) and np.all(jacobians[:3] > 0)
    # batched: (samples, 8, 3) -> (samples, 8)
    assert corner_jacobians(np.stack([box.corners, mirrored.corners])).shape == (2, 8)


def test_batched_cube_coordinates_are_those_of_one_cage_at_a_time_to_the_last_bit():
    """Newton steps taken for many tapered cages at once give each cage's own result."""
    from parsel_core.cage import batched_cube_coordinates

    rng = np.random.default_rng(3)
    cube = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)
    corners = cube * rng.uniform(0.5, 2.0, (6, 5, 1, 3)) + rng.normal(0, 0.04, (6, 5, 8, 3))
    corners[0, 0] = cube  # a box: the affine solve is exact, no Newton step
    points = rng.uniform(0.0, 1.0, (6, 5, 4, 3))
    got = batched_cube_coordinates(corners, points)
    for index in np.ndindex(6, 5):
        one = batched_cube_coordinates(corners[index][None], points[index][None])[0]
        assert np.array_equal(got[index], one)
        if index != (0, 0):  # a taper: Newton ran, as inverse_trilinear alone runs it
            assert np.array_equal(got[index], inverse_trilinear(corners[index], points[index]))
    assert np.allclose(np.einsum("...nk,...kj->...nj", cage_weights(got), corners), points, atol=1e-10)


def test_approximate_cube_coordinates_are_the_batched_ones_to_within_rounding():
    """Boxes (turned, thin, points inside and out) are solved by the explicit inverse to
    within 1e-14 world units of the LAPACK solves; tapered cages take the same Newton
    steps, bit for bit; a flat cage raises as the exact solve does."""
    from parsel_core.cage import approximate_cube_coordinates, batched_cube_coordinates

    rng = np.random.default_rng(11)
    cube = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], dtype=float)
    m = 400
    turns = np.linalg.qr(rng.normal(size=(m, 3, 3)))[0]
    corners = (cube * rng.uniform(0.005, 2.0, (m, 1, 3))) @ turns.transpose(0, 2, 1) + rng.normal(0, 1, (m, 1, 3))
    corners[:40] += rng.normal(0, 0.03, (40, 8, 3))  # tapers
    points = corners[:, :4] * 0.5 + corners[:, 4:] * 0.5 + rng.normal(0, 0.5, (m, 4, 3))
    got = approximate_cube_coordinates(corners, points)
    exact = batched_cube_coordinates(corners, points)
    assert np.array_equal(got[:40], exact[:40])
    edges = np.linalg.norm(corners[:, [4, 2, 1]] - corners[:, :1], axis=-1)               # (m, 3)
    assert np.abs((got - exact) * edges[:, None, :]).max() < 1e-14
    assert np.abs(got[40:]).max() > 1.5  # some points lie well outside their box
    flat = corners[:3].copy()
    flat[1, 4] = flat[1, 0]  # a cage with no extent along u
    flat[1, 6], flat[1, 5], flat[1, 7] = flat[1, 2], flat[1, 1], flat[1, 3]
    with pytest.raises(np.linalg.LinAlgError):
        approximate_cube_coordinates(flat, points[:3])
