"""Candidates with several amounts: scalings about a free origin, translations in any direction.

A candidate of the paper takes its origin and direction from the part's own 27 feature
points and axes (candidates.py), or from an edited neighbour's (nhbd-edits). On real
shapes that is often not enough: ShapeAssembly shapes are slightly asymmetric, so a rail
spanning two legs must stretch about the midpoint of its contacts, not about one of its
own feature points, and under a 2D scaling of a table top a leg must move diagonally.

A :class:`Compound` is a few basis ops on one part whose amounts are solved jointly.
Every relation residual is linear in each basis amount, and the basis keeps the sum
linear: scalings about the part's centre along orthogonal directions first, then
translations along the global axes (a scaling applied after a translation would add
a product of amounts). Screening solves the amounts by linear least squares at each
sample; the winner is written back as the fewest ops (:func:`simplify`): a scaling about
the origin its amounts imply (``o = c - t_n / g`` along the scaled directions) and one
translation along the direction the rest implies, each amount a closed form.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from parsel_aep.candidates import _vec
from parsel_core.hexahedron import Hexahedron
from parsel_core.ops import EditOp, Scale1D, Scale2D, Scale3D, Shear, Translate

AXES = tuple(tuple(float(v) for v in row) for row in np.eye(3))


@dataclass(frozen=True)
class Compound:
    """Basis ops on one part (scalings first, then translations) with one amount each."""

    operand: str
    basis: tuple[EditOp, ...]
    family: str

    name = "compound"
    feature = None
    acts_on = "part"

    @property
    def size(self) -> int:
        return len(self.basis)

    def apply(self, corners: np.ndarray, amounts, math) -> np.ndarray:
        """Corners after every basis op; ``amounts`` (..., K), one per basis op."""
        amounts = np.asarray(amounts, dtype=float)
        out = corners
        for i, op in enumerate(self.basis):
            out = op.apply(out, amounts[..., i, None, None], math)
        return out


def translations(part: str) -> tuple[EditOp, ...]:
    """Translations of ``part`` along the global axes (the last basis ops of a compound)."""
    return tuple(Translate(part, "f", dir=axis) for axis in AXES)


def orthogonal_axes(hexahedron: Hexahedron) -> list[np.ndarray] | None:
    """The part's unit local axes when they are orthogonal (a box), else ``None``."""
    axes = [np.asarray(a, dtype=float) for a in hexahedron.local_axes]
    axes = [a / np.linalg.norm(a) for a in axes]
    if all(abs(float(axes[i] @ axes[j])) < 1e-6 for i in range(3) for j in range(i + 1, 3)):
        return axes
    return None


def compound_candidates(part: str, hexahedron: Hexahedron, directions: Sequence[np.ndarray],
                        hint: str | None = None) -> list[Compound]:
    """Free-direction translation and free-origin scalings of ``part``, filtered by a hint."""
    c = _vec(hexahedron.center)
    moves = translations(part)
    out: list[Compound] = []
    if hint in (None, "translate"):
        out.append(Compound(part, moves, "free_translate"))
    if hint in (None, "scale"):
        for d in directions:
            out.append(Compound(part, (Scale1D(part, "f", origin=c, dir=_vec(d)), *moves), "free_scale_1d"))
        axes = orthogonal_axes(hexahedron)
        if axes is not None:
            for i in range(3):
                pair = [axes[j] for j in range(3) if j != i]
                out.append(Compound(part, (*(Scale1D(part, "f", origin=c, dir=_vec(a)) for a in pair), *moves),
                                    "free_scale_1d_pair"))
            out.append(Compound(part, (*(Scale1D(part, "f", origin=c, dir=_vec(a)) for a in axes), *moves),
                                "free_box"))
        for n in directions:
            out.append(Compound(part, (Scale2D(part, "f", origin=c, normal=_vec(n)), *moves), "free_scale_2d"))
        out.append(Compound(part, (Scale3D(part, "f", origin=c), *moves), "free_scale_3d"))
    return out


def _constant_ratio(numerator: np.ndarray, denominator: np.ndarray) -> float | None:
    """``numerator / denominator`` when it is the same at every sample where both are non-zero."""
    usable = np.abs(denominator) > 1e-9
    if not usable.any():
        return None
    ratios = numerator[usable] / denominator[usable]
    if np.ptp(ratios) > 1e-7 * max(1.0, float(np.abs(ratios).max())):
        return None
    if np.abs(numerator[~usable]).max(initial=0.0) > 1e-9:
        return None
    return float(np.mean(ratios))


@dataclass(frozen=True)
class Term:
    """One output op of a simplified compound: the op (amount to fill in) and the weights of
    the basis amounts whose combination is its amount."""

    op: EditOp
    weights: tuple[float, ...]


def simplify(compound: Compound, f: np.ndarray, scale: float) -> list[Term]:
    """The fewest ops equal to ``compound`` with the per-sample amounts ``f`` (S, K).

    A scaling ``g`` about the centre ``c`` followed by a translation ``t`` is the same
    scaling about ``o = c - (t . n / g) n`` (along each scaled direction n) when that
    ratio is the same at every sample; the translation left over becomes one translation
    along its direction when that direction is constant, else one per global axis.
    Amounts below ``1e-9 * scale`` everywhere are dropped.
    """
    k = compound.size
    moves = 3
    scales = compound.basis[: k - moves]
    weights = np.eye(k)
    t_weights = weights[k - moves:]                       # rows: x, y, z translation amounts
    t = f[:, k - moves:]                                  # (S, 3)
    terms: list[Term] = []
    for i, op in enumerate(scales):
        g = f[:, i]
        if np.abs(g).max() < 1e-9:
            continue
        if isinstance(op, Shear):  # a shear keeps its origin; what it moves there is left to t
            terms.append(Term(op, tuple(weights[i])))
            continue
        if isinstance(op, Scale1D):
            normals = [np.asarray(op.dir)]
        elif isinstance(op, Scale2D):
            n = np.asarray(op.normal)
            basis = np.linalg.svd(np.eye(3) - np.outer(n, n))[0][:, :2].T
            normals = list(basis)
        else:
            normals = list(np.eye(3))
        centre = np.asarray(op.origin, dtype=float)
        shift = np.zeros(3)
        ok = True
        for n in normals:
            ratio = _constant_ratio(t @ n, g)
            if ratio is None:
                ok = False
                break
            shift += ratio * n
        # An origin far outside the shape reads better as a scaling about the centre and a
        # translation (a seat raised by 0.27 and squashed by 0.0004 is not a scaling about y = 695).
        if ok and np.abs(shift).max() > 0 and np.linalg.norm(shift) <= 2 * max(scale, 1e-12):
            # t . n = g * (c - o) . n: the translation along n is absorbed into the origin
            origin = _vec(centre - shift)
            op = _with_origin(op, origin)
            t = t - np.outer(g, shift)
            t_weights = t_weights - np.outer(shift, weights[i])
        terms.append(Term(op, tuple(weights[i])))
    if np.abs(t).max() < 1e-9 * max(scale, 1.0):
        return terms
    end = t[np.argmax(np.linalg.norm(t, axis=1))]
    direction = end / np.linalg.norm(end)
    if np.abs(t - np.outer(t @ direction, direction)).max() < 1e-9 * max(scale, 1.0):
        terms.append(Term(Translate(compound.operand, "f", dir=_vec(direction)), tuple(direction @ t_weights)))
        return terms
    for axis in range(3):
        if np.abs(t[:, axis]).max() >= 1e-9 * max(scale, 1.0):
            terms.append(Term(Translate(compound.operand, "f", dir=AXES[axis]), tuple(t_weights[axis])))
    return terms


def _with_origin(op: EditOp, origin) -> EditOp:
    return dataclasses.replace(op, origin=origin)
