"""Vectorised numeric screening of candidate edits (reference section 4, step 4).

Every relation's residual is linear in the corners, so for a candidate op with amount
``f`` applied to the moving parts the residuals over the sampled parameter values are

* ``r(f, x) = r0(x) + f a``                     for translate / scale / shear (affine in f), and
* ``r(f, x) = A cos f + B sin f + gamma(x)``    for rotations (Rodrigues' formula).

``a``, ``A`` and ``B`` come from evaluating the residuals with the candidate applied at
a few fixed amounts (exact, by linearity), so the best amount at every sample and the
remaining error of every candidate are a handful of array operations. Only the
survivors go to the CAS for their closed form.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from itertools import chain
from types import SimpleNamespace

import numpy as np

from parsel_aep.compound import Compound
from parsel_core.hexahedron import feature_corners
from parsel_core.ops import EditOp, Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate
from parsel_core.relations import Relation

NUMPY_MATH = SimpleNamespace(sin=np.sin, cos=np.cos)


@dataclass
class Screened:
    """A candidate with its amount at every sample and what it leaves broken."""

    op: EditOp
    index: int
    f: np.ndarray           # (S,) amount at each sample
    broken: tuple[str, ...]  # constraint relations still violated
    kind: str               # "affine", "rotation" or "compound"
    a: np.ndarray           # affine: (K,) slope; rotation: (K, 2) [A B]; compound: (B, K) basis slopes
    offset: np.ndarray      # rotation: (K,) the constant part A is measured against
    errors: np.ndarray | None = None  # (R,) largest error of each constraint over the samples
    #: Total error of the constraints left broken, infinite if one is not finite (0 when
    #: none is): breaking-edits compare it (:attr:`ScreenTable.cost`).
    cost: float = 0.0


def _residuals(relations: Sequence[Relation], corners: Mapping[str, np.ndarray]) -> np.ndarray:
    return np.concatenate([np.asarray(r.residual(corners), dtype=float) for r in relations], axis=-1)


def _residuals_and_slices(relations: Sequence[Relation], corners: Mapping[str, np.ndarray]
                          ) -> tuple[np.ndarray, list[slice]]:
    """:func:`_residuals` and :func:`residual_slices` from one evaluation."""
    blocks = [np.asarray(r.residual(corners), dtype=float) for r in relations]
    out, start = [], 0
    for block in blocks:
        out.append(slice(start, start + block.shape[-1]))
        start += block.shape[-1]
    return np.concatenate(blocks, axis=-1), out


def residual_slices(relations: Sequence[Relation], corners: Mapping[str, np.ndarray]) -> list[slice]:
    """Each relation's columns in the concatenated residual (corners of any batch shape)."""
    out, start = [], 0
    for r in relations:
        size = np.asarray(r.residual(corners)).shape[-1]
        out.append(slice(start, start + size))
        start += size
    return out


def _apply_all(ops: Sequence[EditOp], rest: np.ndarray, amount: float) -> np.ndarray:
    """Every op applied to the rest corners (8, 3) at one amount: (N, 8, 3)."""
    return _Batch(ops).apply(rest, amount)


def apply_each(ops: Sequence[EditOp], rest: np.ndarray, amounts: Sequence[float]) -> np.ndarray:
    """Each op applied to the rest corners (8, 3) at its own amount: (N, 8, 3), to the bit
    ``np.stack([op.apply(rest, amount, np) ...])``. The ops are batched (products and sums,
    element by element the same); a rotation's sine and cosine are taken one angle at a
    time, as its own ``apply`` takes them (numpy's sines of an array may round differently
    from one angle's)."""
    return _Batch(ops).apply(rest, np.asarray(amounts, dtype=float))


class _Batch:
    """Ops applied together: those of one class at once, whatever feature each moves
    (:func:`_apply_batch`, their vector fields gathered once for every amount and part),
    any other op (an :class:`~parsel_aep.propagate.AnchorScale`) by its own ``apply``."""

    def __init__(self, ops: Sequence[EditOp]) -> None:
        self.ops = list(ops)
        groups: dict[type, list[int]] = {}
        self.single: list[int] = []
        for i, op in enumerate(self.ops):
            if type(op) in _BATCHED:
                groups.setdefault(type(op), []).append(i)
            else:
                self.single.append(i)
        self.groups = [(kind, index, _fields(kind, [self.ops[i] for i in index]),
                        _moved_corners([self.ops[i].feature for i in index]))
                       for kind, index in groups.items()]

    def apply(self, rest: np.ndarray, amount: float | np.ndarray) -> np.ndarray:
        """Every op at ``amount``, or each at its own (``amount`` of shape (N,))."""
        each = np.ndim(amount) == 1
        out = np.empty((len(self.ops), 8, 3))
        for i in self.single:
            out[i] = self.ops[i].apply(rest, float(amount[i]) if each else amount, NUMPY_MATH)
        for kind, index, fields, moves in self.groups:
            if not each:
                out[index] = _apply_batch(kind, moves, fields, rest, amount)
                continue
            amounts = np.asarray(amount)[index]
            trig = None
            if kind is Rotate:  # one angle at a time, as Rotate.transform takes them
                angles = amounts.tolist()
                trig = (np.array([NUMPY_MATH.cos(a) for a in angles])[:, None, None],
                        np.array([NUMPY_MATH.sin(a) for a in angles])[:, None, None])
            out[index] = _apply_batch(kind, moves, fields, rest, amounts[:, None, None], trig)
        return out


def _moved_corners(features: Sequence[str | None]) -> np.ndarray | None:
    """Which corners each op moves, (G, 8, 1): all for ops on the whole part (``None`` when
    every op is), its feature's corners for the others."""
    if all(feature is None for feature in features):
        return None
    return np.array([_corner_flags(feature) for feature in features], dtype=bool)[:, :, None]


@cache
def _corner_flags(feature: str | None) -> tuple[bool, ...]:
    """Whether an op on ``feature`` (``None``: the whole part) moves each corner."""
    moved = range(8) if feature is None else _corner_indices(feature)
    return tuple(k in moved for k in range(8))


#: The vector fields each batched class reads, in :func:`_apply_batch`'s order.
_FIELDS = {"Translate": ("dir",), "Rotate": ("origin", "axis"), "Scale1D": ("origin", "dir"),
           "Scale2D": ("origin", "normal"), "Scale3D": ("origin",), "Shear": ("origin", "normal", "dir")}


def _fields(kind: type, ops: Sequence[EditOp]) -> tuple[np.ndarray, ...]:
    return tuple(_column(ops, name) for name in _FIELDS[kind.__name__])


def _column(ops: Sequence[EditOp], name: str) -> np.ndarray:
    """A vector field of every op, shaped (G, 1, 3) to broadcast over the corners."""
    # (read from one flat iterator: a list of tuples makes numpy discover its shape first)
    values = chain.from_iterable([getattr(op, name) for op in ops])
    return np.fromiter(values, dtype=float, count=3 * len(ops)).reshape(len(ops), 1, 3)


def _dot(points: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``parsel_core.ops._dot`` with one vector per op (the same arithmetic, term by term)."""
    return points[..., 0:1] * n[..., 0:1] + points[..., 1:2] * n[..., 1:2] + points[..., 2:3] * n[..., 2:3]


def _cross(n: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``parsel_core.ops._cross`` with one vector per op."""
    x, y, z = points[..., 0:1], points[..., 1:2], points[..., 2:3]
    a, b, c = n[..., 0:1], n[..., 1:2], n[..., 2:3]
    return np.concatenate([b * z - c * y, c * x - a * z, a * y - b * x], axis=-1)


def _apply_batch(kind: type, moves: np.ndarray | None, fields: tuple[np.ndarray, ...], points: np.ndarray,
                 amount: float | np.ndarray, trig: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``np.stack([op.apply(points, amount, NUMPY_MATH) for op in ops])`` for ops of one class,
    given their vector fields (:func:`_fields`, each (G, 1, 3)) and the corners each moves
    (:func:`_moved_corners`), with the operations of each op's ``transform`` in the same
    order, so the result is the same to the last bit: every corner is transformed (element
    by element, as an op on a feature transforms its own corners) and an op on a feature
    keeps the rest of its corners where they are. ``trig``: rotations' cosines and sines
    (G, 1, 1), when taken beforehand."""
    if kind is Translate:
        (d,) = fields
        moved = points + d * amount
    elif kind is Rotate:
        o, axis = fields
        centred = points - o
        cos, sin = trig if trig is not None else (NUMPY_MATH.cos(amount), NUMPY_MATH.sin(amount))
        rotated = centred * cos + _cross(axis, centred) * sin + _dot(centred, axis) * axis * (1 - cos)
        moved = o + rotated
    elif kind is Scale1D:
        o, d = fields
        centred = points - o
        moved = o + centred + _dot(centred, d) * d * amount
    elif kind is Scale2D:
        o, n = fields
        centred = points - o
        along = _dot(centred, n) * n
        moved = o + (centred - along) * (1 + amount) + along
    elif kind is Scale3D:
        (o,) = fields
        moved = o + (points - o) * (1 + amount)
    else:  # Shear
        o, n, d = fields
        centred = points - o
        moved = o + centred + _dot(centred, n) * d * amount
    if moves is None:
        return moved
    return np.where(moves, moved, points)


_BATCHED = frozenset({Translate, Rotate, Scale1D, Scale2D, Scale3D, Shear})


@cache
def _corner_indices(feature: str) -> tuple[int, ...]:
    return feature_corners(feature)


def relation_max_errors(residual: np.ndarray, slices: Sequence[slice]) -> np.ndarray:
    """Max |residual| per relation: (..., R) from (..., S, K)."""
    return slice_maxima(np.abs(residual).max(axis=-2, initial=0.0), slices)


def slice_maxima(values: np.ndarray, slices: Sequence[slice]) -> np.ndarray:
    """``values[..., s].max(initial=0.0)`` for each of the ``slices`` (..., R): one segment
    reduction when they are consecutive and cover the last axis (empty ones give 0)."""
    out = np.zeros(values.shape[:-1] + (len(slices),))
    consecutive = all(a.stop == b.start for a, b in zip(slices, slices[1:])) and (
        not slices or (slices[0].start == 0 and slices[-1].stop == values.shape[-1]))
    if not consecutive:
        for i, s in enumerate(slices):
            out[..., i] = values[..., s].max(axis=-1, initial=0.0)
        return out
    filled = np.array([s.stop > s.start for s in slices], dtype=bool)
    if filled.any():
        starts = np.array([s.start for s in slices], dtype=int)
        out[..., filled] = np.maximum.reduceat(values, starts[filled], axis=-1)
    return out


def _max_abs_per_slice(residual: np.ndarray, slices: Sequence[slice]) -> np.ndarray:
    """:func:`relation_max_errors` of a scratch array (overwritten by its absolute values)."""
    return relation_max_errors(np.abs(residual, out=residual), slices)


@dataclass
class _System:
    """Residuals of every candidate as a function of its amount, over all samples."""

    ids: list[str]
    slices: list[slice]
    affine: list[tuple[int, EditOp]]
    r0: np.ndarray          # (S, K) residuals with nothing moved
    slope: np.ndarray       # (Na, K) affine slopes
    rotations: list[tuple[int, EditOp]]
    matrix: np.ndarray      # (Nr, K, 2) rotation [A B]
    offset: np.ndarray      # (Nr, K) rotation A
    compounds: list = None  # (index, Compound, (B, K) basis slopes)
    rest_errors: np.ndarray = None  # (R,) each constraint's own rest error (its allowance floor)


def _system(candidates: Sequence[EditOp], moving: Mapping[str, np.ndarray], others: Mapping[str, np.ndarray],
            constraints: Sequence[Relation], memo: dict | None = None) -> _System:
    """The residuals of every candidate as a function of its amount.

    ``memo`` (a dict kept by the caller, one per search) remembers each candidate's rows
    for these constraints and corners: a search screens its candidates again when it falls
    back to breaking-edits. A row depends only on its own op (ops are applied and residuals
    evaluated row by row), so it is the same whichever candidates it was computed with.
    """
    key = (tuple(r.id for r in constraints), tuple((m, id(c)) for m, c in others.items()),
           tuple((m, id(c)) for m, c in moving.items()))
    known = memo.setdefault(key, {}) if memo is not None else {}
    shared = known.get(None)
    if shared is None:
        samples = next(iter(others.values())).shape[0] if others else 1
        rest_view = {pid: np.broadcast_to(c, (samples, 8, 3)) for pid, c in moving.items()}
        # Removed instances of a re-laid-out group have NaN corners and are not checked.
        r0 = np.nan_to_num(_residuals(constraints, {**others, **rest_view}), nan=0.0, posinf=0.0, neginf=0.0)
        first = {pid: c[:1][None] for pid, c in others.items()}                 # (1, 1, 8, 3)
        rest_one = {p: c[None, None] for p, c in moving.items()}
        base, slices = _residuals_and_slices(constraints, {**first, **rest_one})
        shared = known[None] = (r0, first, base[0, 0], slices, (others, moving))  # (keeps the ids' arrays alive)
    r0, first, base, slices, _ = shared

    def residual_at(ops, amount):
        batch = ops if isinstance(ops, _Batch) else _Batch(ops)
        moved = {pid: batch.apply(c, amount)[:, None] for pid, c in moving.items()}
        return _residuals(constraints, {**first, **moved})[:, 0]               # (N, K)

    def new(ops: Sequence) -> list:
        return [op for op in ops if known.get(id(op), (None,))[0] is not op]

    affine, rotations, listed = [], [], []
    for i, op in enumerate(candidates):  # (one pass: a search screens hundreds of candidates)
        (rotations if isinstance(op, Rotate) else listed if isinstance(op, Compound) else affine).append((i, op))
    k = r0.shape[-1]
    fresh = new([op for _, op in affine])
    slope = None
    if fresh:
        slope = residual_at(fresh, 1.0) - base
        for op, row in zip(fresh, slope):
            known[id(op)] = (op, row)
    if len(fresh) < len(affine):  # (all fresh: the rows just made, in order)
        slope = np.array([known[id(op)][1] for _, op in affine])
    elif not affine:
        slope = np.zeros((0, k))
    fresh = new([op for _, op in rotations])
    offset = matrix = None
    if fresh:
        ops = _Batch(fresh)
        at0, at90, at180 = (residual_at(ops, angle) for angle in (0.0, np.pi / 2, np.pi))
        offset = (at0 - at180) / 2
        matrix = np.stack([offset, at90 - (at0 + at180) / 2], axis=-1)
        for op, offset_row, matrix_row in zip(fresh, offset, matrix):
            known[id(op)] = (op, (offset_row, matrix_row))
    if len(fresh) < len(rotations):
        offset = np.array([known[id(op)][1][0] for _, op in rotations])
        matrix = np.array([known[id(op)][1][1] for _, op in rotations])
    elif not rotations:
        offset, matrix = np.zeros((0, k)), np.zeros((0, k, 2))
    fresh = new([c for _, c in listed])
    if fresh:  # every new compound's basis in one evaluation
        rows = residual_at([op for c in fresh for op in c.basis], 1.0) - base
        ends = np.cumsum([len(c.basis) for c in fresh])
        for c, end in zip(fresh, ends):
            known[id(c)] = (c, rows[end - len(c.basis):end])
    compounds = [(i, c, known[id(c)][1]) for i, c in listed]
    return _System([r.id for r in constraints], slices, affine, r0, slope, rotations, matrix, offset, compounds,
                   np.array([r.allowance(0.0) for r in constraints]))


def _affine_amounts(r0: np.ndarray, slope: np.ndarray, columns) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares amount per sample using the given residual columns; (N, S) and usable mask."""
    a = slope[:, columns]
    norm = np.einsum("nk,nk->n", a, a)
    usable = norm > 1e-18
    f = -(a @ r0[:, columns].T) / np.where(usable, norm, 1.0)[:, None]
    f[~usable] = 0.0
    return f, usable


def _rotation_amounts_batch(system: _System, columns) -> tuple[np.ndarray, np.ndarray]:
    """Angles (N, S) minimising ``|A c + B s + gamma|`` (normal equations, then normalised)."""
    m = system.matrix[:, columns]                                                        # (N, K, 2)
    gamma = system.r0[None, :, columns] - system.offset[:, None, columns]                 # (N, S, K)
    mt = np.ascontiguousarray(m.transpose(0, 2, 1))                                     # (N, 2, K)
    normal = mt @ m
    usable = np.abs(m).max(axis=(1, 2)) > 1e-12
    normal[~usable] = np.eye(2)
    normal += 1e-15 * np.eye(2)
    rhs = -(mt @ gamma.transpose(0, 2, 1))
    cs = np.linalg.solve(normal, rhs)                                                    # (N, 2, S)
    return np.arctan2(cs[:, 1], cs[:, 0]), usable


def screen(candidates: Sequence[EditOp], moving: Mapping[str, np.ndarray], others: Mapping[str, np.ndarray],
           constraints: Sequence[Relation], tolerance: float) -> list[Screened]:
    """Best amounts and leftover broken relations for every candidate, in order
    (:func:`screen_table`, every row made a :class:`Screened`)."""
    table = screen_table(candidates, moving, others, constraints, tolerance)
    return [table.screened(i) for i in table.order]


def screen_table(candidates: Sequence[EditOp], moving: Mapping[str, np.ndarray], others: Mapping[str, np.ndarray],
                 constraints: Sequence[Relation], tolerance: float, memo: dict | None = None,
                 valid_only: bool = False) -> ScreenTable:
    """Best amounts and leftover broken relations for every candidate, as arrays.

    ``moving``: rest corners (8, 3) of the parts the candidate moves (one part, or all
    members of a group edited through its virtual parent); ``others``: corners (S, 8, 3)
    of every other part the constraints mention, at the S sampled parameter values.
    ``memo``: see :func:`_system`. With ``valid_only`` (a search that takes only candidates
    keeping every constraint) a translation or scaling stops being checked at the first
    constraint it breaks: its other errors are not computed and its count of broken
    constraints is only known to be positive. (Breaking-edits, whose amounts are solved
    from each constraint alone, are screened by :mod:`parsel_aep.breaking`.)
    """
    if not candidates or not constraints:
        return ScreenTable(None, [])
    system = _system(candidates, moving, others, constraints, memo)
    allowed = np.maximum(tolerance, system.rest_errors)
    everything = slice(None)
    blocks: list[_Block] = []
    if system.affine:
        f, usable = _affine_amounts(system.r0, system.slope, everything)
        rows = np.flatnonzero(usable)
        f = f[rows]
        if valid_only:
            errors, broken = _errors_until_broken(system, f, system.slope[rows], allowed)
        else:
            errors = _max_abs_per_slice(_affine_residual(system, rows, f), system.slices)
            broken = ~(errors < allowed)
        blocks.append(_Block("affine", rows, f, errors, broken))
    if system.rotations:
        f_all, usable = _rotation_amounts_batch(system, everything)
        rows = np.flatnonzero(usable)
        f_all = f_all[rows]
        errors = _max_abs_per_slice(_rotation_residual(system, rows, f_all), system.slices)
        blocks.append(_Block("rotation", rows, f_all, errors, ~(errors < allowed)))
    blocks += _compound_blocks(system, everything, allowed)
    return ScreenTable(system, blocks)


def _affine_residual(system: _System, sources: np.ndarray, f: np.ndarray, samples: slice = slice(None)
                     ) -> np.ndarray:
    """``r0 + f a`` (N, S', K) of the affine candidates ``sources`` at amounts ``f`` (N, S), at
    the ``samples``."""
    residual = f[:, samples, None] * system.slope[sources, None, :]
    residual += system.r0[samples]                                                     # in place
    return residual


def _rotation_residual(system: _System, sources: np.ndarray, f: np.ndarray, samples: slice = slice(None)
                       ) -> np.ndarray:
    """``A cos f + B sin f + gamma`` (N, S', K) of the rotations ``sources`` at angles ``f``
    (N, S), at the ``samples``."""
    f = f[:, samples]
    residual = (system.matrix[sources] @ np.stack([np.cos(f), np.sin(f)], axis=1)).transpose(0, 2, 1)
    residual += system.r0[samples]                                                     # (A c + B s + r0) - A
    residual -= system.offset[sources, None, :]
    return residual


def _compound_blocks(system: _System, columns, allowed: np.ndarray) -> list[_Block]:
    """Every compound solved on the residual ``columns``, one block each; only those whose
    errors are all finite."""
    if not system.compounds:
        return []
    amounts = _compound_amounts_each(system.r0, [slopes for _, _, slopes in system.compounds], columns)  # (S, B)
    residuals = np.stack([system.r0 + f @ slopes for f, (_, _, slopes) in zip(amounts, system.compounds)])
    every = relation_max_errors(residuals, system.slices)                              # (C, R) at once
    blocks = []
    for j, f in enumerate(amounts):
        errors = every[j:j + 1]
        if np.isfinite(errors).all():
            blocks.append(_Block("compound", np.array([j]), f[None], errors, ~(errors < allowed)))
    return blocks


def _errors_until_broken(system: _System, f: np.ndarray, slope: np.ndarray, allowed: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The largest errors (N, R) of ``r0 + f a`` and whether each reaches its allowance, one
    constraint at a time for the candidates that have broken none so far (the others keep
    0 for the constraints after the first they break). Per candidate and constraint the
    same arithmetic as the whole residual at once."""
    errors = np.zeros((len(f), len(system.slices)))
    broken = np.zeros(errors.shape, dtype=bool)
    alive = np.arange(len(f))
    for j, columns in enumerate(system.slices):
        if not alive.size:
            break
        if columns.stop <= columns.start:
            continue
        residual = f[alive, :, None] * slope[alive, None, columns]
        residual += system.r0[:, columns]
        worst = np.abs(residual, out=residual).max(axis=(1, 2))
        errors[alive, j] = worst
        held = worst < allowed[j]
        broken[alive, j] = ~held
        alive = alive[held]
    return errors, broken


@dataclass
class _Block:
    """Screened rows of one kind solved from one set of residual columns (only candidates
    that move those columns have an amount, so only they are rows)."""

    kind: str
    sources: np.ndarray  # (N,) each row's candidate: a row of the system's affine, rotations or compounds
    f: np.ndarray        # (N, S) amounts; compound: (1, S, B)
    errors: np.ndarray   # (N, R) largest error of each constraint
    broken: np.ndarray   # (N, R) whether it reaches its allowance


class ScreenTable:
    """Every screened result of one :func:`screen_table` call as arrays, in candidate order
    (:attr:`order`). :class:`Screened` objects are made only for the rows asked for
    (:meth:`screened`): a search reads the valid ones."""

    def __init__(self, system: _System | None, blocks: list[_Block]) -> None:
        self._lay_out(system, blocks)
        counts = [_row_costs(b.broken, b.errors) for b in blocks]
        self.nbroken = np.concatenate([n for n, _ in counts] or [np.zeros(0, int)]).astype(int)
        self.cost = np.concatenate([c for _, c in counts] or [np.zeros(0)])
        self.order = np.argsort(self.index, kind="stable")

    def _lay_out(self, system: _System | None, blocks: list[_Block]) -> None:
        """Each row's block, place in it, candidate index and whether its amounts are finite."""
        self.system, self.blocks = system, blocks
        self._made: dict[int, Screened] = {}
        self.block = np.concatenate([np.full(len(b.sources), i) for i, b in enumerate(blocks)] or [np.zeros(0, int)])
        self.row = np.concatenate([np.arange(len(b.sources)) for b in blocks] or [np.zeros(0, int)])
        if system is not None:
            first = {"affine": np.array([i for i, _ in system.affine], dtype=int),
                     "rotation": np.array([i for i, _ in system.rotations], dtype=int),
                     "compound": np.array([i for i, _, _ in system.compounds or ()], dtype=int)}
        self.index = np.concatenate([first[b.kind][b.sources] for b in blocks] or [np.zeros(0, int)]).astype(int)
        # (a block may have no rows: no candidate of its kind moves a constraint)
        self.finite = np.concatenate([np.isfinite(b.f).all(axis=tuple(range(1, b.f.ndim))) for b in blocks]
                                     or [np.zeros(0, bool)]).astype(bool)

    def ops_at_end(self, rows: np.ndarray) -> tuple[list, list[str], list]:
        """Each of ``rows``' (positions in the arrays) op, kind and amount at the last sample:
        what ranking reads, without making a :class:`Screened` of each."""
        lists = {"affine": self.system.affine, "rotation": self.system.rotations, "compound": self.system.compounds}
        ops, kinds, last = [], [], []
        for b, n in zip(self.block[rows].tolist(), self.row[rows].tolist()):
            block = self.blocks[b]
            ops.append(lists[block.kind][block.sources[n]][1])
            kinds.append(block.kind)
            last.append(block.f[n][-1])
        return ops, kinds, last

    def screened(self, i: int) -> Screened:
        """Result ``i`` (a position in the arrays, not in :attr:`order`) as a :class:`Screened`."""
        i = int(i)
        made = self._made.get(i)
        if made is None:
            system, block, n = self.system, self.blocks[self.block[i]], int(self.row[i])
            source = int(block.sources[n])
            broken = tuple(system.ids[k] for k in block.broken[n].nonzero()[0])
            if block.kind == "affine":
                index, op = system.affine[source]
                made = Screened(op, index, block.f[n], broken, "affine", system.slope[source], system.r0,
                                block.errors[n], float(self.cost[i]))
            elif block.kind == "rotation":
                index, op = system.rotations[source]
                made = Screened(op, index, block.f[n], broken, "rotation", system.matrix[source],
                                system.offset[source], block.errors[n], float(self.cost[i]))
            else:
                index, op, slopes = system.compounds[source]
                made = Screened(op, index, block.f[n], broken, "compound", slopes, system.r0, block.errors[n],
                                float(self.cost[i]))
            self._made[i] = made
        return made


def _row_costs(broken: np.ndarray, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's count of broken constraints and :attr:`Screened.cost`: the errors of a
    row that breaks a constraint summed (infinite if one is not finite), else 0."""
    whole = np.isfinite(errors).all(axis=-1)
    with np.errstate(invalid="ignore", over="ignore"):
        total = errors.sum(axis=-1)
    return broken.sum(axis=-1), np.where(~broken.any(axis=-1), 0.0, np.where(whole, total, np.inf))


def _compound_amounts_each(r0: np.ndarray, slopes: Sequence[np.ndarray], columns) -> list[np.ndarray]:
    """Each compound's least-squares basis amounts (S, B) of ``r0 + f @ slopes = 0`` on the
    given columns, those of as many basis amounts solved in one stacked call: a system
    screens a dozen compounds, and a stacked SVD and product make each matrix's LAPACK and
    BLAS calls as alone (the same bits) without the wrappers' per-call cost."""
    by_size: dict[int, list[int]] = {}
    for j, s in enumerate(slopes):
        by_size.setdefault(s.shape[0], []).append(j)
    residual = r0[:, columns].T                                                    # (K', S)
    solved: dict[int, np.ndarray] = {}
    for index in by_size.values():
        solver = compound_solver(np.stack([slopes[j] for j in index]), columns)    # (G, B, K')
        solved.update(zip(index, -(solver @ residual).transpose(0, 2, 1)))
    return [solved[j] for j in range(len(slopes))]


def compound_solver(slopes: np.ndarray, columns) -> np.ndarray:
    """``pinv(A^T)`` (..., B, K'): amounts from residual columns; directions that move none
    of the constrained points get no amount (minimum norm). ``slopes`` (..., B, K) may
    stack several compounds of B basis ops, each scaled and solved on its own."""
    a = slopes[..., columns]
    scale = np.maximum(np.abs(a).max(axis=(-2, -1), keepdims=True, initial=0.0), 1e-300)
    return np.linalg.pinv(np.swapaxes(a, -1, -2) / scale, rcond=1e-9) / scale
