"""Proof that no edit of a part can keep its relations: a search that may be skipped.

A candidate edit of one part moves its eight corners by some displacement ``d`` (24
numbers at each sample), and every relation residual is linear in the corners, so the
part's constraints at a sample read ``|r0 + J d| < a`` componentwise (``a`` each
constraint's allowance). Whatever the candidate (own, borrowed, compound, on a face or
an edge), it is some ``d``; if no ``d`` at all meets the constraints at one sample, no
candidate can, and a search for a valid edit finds nothing.

With ``A = J / a`` and ``b = -r0 / a`` the question is whether ``|A d - b| <= 1`` has a
solution. Weak duality (Farkas) gives a certificate that it has none: any ``y`` with
``A^T y = 0`` satisfies ``y . (A d - b) = -y . b`` for every ``d``, which is at most
``|y|_1`` when ``|A d - b| <= 1``; so ``|y . b| > |y|_1`` rules every ``d`` out. The
weighted least-squares residual ``y = W^2 (b - A d_W)`` is such a ``y`` (the normal
equations), and reweighting by the residual concentrates it on the components that no
displacement can bring within bounds.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from parsel_aep.screening import _residuals, _residuals_and_slices
from parsel_core.relations import Relation

#: The certificate must beat ``|y|_1`` by this factor: screening's rounding and the
#: least-squares solve's never come near it.
MARGIN = 1.01
#: Reweighted least-squares passes per sample, and samples tried (those where the part at
#: rest is furthest from its constraints).
ITERATIONS = 4
SAMPLES = 3


def no_displacement_keeps(a: np.ndarray, b: np.ndarray, iterations: int = ITERATIONS) -> bool:
    """Whether ``|a d - b| <= 1`` (componentwise) provably has no solution ``d``.

    ``y`` must be a clear certificate: ``|y|_1`` well above rounding (a consistent system
    leaves a residual of round-off, whose ``y`` proves nothing) and ``a^T y`` zero to
    rounding, so no displacement of a realistic size can make up the margin.
    """
    scale = float(np.abs(a).max(initial=0.0))
    weights = np.ones(len(b))
    for step in range(iterations):
        root = np.sqrt(weights)
        d = np.linalg.lstsq(a * root[:, None], b * root, rcond=None)[0]
        residual = b - a @ d
        if step == 0 and _solves(residual, d, scale):
            return False
        y = weights * residual
        l1 = float(np.abs(y).sum())
        if (abs(float(y @ b)) > MARGIN * l1 and l1 > 1e-3
                and float(np.abs(a.T @ y).max(initial=0.0)) <= 1e-9 * scale * l1):
            return True
        weights = np.maximum(np.abs(residual), 1e-6) ** 2
        weights /= weights.max()
    return False


def _solves(residual: np.ndarray, d: np.ndarray, scale: float) -> bool:
    """Whether the displacement ``d`` (residual ``b - a d``) shows that no ``y`` can pass
    :func:`no_displacement_keeps`' test: it meets every bound (``|a d - b| < 1``) and is
    small enough that ``|y . b| <= |y . (b - a d)| + |a^T y| |d|_1 <= (1 + 1e-9 scale |d|_1)
    |y|_1`` stays below ``MARGIN |y|_1`` whatever ``y`` the test accepts (``|a^T y| <=
    1e-9 scale |y|_1``). The reweighted passes would then prove nothing."""
    return (float(np.abs(residual).max(initial=0.0)) <= 1.0 - 1e-9
            and 1e-9 * scale * float(np.abs(d).sum()) <= 0.5 * (MARGIN - 1.0))


def no_edit_keeps(part: str, rest: np.ndarray, others: Mapping[str, np.ndarray],
                  constraints: Sequence[Relation], allowances: np.ndarray) -> bool:
    """Whether no displacement of ``part``'s corners keeps every one of ``constraints``.

    ``rest``: the part's rest corners (8, 3); ``others``: corners (S, 8, 3) of every other
    member at the samples; ``allowances``: (R,) each constraint's allowed error, as
    screening compares it. ``False`` whenever it cannot tell (removed instances with
    NaN corners, no constraints).
    """
    if not constraints:
        return False
    first = {m: c[0] for m, c in others.items()}
    unit = np.eye(24).reshape(24, 8, 3)
    at_rest, slices = _residuals_and_slices(constraints, {**first, part: rest})
    allowed = np.concatenate([np.full(s.stop - s.start, limit) for s, limit in zip(slices, allowances)])
    moved = _residuals(constraints, {**{m: c[None] for m, c in first.items()}, part: rest[None] + unit})
    jacobian = (moved - at_rest).T                                                       # (K, 24)
    samples = len(next(iter(others.values()))) if others else 1
    r0 = _residuals(constraints, {**others, part: np.broadcast_to(rest, (samples, 8, 3))})
    r0 = np.broadcast_to(r0, (samples, len(allowed)))                                    # (S, K)
    if not (np.all(np.isfinite(jacobian)) and np.all(np.isfinite(r0))):
        return False
    a, b = jacobian / allowed[:, None], -r0 / allowed
    worst = np.argsort(-np.abs(b).max(axis=1), kind="stable")[:SAMPLES]
    return any(no_displacement_keeps(a, b[s]) for s in worst)
