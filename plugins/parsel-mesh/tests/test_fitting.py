"""hexahedron_of: tight, canonical, and equivariant under translation and mirroring."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from parsel_core.cage import inverse_trilinear
from parsel_core.hexahedron import CORNER_BITS, MIRROR_PERMUTATION
from parsel_mesh.fitting import MIN_THICKNESS, alignment, assign_axes, fit_box, hexahedron_of


def _box_points(extents, rotation=None, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    rotation = np.eye(3) if rotation is None else np.asarray(rotation)
    return trimesh.creation.box(extents=extents).vertices @ rotation.T + np.asarray(offset)


def _reflect(points: np.ndarray, axis: int) -> np.ndarray:
    flip = np.ones(3)
    flip[axis] = -1.0
    return points * flip


def _inside(hexahedron, points, tol=1e-9) -> bool:
    uvw = inverse_trilinear(hexahedron.corners, points)
    return bool(np.all(uvw >= -tol) and np.all(uvw <= 1 + tol))


def test_axis_aligned_box_is_its_bounds_in_canonical_order():
    points = _box_points((0.4, 0.1, 0.2), offset=(1.0, 2.0, 3.0))
    corners = hexahedron_of(points).corners
    lo, hi = points.min(axis=0), points.max(axis=0)
    np.testing.assert_array_equal(corners, np.where(CORNER_BITS == 1, hi, lo))


@pytest.mark.parametrize("seed", range(8))
def test_rotated_box_is_recovered(seed):
    rotation = Rotation.random(random_state=seed).as_matrix()
    extents = np.array([0.5, 0.12, 0.3])
    points = _box_points(extents, rotation, (0.3, -1.0, 2.0))
    hexahedron = hexahedron_of(points)
    assert hexahedron.volume == pytest.approx(np.prod(extents), rel=1e-9)
    assert sorted(hexahedron.extents) == pytest.approx(sorted(extents), rel=1e-9)
    assert _inside(hexahedron, points)
    # u, v, w point along +x, +y, +z as far as the box allows, and form a rotation
    axes = hexahedron.local_axes
    assert np.all(np.diagonal(axes) > 0)
    assert np.linalg.det(axes) == pytest.approx(1.0)


def test_slightly_rotated_box_prefers_the_axis_aligned_box():
    rotation = Rotation.from_euler("y", 0.05, degrees=True).as_matrix()
    points = _box_points((0.3, 0.2, 0.25), rotation)
    np.testing.assert_allclose(hexahedron_of(points).local_axes, np.eye(3), atol=1e-12)
    # with no tolerance the fitted box wins
    assert not np.allclose(hexahedron_of(points, aabb_tolerance=0.0).local_axes, np.eye(3), atol=1e-6)


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("seed", range(6))
def test_mirrored_pairs_get_corresponding_corners(axis, seed):
    rotation = Rotation.random(random_state=100 + seed).as_matrix()
    points = _box_points((0.5, 0.2, 0.1), rotation, (0.7, 0.2, -0.4))
    a = hexahedron_of(points)
    b = hexahedron_of(_reflect(points, axis))
    perm = list(MIRROR_PERMUTATION[axis])
    np.testing.assert_allclose(b.corners[perm], _reflect(a.corners, axis), atol=1e-9)
    np.testing.assert_allclose(b.extents, a.extents, rtol=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_translated_copies_get_identical_corners(seed):
    rotation = Rotation.random(random_state=200 + seed).as_matrix()
    points = _box_points((0.05, 0.4, 0.02), rotation)
    step = np.array([0.06, 0.0, 0.01])
    a, b = hexahedron_of(points), hexahedron_of(points + step)
    np.testing.assert_allclose(b.corners, a.corners + step, atol=1e-9)


def test_upright_cylinder_gets_the_axis_aligned_box():
    cylinder = trimesh.creation.cylinder(radius=0.02, height=0.5, sections=32)
    cylinder.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))  # along y
    hexahedron = hexahedron_of(cylinder.vertices)
    np.testing.assert_allclose(hexahedron.local_axes, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(hexahedron.extents, [0.04, 0.5, 0.04], rtol=1e-9)


def test_tilted_cylinder_follows_its_axis_and_mirrors():
    cylinder = trimesh.creation.cylinder(radius=0.02, height=0.5, sections=32)
    tilt = Rotation.from_euler("xz", [90, 30], degrees=True).as_matrix()  # the axis tilted 30 deg from y
    points = cylinder.vertices @ tilt.T + [0.3, 0.25, 0.1]
    direction = tilt @ [0.0, 0.0, 1.0]
    a = hexahedron_of(points)
    assert abs(a.local_axes[1] @ direction) == pytest.approx(1.0, abs=1e-9)  # v runs along the leg
    assert a.extents[1] == pytest.approx(0.5, rel=1e-9)
    assert _inside(a, points)
    b = hexahedron_of(_reflect(points, 0))
    np.testing.assert_allclose(b.corners[list(MIRROR_PERMUTATION[0])], _reflect(a.corners, 0), atol=1e-9)


def test_flat_part_is_thickened_about_its_plane():
    rng = np.random.default_rng(1)
    points = rng.uniform(-1, 1, (40, 3))
    points[:, 1] = 0.25
    hexahedron = hexahedron_of(points)
    extents = hexahedron.extents
    assert extents[1] == pytest.approx(MIN_THICKNESS * extents.max())
    assert hexahedron.center[1] == pytest.approx(0.25)
    assert hexahedron.volume > 0


def test_tilted_flat_part_is_thickened_along_its_normal():
    rotation = Rotation.from_euler("x", 40, degrees=True).as_matrix()
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0.5], [1, 0, 0.5]], dtype=float) @ rotation.T
    hexahedron = hexahedron_of(points)
    assert sorted(hexahedron.extents)[-2:] == pytest.approx([0.5, 1.0])
    assert _inside(hexahedron, points)


@pytest.mark.parametrize(("points", "fragment"), [
    (np.zeros((0, 3)), "no vertices"),
    (np.ones((4, 3)), "same point"),
    (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]]), "collinear"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 1.0]]), "NaN"),
    (np.zeros((3, 2)), "expected"),
])
def test_degenerate_input(points, fragment):
    with pytest.raises(ValueError, match=fragment):
        hexahedron_of(points)


def test_assign_axes_orders_and_flips():
    axes = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_array_equal(assign_axes(axes), np.eye(3))
    assert alignment(np.eye(3)) == 3.0


def test_assigned_frames_are_rotations():
    for seed in range(300):
        frame = Rotation.random(random_state=seed).as_matrix()
        if seed % 2:
            frame = frame * [1.0, 1.0, -1.0]  # left-handed input
        axes = assign_axes(frame)
        assert np.linalg.det(axes) == pytest.approx(1.0)
        assert np.all(np.diagonal(axes) >= 0)


def test_fit_box_bounds_contain_the_points():
    rotation = Rotation.random(random_state=7).as_matrix()
    points = np.random.default_rng(3).normal(size=(200, 3)) * [0.5, 0.1, 0.2] @ rotation.T
    frame = fit_box(points)
    local = points @ frame.axes.T
    assert np.all(local >= frame.lo - 1e-12) and np.all(local <= frame.hi + 1e-12)
