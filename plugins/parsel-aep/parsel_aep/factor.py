"""A box edit's linear part written exactly as ops applied one after another.

The joint pass (cluster.py) solves every part of a cluster as ``p -> p + M (p - c) + t``:
scalings along three orthogonal axes (M's diagonal), shears between them (its
off-diagonal entries) and a translation, all linear in the amounts. Written back as
those same ops, applied in turn, a shear that reads an axis a scaling also changed (or
another shear wrote) adds a product of amounts: a back upright turned with its slat by
shears drifts off it by 1% of its height.

``A = I + M`` is instead factored as ``A = L D U`` (Gaussian elimination without pivoting,
in the axis order with the fewest ops): the upper shears ``U`` are applied first, each
reading an axis no earlier op wrote, then the scalings ``D - I``, then the lower shears
``L`` the same way; the product is exactly ``A``. Amounts become rational in the solved
ones (``u = A_01 / A_00``...). The arithmetic is written once for any number type, so
the same code gives the per-sample values (numpy) that check the closed forms (CAS).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from parsel_aep.candidates import _vec
from parsel_aep.compound import Compound
from parsel_core.ops import EditOp, Scale1D, Scale3D, Shear

#: Basis amounts below this (at every sample) are structural zeros of M.
NEGLIGIBLE = 1e-12
#: A pivot ``D_kk = 1 + scaling`` may not come closer to 0 than this (a part flattened).
MIN_PIVOT = 0.05


def live(f: np.ndarray) -> list[bool]:
    """Per basis amount in ``f`` (S, K): whether it is non-zero at some sample."""
    return [bool(np.abs(f[:, i]).max() > NEGLIGIBLE) for i in range(f.shape[1])]


def has_shears(compound: Compound, f: np.ndarray) -> bool:
    """Whether any shear of ``compound`` has a non-zero amount in ``f`` (S, K)."""
    return any(isinstance(op, Shear) and on for op, on in zip(compound.basis, live(f)))


def frame(compound: Compound) -> np.ndarray:
    """The compound's three orthogonal axes (rows): its Scale1D directions, else the world's."""
    dirs = [np.asarray(op.dir, dtype=float) for op in compound.basis if isinstance(op, Scale1D)]
    return np.array(dirs) if len(dirs) == 3 else np.eye(3)


def _axis(axes: np.ndarray, v) -> int:
    return int(np.argmax(np.abs(axes @ np.asarray(v, dtype=float))))


def _add(a, b):
    return b if a is None else a if b is None else a + b


def _mul(a, b):
    return None if a is None or b is None else a * b


def _sub(a, b):
    return a if b is None else (-b if a is None else a - b)


def linear_map(compound: Compound, amounts: Sequence, live: Sequence[bool], one) -> list[list]:
    """``A = I + M`` in the frame's coordinates (row: output axis, column: input axis);
    ``None`` for a structural zero. ``amounts`` are per basis op, ``live`` says which are
    non-zero, ``one`` is 1 in the amounts' number type."""
    axes = frame(compound)
    a: list[list] = [[one if i == j else None for j in range(3)] for i in range(3)]
    for op, amount, on in zip(compound.basis, amounts, live):
        if not on:
            continue
        if isinstance(op, Scale1D):
            k = _axis(axes, op.dir)
            a[k][k] = _add(a[k][k], amount)
        elif isinstance(op, Scale3D):
            for k in range(3):
                a[k][k] = _add(a[k][k], amount)
        elif isinstance(op, Shear):
            # p += s (n . (p - c)) d: output axis d reads input axis n
            a[_axis(axes, op.dir)][_axis(axes, op.normal)] = _add(a[_axis(axes, op.dir)][_axis(axes, op.normal)],
                                                                 amount)
    return a


def ldu(a: list[list], order: Sequence[int]) -> tuple[list[list], list, list[list]]:
    """Doolittle ``A = L D U`` of ``A`` permuted to ``order`` (``None`` entries are zeros).

    Returns L (strictly lower), D (diagonal) and U (strictly upper) in the permuted order.
    """
    n = len(order)
    p = [[a[order[i]][order[j]] for j in range(n)] for i in range(n)]
    lower = [[None] * n for _ in range(n)]
    upper = [[None] * n for _ in range(n)]
    diag: list = [None] * n
    for k in range(n):
        d = p[k][k]
        for m in range(k):
            d = _sub(d, _mul(_mul(lower[k][m], diag[m]), upper[m][k]))
        diag[k] = d
        for j in range(k + 1, n):
            u = p[k][j]
            for m in range(k):
                u = _sub(u, _mul(_mul(lower[k][m], diag[m]), upper[m][j]))
            upper[k][j] = None if u is None else u / d
            v = p[j][k]
            for m in range(k):
                v = _sub(v, _mul(_mul(lower[j][m], diag[m]), upper[m][k]))
            lower[j][k] = None if v is None else v / d
    return lower, diag, upper


def _ops(compound: Compound, order: Sequence[int], lower, diag, upper, one) -> list[tuple[EditOp, object]]:
    """The factors as ops in the order they apply: U's shears, the scalings, L's shears."""
    axes = frame(compound)
    c = next(op.origin for op in compound.basis if hasattr(op, "origin"))
    part = compound.operand
    out: list[tuple[EditOp, object]] = []

    def shear(write: int, read: int, amount) -> None:
        if amount is not None:
            out.append((Shear(part, "f", origin=c, normal=_vec(axes[order[read]]), dir=_vec(axes[order[write]])),
                        amount))

    # U: rows top-down (each shear writes an axis and reads later ones, which nothing wrote yet)
    for i in range(3):
        for j in range(i + 1, 3):
            shear(i, j, upper[i][j])
    for k in range(3):
        if diag[k] is not None:
            out.append((Scale1D(part, "f", origin=c, dir=_vec(axes[order[k]])), diag[k] - one))
    # L: rows bottom-up (each shear writes an axis and reads earlier ones, still as D left them)
    for i in (2, 1):
        for j in range(i):
            shear(i, j, lower[i][j])
    return out


def choose_order(compound: Compound, f: np.ndarray) -> tuple[int, ...] | None:
    """The axis order whose factors need the fewest ops, or ``None`` when every order
    passes a pivot near zero somewhere in the range."""
    a = linear_map(compound, list(f.T), live(f), np.ones(f.shape[0]))
    best = None
    for order in itertools.permutations(range(3)):
        with np.errstate(all="ignore"):
            lower, diag, upper = ldu(a, order)
        if any(d is None or not np.all(np.abs(d) > MIN_PIVOT) for d in diag):
            continue
        values = [v for v in (*diag, *itertools.chain(*lower), *itertools.chain(*upper)) if v is not None]
        if not all(np.all(np.isfinite(v)) for v in values):
            continue
        count = sum(np.abs(v).max() > NEGLIGIBLE for v in itertools.chain(*lower, *upper) if v is not None)
        count += sum(np.abs(d - 1.0).max() > NEGLIGIBLE for d in diag)
        if best is None or count < best[0]:
            best = (count, order)
    return None if best is None else best[1]


def factor(compound: Compound, amounts: Sequence, live: Sequence[bool], order: Sequence[int],
           one) -> list[tuple[EditOp, object]]:
    """The linear part of ``compound`` (translations left out) as ``(op, amount)`` pairs in
    the order they apply, the amounts in the number type of ``amounts`` (floats, arrays or
    CAS expressions)."""
    lower, diag, upper = ldu(linear_map(compound, amounts, live, one), order)
    return _ops(compound, order, lower, diag, upper, one)
