"""Neighbouring parts re-solved together: the joint pass after the part-by-part loop.

The loop of the paper decides one part at a time against the parts decided before it.
On real shapes two undecided neighbours often constrain each other: a short apron
between a stretched long apron and the top, the rails between a copied scaling and a
rigid side. Whichever is decided first may leave the other no edit that keeps both,
and a breaking-edit follows. Here the parts around the relations still broken are
given a box edit each (scalings along their own axes about their centres, then a
translation) and all amounts are solved in one linear least-squares system.

Every relation residual is linear in the corners and every basis op is linear in its
amount on the rest corners, so with ``S`` the (B, K) residual slopes of the B basis
amounts the system is ``r0(x) + f(x) S = 0``: the minimum-displacement solution
``f(x) = -pinv(S^T) r0(x)`` is a fixed linear map of the residuals, and ``r0`` is an
expression of the parameter, so every amount has a closed form (the same as a
:mod:`compound` candidate, across parts). Basis amounts are weighted by how far they
move the part's corners, so among the edits that keep everything the one that moves
the shape least is taken. Relations the system cannot keep are dropped one at a time,
largest error first (a breaking-edit over the cluster), and the result replaces the
cluster's edits only when the whole shape's error goes down.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from parsel_aep.candidates import _vec
from parsel_aep.compound import Compound, orthogonal_axes, translations
from parsel_aep.screening import _Batch, relation_max_errors, residual_slices
from parsel_core.blas import forget_libraries, one_blas_thread
from parsel_core.ops import Scale1D, Scale3D, Shear
from parsel_core.relations import Relation

#: A basis amount moving a part less than this fraction of the shape's size is left out.
_NEGLIGIBLE = 1e-9
#: The simplest edit that keeps the relations is preferred (the paper's simplicity order):
#: a unit of displacement by a scaling costs twice a translation's, by a shear four times.
COSTS = {"translate": 1.0, "scale_1d": 2.0, "scale_3d": 2.0, "shear": 4.0}


@dataclass
class ClusterSystem:
    """The joint linear system of a cluster of parts, at every sample."""

    parts: tuple[str, ...]
    compounds: tuple[Compound, ...]
    blocks: tuple[slice, ...]       # each part's columns in the basis
    constraints: tuple[Relation, ...]
    slices: tuple[slice, ...]       # each constraint's residual columns
    r0: np.ndarray                  # (S, K) residuals with the cluster at rest
    slopes: np.ndarray              # (B, K) residual change per unit basis amount
    weights: np.ndarray             # (B,) corner displacement per unit basis amount
    costs: np.ndarray               # (B,) preference: translations, then scalings, then shears
    allowances: np.ndarray          # (R,) each constraint's allowed drift
    #: :func:`solver`'s matrices by their inputs: the passes of :func:`solve` meet the same
    #: system again (a kept set both drops reach, reweighting that has settled).
    solved: dict = field(default_factory=dict, repr=False, compare=False)

    # What the solves read again and again, made once per system (read-only).

    @functools.cached_property
    def costed(self) -> np.ndarray:
        """``displacement x cost`` per basis amount, 0 for amounts that move nothing."""
        return _frozen(np.where(self.weights > _NEGLIGIBLE, self.weights * self.costs, 0.0))

    @functools.cached_property
    def prior(self) -> np.ndarray:
        """``1 / (displacement x cost)`` per basis amount: what the least-squares solution weighs."""
        c = self.costed
        return _frozen(np.where(c > 0, 1.0 / np.where(c > 0, c, 1.0), 0.0))

    @functools.cached_property
    def sizes(self) -> np.ndarray:
        """Each constraint's number of residual columns."""
        return _frozen(np.array([s.stop - s.start for s in self.slices], dtype=int))

    @functools.cached_property
    def starts(self) -> np.ndarray:
        """Each constraint's first residual column."""
        return _frozen(np.array([s.start for s in self.slices], dtype=int))


def _frozen(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


#: box_compound's bases by (part, rest corners, frame, shears): the joint pass builds the same
#: parts' bases for every variant and ring (bounded; cleared when full).
_BOXES: dict[tuple, Compound] = {}
_BOXES_SIZE = 1024


def box_compound(part: str, hexahedron, frame: str = "local", shears: bool = False) -> Compound:
    """Scalings about the part's centre along three orthogonal axes, then translations.

    ``frame`` ``local`` scales along the part's own axes (a box stays a box), ``world``
    along the global axes (a tilted brace between two parts stretched along z follows
    them as a parallelepiped). A skewed part is scaled uniformly instead. ``shears`` adds
    the six shears between those axes, applied after the scalings: a stretcher between two
    legs that grow by slightly different amounts must tilt with them. (A shear reading an
    axis that a scaling also changed adds a product of amounts, which the final check
    measures; the scalings and shears of one part are rarely both needed.) The same basis
    (frozen ops) is returned for the same part, box, frame and shears.
    """
    key = (part, np.asarray(hexahedron.corners, dtype=float).tobytes(), frame, shears)
    known = _BOXES.get(key)
    if known is None:
        if len(_BOXES) >= _BOXES_SIZE:
            _BOXES.clear()
        known = _BOXES[key] = _box_compound(part, hexahedron, frame, shears)
    return known


def _box_compound(part: str, hexahedron, frame: str, shears: bool) -> Compound:
    c = _vec(hexahedron.center)
    axes = list(np.eye(3)) if frame == "world" else orthogonal_axes(hexahedron)
    if axes is None:
        scales: tuple = (Scale3D(part, "f", origin=c),)
        axes = list(np.eye(3))
    else:
        scales = tuple(Scale1D(part, "f", origin=c, dir=_vec(a)) for a in axes)
    tilts = tuple(Shear(part, "f", origin=c, normal=_vec(axes[i]), dir=_vec(axes[j]))
                  for i in range(3) for j in range(3) if i != j) if shears else ()
    return Compound(part, (*scales, *tilts, *translations(part)), "free_box")


def aligned(hexahedron) -> bool:
    """Whether the part's own axes are the global axes (up to order and sign)."""
    return bool(np.allclose(np.abs(np.asarray(hexahedron.local_axes)).max(axis=1), 1.0, atol=1e-6))


def build_system(parts: Sequence[str], hexahedra: Mapping[str, object], rest: Mapping[str, np.ndarray],
                 corners: Mapping[str, np.ndarray], constraints: Sequence[Relation],
                 tolerance: float, frame: str = "local", shears: bool = False,
                 translate_only: frozenset[str] = frozenset(),
                 members: Mapping[str, tuple[str, ...]] | None = None, memo: dict | None = None) -> ClusterSystem:
    """Residual slopes of every part's box basis against ``constraints``.

    ``corners``: (S, 8, 3) corners of every part at the samples with the cluster's parts
    at rest; ``rest``: (8, 3) rest corners; ``translate_only``: parts hinted to translate
    (their other basis amounts are left out); ``members``: for a repeated group edited
    through its virtual parent, the parts its ops move (each the same point map).
    ``memo`` (a dict kept by the caller for one shape at rest) remembers each basis's
    moved corners and its slopes on each constraint: they depend only on the rest shape,
    and the joint pass builds the same parts' systems for every variant and ring.
    """
    def residuals(view, which=None) -> np.ndarray:
        blocks = [np.asarray(r.residual(view), dtype=float) for r in (constraints if which is None else which)]
        lead = np.broadcast_shapes(*(b.shape[:-1] for b in blocks))
        return np.concatenate([b if b.shape[:-1] == lead else np.broadcast_to(b, lead + b.shape[-1:])
                               for b in blocks], axis=-1)

    involved = {m for r in constraints for m in r.members}
    r0 = np.nan_to_num(residuals({m: corners[m] for m in involved}), nan=0.0, posinf=0.0, neginf=0.0)
    still = {m: rest[m][None] for m in involved}
    base = residuals(still)[0]
    slices = residual_slices(constraints, rest)
    compounds, blocks, slopes, weights, costs = [], [], [], [], []
    column = 0
    memo = {} if memo is None else memo
    for part in parts:
        compound = box_compound(part, hexahedra[part], frame, shears)
        targets = (members or {}).get(part, (part,))
        key = (id(compound), targets)  # (each entry holds its compound and constraint: the ids stay theirs)
        known = memo.get(key)
        if known is None:
            batch = _Batch(compound.basis)
            moved = {m: batch.apply(rest[m], 1.0) for m in targets}                      # (Kp, 8, 3)
            moves = np.sqrt(sum(((moved[m] - rest[m]) ** 2).sum(axis=(-1, -2)) for m in targets)
                            / (8.0 * len(targets)))
            known = memo[key] = (compound, moved, moves)
        _, moved, moves = known
        # Only the constraints on the moved parts change: the others' rows are base - base
        # (a part that none of the constraints reads gets zero slopes, not a missing block).
        slope = np.empty((compound.size, len(base)))
        slope[:] = base - base
        reading = [i for i, r in enumerate(constraints) if set(r.members) & set(targets)]
        fresh = [i for i in reading if (*key, id(constraints[i])) not in memo]
        if fresh:
            changed = residuals({**still, **moved}, [constraints[i] for i in fresh])
            start = 0
            for i in fresh:
                width = slices[i].stop - slices[i].start
                memo[(*key, id(constraints[i]))] = (compound, constraints[i], np.broadcast_to(
                    changed[..., start:start + width] - base[slices[i]], (compound.size, width)))
                start += width
        for i in reading:
            slope[:, slices[i]] = memo[(*key, id(constraints[i]))][2]
        slopes.append(slope)
        if part in translate_only:  # a part hinted to translate keeps its shape
            moves = np.where([op.name == "translate" for op in compound.basis], moves, 0.0)
        weights.append(moves)
        costs.append([COSTS[op.name] for op in compound.basis])
        compounds.append(compound)
        blocks.append(slice(column, column + compound.size))
        column += compound.size
    return ClusterSystem(tuple(parts), tuple(compounds), tuple(blocks), tuple(constraints), tuple(slices), r0,
                         np.concatenate(slopes), np.concatenate(weights), np.concatenate(costs),
                         np.array([r.allowance(tolerance) for r in constraints]))


def _amounts(system: ClusterSystem, matrix: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """``f = -M r0`` at every sample (S, B) for a solver ``M`` over the residual ``columns``."""
    return -(matrix @ system.r0[:, columns].T).T


def _solve_key(columns: np.ndarray, rows: np.ndarray | None, prior: np.ndarray) -> tuple:
    """What a solve on ``columns`` with row weights ``rows`` and ``prior`` is remembered by,
    in :func:`solver`'s memo and in :class:`_Numerics`', where :meth:`_Numerics.settled` and
    :meth:`_Numerics.determined` look up what :meth:`_Numerics.amounts` solved."""
    return columns.tobytes(), None if rows is None else rows.tobytes(), prior.tobytes()


def solver(system: ClusterSystem, columns: np.ndarray, rows: np.ndarray | None = None,
           prior: np.ndarray | None = None) -> np.ndarray:
    """``P pinv(W S^T P) W`` (B, K'): the amounts from the residual columns that minimise
    ``sum (f_j / p_j)^2`` among those meeting the columns (least squares otherwise).

    ``prior`` ``P`` (B,) defaults to :attr:`ClusterSystem.prior` (the least costed
    displacement); a zero leaves that amount out. ``rows`` (K',) weighs the residual
    columns (the same solution when the system can be met exactly).
    """
    p = system.prior if prior is None else prior
    key = _solve_key(columns, rows, p)
    out = system.solved.get(key)
    if out is not None:
        return out
    a = system.slopes[:, columns].T * p                                               # (K', B)
    if rows is not None:
        a = a * rows[:, None]
    norm = _largest(a)
    out = np.linalg.pinv(a / norm, rcond=1e-9) / norm * p[:, None]
    if rows is not None:
        out = out * rows[None, :]
    out.flags.writeable = False
    system.solved[key] = out
    return out


def _largest(a: np.ndarray) -> float:
    """The largest ``|a|``: a system is divided by it before it is solved, and its solution
    scaled back (1e-300 for a zero system, which then stays zero)."""
    return max(float(np.abs(a).max(initial=0.0)), 1e-300)


def relation_errors(system: ClusterSystem, f: np.ndarray) -> np.ndarray:
    """Largest |residual| over the samples, per constraint, for amounts ``f`` (S, B)."""
    return relation_max_errors(system.r0 + f @ system.slopes, system.slices)


def _columns(system: ClusterSystem, kept: Sequence[int]) -> np.ndarray:
    """The residual columns of the ``kept`` constraints, in their order."""
    if not len(kept):
        return np.zeros(0, dtype=int)
    kept = np.asarray(kept, dtype=int)
    sizes = system.sizes[kept]
    # (each constraint's run start, start + 1, ...: a running count less each run's offset)
    return np.arange(int(sizes.sum())) + np.repeat(system.starts[kept] - (np.cumsum(sizes) - sizes), sizes)


class _Borderline(Exception):
    """A decision of the numerical plan too close to call with one BLAS thread's rounding."""


#: What a fast solve may raise instead of deciding: the step is then decided exactly.
_REFUSED = (_Borderline, np.linalg.LinAlgError, FloatingPointError)


class _Numerics:
    """How :func:`solve` solves while it decides: the exact solver, or a fast one.

    The decisions of :func:`solve` (which constraints to drop, which amounts to leave out)
    are discrete, and its result is one last solve fixed by them. The decisions can be
    made with a cheaper solve: least squares on the live amounts only (no pseudo-inverse
    of the whole system), on one BLAS thread, whose last bits differ from the exact
    solver's. ``fast`` numerics raise :class:`_Borderline` whenever a decision is within
    ``MARGIN`` (relative) of going the other way, or a singular value is near pinv's
    cutoff; that step is then decided again with the exact solver (:attr:`exact`). The
    final solve is always the exact one, so the result is the one the exact decisions
    give, bit for bit.
    """

    #: Relative distance from a threshold that a fast decision must keep.
    MARGIN = 1e-6
    #: Relative distance from pinv's cutoff that a fast singular value must keep.
    CUTOFF_MARGIN = 1e-4

    def __init__(self, system: ClusterSystem, fast: bool) -> None:
        self.system, self.fast = system, fast
        self.solved: dict = {}
        self.factored: dict = {}
        self.seen: set = set()
        #: Solves whose matrix was proved to have full column rank (:func:`_conditioned_lstsq`).
        self.conditioned: set = set()
        #: The latest singular values found by a solve on each prior (:meth:`deficient`).
        self.spectra: dict[bytes, list[tuple[np.ndarray, np.ndarray | None, float, float]]] = {}
        self.gathers: dict = {}
        #: Solves made by gelsy (:func:`_orthogonal_lstsq`) rather than gelsd.
        self.orthogonal: set = set()
        self.exact = _Numerics(system, fast=False) if fast else self

    def amounts(self, columns: np.ndarray, rows: np.ndarray | None = None,
                prior: np.ndarray | None = None) -> np.ndarray:
        """The amounts (S, B) of :func:`solver`'s matrix on ``r0``; fast: solved directly by
        least squares on one BLAS thread (LAPACK gelsd, the same minimum-norm solution with
        the same cutoff, or gelsy where it is proved to be that solution: see
        :meth:`settled`), refused near the cutoff, amounts with a zero prior left out."""
        if not self.fast:
            return _amounts(self.system, solver(self.system, columns, rows, prior), columns)
        p = self.system.prior if prior is None else prior
        key = _solve_key(columns, rows, p)
        out = self.solved.get(key)
        if out is None:
            live = np.flatnonzero(p)
            compressed = self.compressed(columns, rows)
            if compressed is not None:  # the same least-squares problem, B rows instead of K'
                r, b = compressed
                a = r[:, live] * p[live]
            else:
                a, b = self.weighted(columns, live, p, rows)                             # (K', B'), (K', S)
            norm = _largest(a)
            scaled = a / norm
            direct = compressed is None
            with one_blas_thread():
                y = None if direct and self.deficient(columns, rows, p, a) else _conditioned_lstsq(scaled, b)
                if y is None:
                    spectrum: list[tuple[float, float, int]] = []
                    try:
                        if direct:
                            y = _orthogonal_lstsq(scaled, b, 1e-9, self.CUTOFF_MARGIN, spectrum)
                            if y is not None:
                                self.orthogonal.add(key)
                        if y is None:
                            y = _guarded_lstsq(scaled, b, 1e-9, self.CUTOFF_MARGIN, spectrum)
                    finally:
                        if direct and spectrum:
                            smallest, largest, count = spectrum[0]
                            self.remember(columns, rows, p, smallest * norm, largest * norm, count)
                else:
                    self.conditioned.add(key)
            out = self.solved[key] = _spread(p, live, y, norm)
        return out

    def settled(self, f: np.ndarray, columns: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        """``f``, or when it is gelsy's solve on these columns and rows (default prior) the
        same solve by gelsd. The drop steps and the L1 fit decide on residuals, which any
        backward-stable solve gives alike; the amounts themselves, along directions near
        pinv's cutoff, agree only to ``~cond u`` (1e-7 at a condition of 1e9), and FOCUSS
        starts from them: it starts from gelsd's, as before."""
        p = self.system.prior
        key = _solve_key(columns, rows, p)
        if key not in self.orthogonal or self.solved.get(key) is not f:
            return f
        live = np.flatnonzero(p)
        a, b = self.weighted(columns, live, p, rows)
        norm = _largest(a)
        try:
            with one_blas_thread():
                y = _guarded_lstsq(a / norm, b, 1e-9, self.CUTOFF_MARGIN)
        except _REFUSED:  # (gelsd would not have decided this step: the exact amounts)
            return self.exact.amounts(columns, rows)
        self.orthogonal.discard(key)
        out = self.solved[key] = _spread(p, live, y, norm)
        return out

    def deficient(self, columns: np.ndarray, rows: np.ndarray | None, p: np.ndarray, a: np.ndarray) -> bool:
        """Whether ``a`` (the weighted system on ``columns``) is proved too ill-conditioned
        for :func:`_conditioned_lstsq`, whose proof would fail: from an earlier solve on the
        same prior and a superset of the columns (the reweighted solves, the drop steps).

        ``a`` is that system's rows, each reweighted: ``a = D S A``, so its smallest singular
        value is at most ``max(D)`` times ``A``'s (removing rows cannot raise it), and its
        largest at least ``|a|_F / sqrt(n)``. When that bounds ``s_min / s_max`` by 1e-6,
        ``a^T a - d I`` with ``d >= (1e-5 s_max)^2`` has an eigenvalue near ``-d``, far
        beyond rounding, and its Cholesky factorisation fails: the solve goes straight to
        the SVD, as it would have after the failed proof.
        """
        m, n = a.shape
        if m < n or n == 0:
            return False
        frobenius = float(np.sqrt(np.einsum("ij,ij->", a, a)))
        for mask, old_rows, s_min, s_max in reversed(self.spectra.get(p.tobytes(), ())):
            if not mask[columns].all():
                continue
            if rows is None and old_rows is None:
                growth = 1.0
            else:
                new = np.ones(len(columns)) if rows is None else rows
                old = np.ones(len(columns)) if old_rows is None else old_rows[columns]
                if not np.all(old > 0):
                    continue
                growth = float((new / old).max())
            # (the SVD's singular values are exact for a matrix within ~n u s_max of A)
            if growth * (s_min + 1e-12 * s_max) * np.sqrt(n) <= 1e-6 * frobenius:
                return True
        return False

    def remember(self, columns: np.ndarray, rows: np.ndarray | None, p: np.ndarray, smallest: float,
                 largest: float, count: int) -> None:
        """Keep bounds from above of the smallest and the largest of the ``count`` singular
        values of the weighted system on ``columns`` (the last two per prior)."""
        if not 0 < np.count_nonzero(p) <= count:  # (fewer rows than amounts: nothing to bound)
            return
        mask = np.zeros(self.system.slopes.shape[1], dtype=bool)
        mask[columns] = True
        full = None
        if rows is not None:
            full = np.zeros(len(mask))
            full[columns] = rows
        kept = self.spectra.setdefault(p.tobytes(), [])
        kept.append((mask, full, float(smallest), float(largest)))
        del kept[:-2]

    def weighted(self, columns: np.ndarray, live: np.ndarray, p: np.ndarray, rows: np.ndarray | None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The least-squares problem of a direct solve: the ``live`` amounts' slopes on
        ``columns`` scaled by the prior ``p``, and the residuals, rows weighted by ``rows``."""
        slopes, r0 = self.gathered(columns, live)
        return _weighted(slopes * p[live], r0, rows)

    def gathered(self, columns: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The slopes (K', B') of the ``live`` amounts on ``columns`` and the residuals there
        (K', S), gathered once: the reweighted solves (IRLS, FOCUSS) read them again."""
        key = (columns.tobytes(), live.tobytes())
        out = self.gathers.get(key)
        if out is None:
            out = self.gathers[key] = (self.system.slopes[np.ix_(live, columns)].T, self.system.r0[:, columns].T)
        return out

    def determined(self, columns: np.ndarray, rows: np.ndarray | None) -> bool:
        """Whether the kept constraints determine every live amount: the fast solve with the
        default prior on these columns and rows was proved to have full column rank."""
        key = _solve_key(columns, rows, self.system.prior)
        return self.fast and key in self.conditioned

    def compressed(self, columns: np.ndarray, rows: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
        """``(R, Q^T b)`` of the weighted system ``A = Q R`` (K' x B, K' at least B) on these
        columns and rows, or ``None``. Solves that differ only in the prior (FOCUSS's
        iterations) scale columns of ``A``: ``min |A P y - b|`` has the minimisers of
        ``min |R P y - Q^T b|`` and ``A P`` the singular values of ``R P`` (Q has orthonormal
        columns), so the QR is made once (at the second solve) and each solve is B x B.
        (Below about 1.6 B rows LAPACK's gelsd bidiagonalises the K' x B system whole, about
        ``4 K' B^2 - 4 B^3 / 3`` flops against ``8 B^3 / 3`` for B x B: FOCUSS's dozen solves
        on one system repay the QR even when K' is little above B.)"""
        key = (columns.tobytes(), None if rows is None else rows.tobytes())
        if key in self.factored:
            return self.factored[key]
        if key not in self.seen:  # factored from the second solve on: most systems are solved once
            self.seen.add(key)
            return None
        out = None
        if len(columns) >= self.system.slopes.shape[0]:
            a, b = _weighted(self.system.slopes[:, columns].T, self.system.r0[:, columns].T, rows)
            with one_blas_thread():
                q, r = np.linalg.qr(a)
                out = (r, q.T @ b)
        self.factored[key] = out
        return out

    def below(self, values: np.ndarray, limits) -> np.ndarray:
        """``values < limits``; fast: refused (:class:`_Borderline`) near equality or for
        values that are not finite."""
        values = np.asarray(values, dtype=float)
        limits = np.broadcast_to(np.asarray(limits, dtype=float), values.shape)
        if self.fast and (not np.all(np.isfinite(values))
                          or np.any(np.abs(values - limits) <= self.MARGIN * np.abs(limits))):
            raise _Borderline
        return values < limits

    def worst(self, ratios: Sequence[tuple[float, int]]) -> tuple[float, int]:
        """``max(ratios)``; fast: refused when the two largest are within the margin."""
        best = max(ratios)
        if self.fast and len(ratios) > 1:
            second = sorted(ratios)[-2]
            if best[0] - second[0] <= self.MARGIN * abs(best[0]):
                raise _Borderline
        return best

    def less(self, a: float, b: float) -> bool:
        """``a < b`` for two error totals; fast: refused when they are within the margin."""
        if self.fast and (not (np.isfinite(a) and np.isfinite(b)) or abs(a - b) <= self.MARGIN * max(abs(a), abs(b))):
            raise _Borderline
        return a < b

    def positive(self, value: float, columns: np.ndarray) -> bool:
        """``value > 0`` for the largest amount; fast: refused for an amount that could be a
        rounding of zero (exactly zero only when the residuals are)."""
        if self.fast:
            if value == 0.0 and not np.any(self.system.r0[:, columns]):
                return False
            if not value > 1e-250:
                raise _Borderline
        return bool(value > 0)


def _spread(p: np.ndarray, live: np.ndarray, y: np.ndarray, norm: float) -> np.ndarray:
    """The amounts (S, B) from a solve ``y`` (B', S) of the ``live`` amounts' system scaled
    by ``1 / norm`` with the prior ``p`` (the others zero)."""
    out = np.zeros((len(p), y.shape[1]))
    out[live] = p[live, None] * y / norm
    return -out.T


def _weighted(a: np.ndarray, b: np.ndarray, rows: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares problem ``min |a y - b|`` with its rows weighted by ``rows``."""
    if rows is None:
        return a, b
    return a * rows[:, None], rows[:, None] * b


def _guarded_lstsq(a: np.ndarray, b: np.ndarray, rcond: float, margin: float,
                   spectrum: list | None = None) -> np.ndarray:
    """``np.linalg.pinv(a, rcond) @ b`` by ``np.linalg.lstsq`` (singular values up to
    ``rcond`` times the largest count as zero in both), refused (:class:`_Borderline`) when
    a singular value is within ``margin`` (relative) of that cutoff. ``(smallest, largest,
    count)`` of the singular values are appended to ``spectrum``."""
    if a.size == 0:
        return np.zeros((a.shape[1], b.shape[1]))
    y, _, _, s = np.linalg.lstsq(a, b, rcond=rcond)
    if spectrum is not None:
        spectrum.append((float(s.min()), float(s.max()), len(s)))
    cutoff = rcond * s.max(initial=0.0)
    if not cutoff > 0:  # a zero matrix (or not finite: refused)
        if np.all(s == 0):
            return np.zeros((a.shape[1], b.shape[1]))
        raise _Borderline
    if np.any(np.abs(s - cutoff) <= margin * cutoff) or not np.all(np.isfinite(y)):
        raise _Borderline
    return y


#: How far the complete orthogonal solution may lie from pinv's, relative: a hundredth of
#: the decisions' margin (:attr:`_Numerics.MARGIN`).
ORTHOGONAL_DRIFT = 1e-8


@functools.cache
def lapack_wrappers():
    """scipy's LAPACK wrappers (its ``scipy.linalg._flapack`` extension), or ``None``.

    Loaded from their file, without the rest of ``scipy.linalg``: importing the package
    takes about 0.36 s of CPU (``numpy.ma`` and most of scipy.linalg with it), the
    extension alone 8 ms, and a command that solves one small shape must not pay the
    former. Where scipy is laid out otherwise the joint pass keeps to numpy's gelsd.
    The extension brings scipy's own OpenBLAS, which :func:`one_blas_thread` must find
    to keep on one thread: a process whose BLAS was not started on one thread calls this
    before entering the solve's block (:func:`~parsel_aep.propagate.propagate`)."""
    import importlib.machinery
    import importlib.util
    from pathlib import Path

    name = "parsel_aep._flapack"  # (its own name: scipy.linalg itself stays unimported)
    try:
        found = importlib.util.find_spec("scipy")
        folder = Path(found.origin).parent / "linalg"
        path = next(folder / f"_flapack{suffix}" for suffix in importlib.machinery.EXTENSION_SUFFIXES
                    if (folder / f"_flapack{suffix}").is_file())
        loader = importlib.machinery.ExtensionFileLoader(name, str(path))
        module = importlib.util.module_from_spec(importlib.util.spec_from_file_location(name, path, loader=loader))
        loader.exec_module(module)
    except (ImportError, AttributeError, StopIteration, OSError):  # (no scipy, or laid out otherwise)
        return None
    if not all(hasattr(module, f) for f in ("dgelsy", "dgelsy_lwork", "dtrtri", "dpotrf", "dposv", "dpotrs")):
        return None
    forget_libraries()
    return module


@functools.lru_cache(maxsize=256)
def _gelsy_work(m: int, n: int, columns: int) -> int:
    """gelsy's workspace for an m x n system with ``columns`` right-hand sides."""
    return int(lapack_wrappers().dgelsy_lwork(m, n, columns, 1e-9)[0])


def _orthogonal_lstsq(a: np.ndarray, b: np.ndarray, rcond: float, margin: float,
                      spectrum: list | None = None) -> np.ndarray | None:
    """``pinv(a, rcond) @ b`` for a tall ``a`` by LAPACK's gelsy (with this certificate about
    0.6 of gelsd's CPU), or ``None`` where its rank is not proved to be pinv's.

    gelsy factors ``a P = Q [R11 R12; 0 R22]`` (QR with column pivoting), keeps the r
    columns it finds independent and solves through ``[R11 R12] = [T11 0] Z``. The SVD
    would keep the same r singular values when, each by ``margin``, the r-th is above
    pinv's cutoff and the next below it: ``s_r(a) >= s_min(T11) >= 1 / |T11^-1|_F`` (rows
    taken away cannot raise a singular value), ``s_(r+1)(a) <= |R22|_F``, and the cutoff
    lies between ``rcond`` times ``a``'s longest column and ``rcond |a|_F``. The two
    minimum-norm solutions then differ by a relative ``~|R22| / s_min(T11)`` (the
    decomposition is of ``a`` less ``R22``), held below :data:`ORTHOGONAL_DRIFT`. The
    drop steps' and the L1 fit's systems mostly pass (an exact null space, the rest well
    conditioned); FOCUSS's priors spread the singular values across the cutoff, so its
    (compressed) solves go to gelsd directly.
    """
    m, n = a.shape
    if m < n or not np.all(np.isfinite(a)):
        return None
    lapack = lapack_wrappers()
    if lapack is None:
        return None
    factors, x, _, rank, info = lapack.dgelsy(a, b, np.zeros(n, dtype=np.int32), rcond,
                                              lwork=_gelsy_work(m, n, b.shape[1]))
    r = int(rank)
    if info != 0 or r == 0:
        return None
    inverse, info = lapack.dtrtri(factors[:r, :r])  # (T11^-1, from the upper triangle only)
    if info != 0:
        return None
    inverse = np.triu(inverse)
    kept = 1.0 / float(np.sqrt(np.einsum("ij,ij->", inverse, inverse)))
    rest = np.triu(factors[r:n, r:n])
    dropped = float(np.sqrt(np.einsum("ij,ij->", rest, rest)))
    frobenius = float(np.sqrt(np.einsum("ij,ij->", a, a)))
    longest = float(np.sqrt(np.einsum("ij,ij->j", a, a).max()))
    y = x[:n]
    if not (kept > (1 + margin) * rcond * frobenius and dropped < (1 - margin) * rcond * longest
            and dropped <= ORTHOGONAL_DRIFT * kept and np.all(np.isfinite(y))):
        return None
    if spectrum is not None:  # (s_n <= |R22| when columns were dropped, else <= T11's least pivot)
        smallest = dropped if r < n else float(np.abs(np.diag(factors)[:r]).min())
        spectrum.append((smallest, frobenius, n))
    return y


#: Smallest singular value over the largest that :func:`_conditioned_lstsq` proves; far
#: above pinv's cutoff (1e-9), so the problem has full rank and the cutoff cannot act.
CONDITIONED = 1e-5


def _conditioned_lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``np.linalg.pinv(a, 1e-9) @ b`` for a tall ``a`` proved well conditioned, by the
    normal equations with one step of refinement (the corrected semi-normal equations),
    or ``None`` when the proof fails.

    The joint systems are tall and sparse, so the Gram matrix ``G = a^T a`` costs a
    fraction of the SVD that ``lstsq`` makes. A Cholesky factorisation of ``G - d I``
    with ``d = CONDITIONED^2 |G|_1 >= CONDITIONED^2 s_max^2`` exists only when
    ``s_min >= CONDITIONED s_max`` (up to rounding of order ``n u s_max^2``, far below
    ``d``): then ``a`` has full column rank, its least-squares solution is unique and
    the refined normal equations give it to a relative ``~cond(a) u`` (Bjorck, *Numerical
    Methods for Least Squares Problems*, 6.6.5), like the SVD does.
    """
    m, n = a.shape
    if m < n or n == 0:
        return None
    # G's diagonal holds the columns' squared norms, and d >= CONDITIONED^2 max diag(G)
    # (both the trace and the largest row sum are at least it): a column shorter than that
    # leaves G - d I a negative diagonal entry, whose Cholesky pivot is negative however it
    # rounds. FOCUSS's priors shrink most columns so; their proof is not even started.
    squares = np.einsum("ij,ij->j", a, a)
    if float(squares.min()) < 0.5 * CONDITIONED * CONDITIONED * float(squares.max()):
        return None
    g = a.T @ a
    top = min(float(np.trace(g)), float(np.abs(g).sum(axis=1).max()))
    if not (np.isfinite(top) and top > 0):
        return None
    if not _positive_definite(g - (CONDITIONED * CONDITIONED * top) * np.eye(n)):
        return None
    lapack = lapack_wrappers()
    if lapack is None:
        try:
            y = np.linalg.solve(g, a.T @ b)
            y += np.linalg.solve(g, a.T @ (b - a @ y))
        except np.linalg.LinAlgError:
            return None
    else:  # (G's own Cholesky factor, made once for both solves: a third of two LU solves)
        factor, y, info = lapack.dposv(g.T, a.T @ b, overwrite_a=1)
        if info != 0:
            return None
        correction, info = lapack.dpotrs(factor, a.T @ (b - a @ y))
        if info != 0:
            return None
        y = y + correction
    return y if np.all(np.isfinite(y)) else None


def _positive_definite(m: np.ndarray) -> bool:
    """Whether the symmetric ``m`` has a Cholesky factorisation (LAPACK's potrf)."""
    lapack = lapack_wrappers()
    if lapack is None:
        try:
            np.linalg.cholesky(m)
        except np.linalg.LinAlgError:
            return False
        return True
    _, info = lapack.dpotrf(m.T, clean=0)  # (m.T: the same matrix, in LAPACK's order)
    return info == 0


def _sparse_breaks(system: ClusterSystem, iterations: int = 12, numerics: _Numerics | None = None) -> list[int]:
    """The constraints to keep, chosen by iteratively reweighted least squares.

    Minimising the sum of the relations' errors (not their squares) breaks few relations
    by a lot rather than many by a little: each pass weighs a relation's rows by
    ``1 / sqrt(its error over its allowance)``.
    """
    numerics = numerics or _Numerics(system, fast=False)
    try:
        return _reweighted(system, iterations, numerics)
    except _REFUSED:
        if not numerics.fast:
            raise
        return _reweighted(system, iterations, numerics.exact)


def _reweighted(system: ClusterSystem, iterations: int, numerics: _Numerics) -> list[int]:
    everything = list(range(len(system.constraints)))
    columns = _columns(system, everything)
    sizes = system.sizes
    relative = np.ones(len(everything))
    for _ in range(iterations):
        weight = 1.0 / (system.allowances * np.sqrt(np.maximum(relative, 1e-3)))
        rows = np.repeat(weight / np.sqrt(sizes), sizes)
        f = numerics.amounts(columns, rows)
        relative = relation_errors(system, f) / system.allowances
    below = numerics.below(relative, 1.0)
    return [i for i in everything if below[i]]


def _row_weights(system: ClusterSystem, kept: Sequence[int]) -> np.ndarray:
    """``1 / allowance`` for each residual column of the ``kept`` constraints: where not
    everything can be met exactly, the error goes to the relations that may drift most (a
    mirror pair detected 1% asymmetric takes 0.1% more before a contact does)."""
    if not len(kept):
        return np.zeros(0)
    kept = np.asarray(kept, dtype=int)
    return np.repeat(1.0 / system.allowances[kept], system.sizes[kept])


def _drop_until_kept(system: ClusterSystem, kept: list[int], numerics: _Numerics | None = None
                     ) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Solve on ``kept``; while a kept constraint fails, drop the worst (error over allowance).

    Each step depends only on the constraints still kept, so a step too close to call with
    fast numerics is decided with the exact ones and the next steps go on fast.
    """
    numerics = numerics or _Numerics(system, fast=False)
    kept = list(kept)
    while True:
        try:
            f, matrix, worst = _drop_step(system, kept, numerics)
        except _REFUSED:
            if not numerics.fast:
                raise
            f, matrix, worst = _drop_step(system, kept, numerics.exact)
        if worst is None:
            return f, matrix, kept
        kept.remove(worst)


def _drop_step(system: ClusterSystem, kept: list[int], numerics: _Numerics):
    """The solve on ``kept`` and the constraint to drop next (``None``: all are kept)."""
    columns = _columns(system, kept)
    if not kept:
        matrix = np.zeros((len(system.weights), 0))
        f = _amounts(system, matrix, columns)
    elif numerics.fast:  # (only the amounts: the matrix is solved exactly once chosen)
        matrix, f = None, numerics.amounts(columns, _row_weights(system, kept))
    else:
        matrix = solver(system, columns, _row_weights(system, kept))
        f = _amounts(system, matrix, columns)
    errors = relation_errors(system, f)
    held = numerics.below(errors[kept], system.allowances[kept]) if kept else np.zeros(0, dtype=bool)
    over = [(errors[i] / system.allowances[i], i) for i, ok in zip(kept, held) if not ok]
    return f, matrix, numerics.worst(over)[1] if over else None


def sparsify(system: ClusterSystem, kept: Sequence[int], f: np.ndarray, iterations: int = 12,
             numerics: _Numerics | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """The same constraints met by as few basis amounts as possible, or ``None``.

    The least-squares solution spreads a little of every basis op over the cluster (a
    stretcher's tilt shared by the legs as 1e-5 shears). Reweighted least squares
    (FOCUSS, with the prior ``sqrt(|g|) / c`` for costed displacements ``g``) drives the
    unneeded amounts to zero; those are left out and the rest solved again exactly.
    ``f`` is the least-costed solution on ``kept`` (exact: fast numerics start from it
    but decide again from the exact one when they cannot decide).
    """
    found = _sparse_prior(system, kept, f, iterations, numerics or _Numerics(system, fast=False))
    if found is None:
        return None
    columns = _columns(system, kept)
    matrix = solver(system, columns, _row_weights(system, kept), prior=found)
    return _amounts(system, matrix, columns), matrix


def _sparse_prior(system: ClusterSystem, kept: Sequence[int], f: np.ndarray, iterations: int,
                  numerics: _Numerics) -> np.ndarray | None:
    """The prior of :func:`sparsify`'s solution (amounts left out are 0), or ``None``."""
    try:
        return _focuss(system, kept, f, iterations, numerics)
    except _REFUSED:
        if not numerics.fast:
            raise
    columns = _columns(system, kept)
    if kept:  # the exact least-costed solution the exact decisions start from
        f = _amounts(system, solver(system, columns, _row_weights(system, kept)), columns)
    return _focuss(system, kept, f, iterations, numerics.exact)


def _focuss(system: ClusterSystem, kept: Sequence[int], f: np.ndarray, iterations: int,
            numerics: _Numerics) -> np.ndarray | None:
    columns = _columns(system, kept)
    rows = _row_weights(system, kept)
    base, c = system.prior, system.costed
    g = np.abs(f * c).max(axis=0)
    if not numerics.positive(g.max(), columns):
        return None
    # With full column rank the least-squares amounts are unique: reweighting the prior
    # (which only chooses among equally good solutions) gives ``f`` back at every step,
    # up to rounding and to pinv's cutoff, far below the thresholds' margins.
    for _ in range(0 if numerics.determined(columns, rows) else iterations):
        f = numerics.amounts(columns, rows, prior=np.sqrt(np.maximum(g, 1e-12 * g.max())) * base)
        g = np.abs(f * c).max(axis=0)
        if not numerics.positive(g.max(), columns):
            return None
    # The amounts left small are dropped, boldly first; the rest is solved again exactly.
    for threshold in (1e-2, 1e-4, 1e-6):
        numerics.below(g, threshold * g.max())  # (fast: refused near the threshold)
        prior = np.where(g > threshold * g.max(), base, 0.0)
        f = numerics.amounts(columns, rows, prior=prior)
        errors = relation_errors(system, f)
        if not kept or numerics.below(errors[list(kept)], system.allowances[list(kept)]).all():
            return prior
    return None


def solve(system: ClusterSystem) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Amounts (S, B), the solver used (B, K') and the constraints kept in the system.

    Two ways to choose what to give up when not everything can be kept: from all the
    constraints, drop the worst one at a time; or start from the ones an L1 fit keeps
    (:func:`_sparse_breaks`). The one keeping more constraints (then less total error)
    wins; the dropped constraints are the cluster's breaking-edits. The amounts are then
    made sparse (:func:`sparsify`).

    The choices are made with fast numerics (one BLAS thread), each again with the exact
    ones when it is too close to call (:class:`_Numerics`); the amounts and the solver
    returned are the exact solve of what was chosen.
    """
    return plan(system).solve()


@dataclass
class Plan:
    """What :func:`solve` keeps, chosen; the sparse amounts are solved on :meth:`solve`.

    Which constraints are kept is known before the amounts are made sparse, and the sparse
    amounts keep the same constraints: a caller ranking clusters by what they give up
    solves only the ones it goes on to use.
    """

    system: ClusterSystem
    kept: list[int]
    f: np.ndarray                   # the least-costed amounts on ``kept`` (fast numerics)
    numerics: _Numerics

    def solve(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """:func:`solve`'s result: the exact sparse amounts, their solver and ``kept``."""
        system, kept = self.system, self.kept
        prior = _sparse_prior(system, kept, self.f, 12, self.numerics)
        columns = _columns(system, kept)
        if not kept:
            matrix = np.zeros((len(system.weights), 0))
        else:
            matrix = solver(system, columns, _row_weights(system, kept), prior)
        return _amounts(system, matrix, columns), matrix, kept


def plan(system: ClusterSystem) -> Plan:
    """The constraints :func:`solve` keeps (its sparse amounts still to solve)."""
    numerics = _Numerics(system, fast=True)
    kept, f = _plan(system, numerics)
    if kept:
        f = numerics.settled(f, _columns(system, kept), _row_weights(system, kept))
    return Plan(system, kept, f, numerics)


def _plan(system: ClusterSystem, numerics: _Numerics) -> tuple[list[int], np.ndarray]:
    """:func:`solve`'s choice of the constraints kept, and the least-costed amounts on them
    that the sparse solution starts from."""
    everything = list(range(len(system.constraints)))
    best = None
    for start in (everything, None):
        if start is None:  # only needed when not everything can be kept
            start = _sparse_breaks(system, numerics=numerics)
            if len(start) < len(best[2]):
                break  # dropping from fewer constraints keeps fewer: it cannot score better
        f, _, kept = _drop_until_kept(system, start, numerics)
        if best is not None and kept == best[2]:
            break  # the same solve: the same score, and the first one stays
        try:
            score = _score(system, f, kept, numerics)
            better = best is None or _better(score, best[0], numerics)
        except _REFUSED:
            if not numerics.fast:
                raise
            f = _exact_amounts(system, kept)
            score = _score(system, f, kept, numerics.exact)
            better = best is None or _better(
                score, _score(system, _exact_amounts(system, best[2]), best[2], numerics.exact), numerics.exact)
        if better:
            best = (score, f, kept)
        if len(kept) == len(everything):
            break
    _, f, kept = best
    return kept, f


def _score(system: ClusterSystem, f: np.ndarray, kept: list[int], numerics: _Numerics) -> tuple[int, float]:
    """Fewest constraints given up, then least total error of the broken ones."""
    errors = relation_errors(system, f) / system.allowances
    numerics.below(errors, 1.0)  # (fast: refused near 1)
    return -len(kept), float(np.sum(errors[errors >= 1.0]))


def _better(score: tuple[int, float], than: tuple[int, float], numerics: _Numerics) -> bool:
    """``score < than``, the totals compared by :meth:`_Numerics.less`."""
    if score[0] != than[0]:
        return score[0] < than[0]
    return numerics.less(score[1], than[1])


def _exact_amounts(system: ClusterSystem, kept: list[int]) -> np.ndarray:
    columns = _columns(system, kept)
    matrix = solver(system, columns, _row_weights(system, kept)) if kept else np.zeros((len(system.weights), 0))
    return _amounts(system, matrix, columns)
