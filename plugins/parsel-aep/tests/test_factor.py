"""The joint pass's box edits written as ops: applied in turn they equal the linear model."""

import numpy as np
import pytest

from parsel_aep import factor
from parsel_aep.cluster import box_compound
from parsel_core.hexahedron import Hexahedron
from parsel_core.ops import Scale1D, Shear


def tilted_box() -> Hexahedron:
    """A box turned about y by 0.3 rad, so its frame is not the world's."""
    c, s = np.cos(0.3), np.sin(0.3)
    axes = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
    unit = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return Hexahedron((unit * [0.4, 0.2, 0.1]) @ axes + [0.5, 1.0, -0.2])


def linear_model(compound, amounts: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """``p + sum_i a_i (op_i(p) - p)``: what the joint system solves for (cluster.build_system)."""
    return corners + sum(a * (op.apply(corners, 1.0, np) - corners) for op, a in zip(compound.basis, amounts))


def applied(pairs, corners: np.ndarray) -> np.ndarray:
    for op, amount in pairs:
        corners = op.apply(corners, amount, np)
    return corners


@pytest.mark.parametrize("seed", range(6))
def test_factored_ops_applied_in_turn_equal_the_linear_model(seed):
    rng = np.random.default_rng(seed)
    hexahedron = tilted_box()
    compound = box_compound("p", hexahedron, "local", shears=True)
    amounts = rng.uniform(-0.3, 0.3, compound.size)
    amounts[rng.random(compound.size) < 0.4] = 0.0          # some structural zeros
    amounts[-3:] = 0.0                                      # translations are not factored
    f = amounts[None]
    order = factor.choose_order(compound, f)
    assert order is not None
    live = [abs(a) > 0 for a in amounts]
    pairs = factor.factor(compound, list(f.T), live, order, np.ones(1))
    expected = linear_model(compound, amounts, hexahedron.corners)
    naive = applied([(op, a) for op, a in zip(compound.basis, amounts) if a], hexahedron.corners)
    got = applied([(op, float(a[0])) for op, a in pairs], hexahedron.corners)
    assert got == pytest.approx(expected, abs=1e-12)
    if any(isinstance(op, Shear) and a for op, a in zip(compound.basis, amounts)):
        assert not np.allclose(naive, expected, atol=1e-6)  # the plain basis order is not exact


def test_one_shear_and_scalings_give_one_shear_and_the_scalings():
    compound = box_compound("p", tilted_box(), "local", shears=True)
    amounts = np.zeros(compound.size)
    amounts[0], amounts[1] = 0.2, -0.1                      # two scalings
    shear = next(i for i, op in enumerate(compound.basis) if isinstance(op, Shear))
    amounts[shear] = 0.25
    f = np.stack([amounts * t for t in (0.0, 0.5, 1.0)])
    order = factor.choose_order(compound, f)
    pairs = factor.factor(compound, list(f.T), factor.live(f), order, np.ones(3))
    kinds = sorted(type(op).__name__ for op, a in pairs if np.abs(a).max() > 1e-12)
    assert kinds == ["Scale1D", "Scale1D", "Shear"]
    for k, t in enumerate((0.0, 0.5, 1.0)):
        corners = tilted_box().corners
        got = applied([(op, float(a[k])) for op, a in pairs], corners)
        assert got == pytest.approx(linear_model(compound, amounts * t, corners), abs=1e-12)


def test_a_scaling_that_flattens_the_part_has_no_factors():
    """A singular linear part: every axis order meets a zero pivot (their product is det A)."""
    compound = box_compound("p", tilted_box(), "local", shears=True)
    amounts = np.zeros(compound.size)
    flatten = next(i for i, op in enumerate(compound.basis) if isinstance(op, Scale1D))
    amounts[flatten] = -1.0
    amounts[next(i for i, op in enumerate(compound.basis) if isinstance(op, Shear))] = 0.2
    f = np.stack([amounts * 0.5, amounts])
    assert factor.has_shears(compound, f)
    assert factor.choose_order(compound, f) is None
    assert factor.choose_order(compound, f[:1]) is not None   # half-way it is not flat yet


def test_a_skewed_part_scaled_uniformly_and_sheared_is_factored_in_world_axes():
    """A part without orthogonal axes gets one uniform scaling in its basis (cluster.py):
    its factors are scalings along the world axes and shears, still exactly the model."""
    skewed = Hexahedron(tilted_box().corners + np.array([[0.0, 0.0, 0.0]] * 7 + [[0.05, 0.02, 0.0]]))
    compound = box_compound("p", skewed, "local", shears=True)
    assert compound.basis[0].name == "scale_3d"
    amounts = np.zeros(compound.size)
    amounts[0] = 0.15
    shears = [i for i, op in enumerate(compound.basis) if isinstance(op, Shear)]
    amounts[shears[0]], amounts[shears[3]] = 0.2, -0.1
    f = amounts[None]
    order = factor.choose_order(compound, f)
    pairs = factor.factor(compound, list(f.T), [a != 0 for a in amounts], order, np.ones(1))
    got = applied([(op, float(a[0])) for op, a in pairs], skewed.corners)
    assert got == pytest.approx(linear_model(compound, amounts, skewed.corners), abs=1e-12)
