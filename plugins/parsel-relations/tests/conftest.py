"""Small synthetic shapes with known relations, built from exact boxes (the ``shapes`` fixture)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from parsel_core import Hexahedron, Part, ShapeGraph


def rot_y(angle: float) -> np.ndarray:
    """Right-handed rotation about +y (turns +z towards +x)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def posed_box(center, size, rotation) -> Hexahedron:
    """A box of full ``size`` turned by ``rotation`` (its local axes are the rotation's columns)."""
    return Hexahedron.from_box(center, size, np.asarray(rotation).T)


def bounds(pid: str, label: str, lo, hi) -> Part:
    return Part(pid, label, Hexahedron.from_bounds(lo, hi))


def spokes(count: int = 6, y: float = 0.1) -> ShapeGraph:
    """A hub with ``count`` radial spokes around the y axis (a swivel-chair base)."""
    parts = [bounds("hub", "hub", (-0.1, 0.0, -0.1), (0.1, 0.2, 0.1))]
    for k in range(count):
        angle = 2.0 * np.pi * k / count
        rotation = rot_y(angle)
        center = rotation @ np.array([0.0, y, 0.4])
        parts.append(Part(f"spoke_{k}", "spoke", posed_box(center, (0.06, 0.04, 0.6), rotation)))
    return ShapeGraph(parts, name=f"spokes_{count}")


def mirrored_pair(angle: float = 0.5, label_b: str = "arm") -> ShapeGraph:
    """Two boxes turned about y and z, mirror images about the plane x = 0.2."""
    rotation = rot_y(angle) @ rot_x(0.3)
    a = posed_box((-0.6, 0.5, 0.1), (0.2, 0.1, 0.5), rotation)
    mirror = np.diag([-1.0, 1.0, 1.0])
    corners = a.corners @ mirror
    corners[:, 0] += 0.4
    return ShapeGraph([Part("arm_a", "arm", a), Part("arm_b", label_b, Hexahedron(corners))], name="pair")


def two_rows(count: int = 5) -> ShapeGraph:
    """Two collinear rows of ``count`` slats along x, mirror images of each other about x = 0."""
    parts = [bounds("bar", "bar", (-2.0, 0.0, -0.5), (2.0, 0.1, 0.5))]
    for side, sign in (("l", -1.0), ("r", 1.0)):
        for k in range(count):
            x = sign * (0.5 + 0.3 * k)
            parts.append(bounds(f"slat_{side}{k}", "slat", (x - 0.05, 0.1, -0.4), (x + 0.05, 0.15, 0.4)))
    return ShapeGraph(parts, name="two_rows")


def square_legs() -> ShapeGraph:
    """Four square legs at the corners of a square under a top: mirror pairs, not a ring."""
    parts = [bounds("top", "top", (-0.6, 1.0, -0.6), (0.6, 1.1, 0.6))]
    for name, (x, z) in {"bl": (-0.5, -0.5), "br": (0.5, -0.5), "fl": (-0.5, 0.5), "fr": (0.5, 0.5)}.items():
        parts.append(bounds(f"leg_{name}", "leg", (x - 0.05, 0.0, z - 0.05), (x + 0.05, 1.0, z + 0.05)))
    return ShapeGraph(parts, name="square_legs")


@pytest.fixture
def shapes() -> SimpleNamespace:
    """The builders above, for tests: ``shapes.spokes(6)``, ``shapes.two_rows()``, ..."""
    return SimpleNamespace(rot_y=rot_y, rot_x=rot_x, posed_box=posed_box, bounds=bounds, spokes=spokes,
                           mirrored_pair=mirrored_pair, two_rows=two_rows, square_legs=square_legs)
