"""Breaking-edits screened lazily: bounds for every row, exact errors for the few the choice reads.

When no candidate keeps every constraint, a search solves each candidate's amount from
each constraint alone and measures all the constraints under it (paper 5.3.1): one row
per candidate and constraint, each with errors at every sample. The search then takes
the least total error among the edits that are not too distorting and ranks the edits
within 1% of it (:func:`least_breaking`); a row in a hundred comes that near.

So every row's errors are first bounded below by their values at the last sample (the
end of the range, where edits move most: one sample's residual instead of all of them),
which bounds its total error, and exact errors are computed only for rows whose bound
could place them among those the choice reads. The rows, their exact errors and the
choice are those of screening every row in full (the residuals and costs are those of
:func:`~parsel_aep.screening.screen_table`), to the bit.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from parsel_aep.screening import (
    Screened,
    ScreenTable,
    _affine_amounts,
    _affine_residual,
    _Block,
    _compound_blocks,
    _max_abs_per_slice,
    _rotation_amounts_batch,
    _rotation_residual,
    _row_costs,
    _System,
    _system,
    slice_maxima,
)
from parsel_core.ops import EditOp
from parsel_core.relations import Relation

#: Rows whose exact errors are computed together, at first (doubling as more are needed).
_FIRST_BATCH = 64
#: Breaking-edits whose distortion is measured together, least error first.
_CHUNK = 16


class BreakingTable(ScreenTable):
    """Every candidate solved from each constraint alone, one row per pair, laid out as a
    :class:`~parsel_aep.screening.ScreenTable`; a row's errors are computed on
    :meth:`evaluate`, and :attr:`bound` holds a lower bound of its :attr:`cost` until
    then. Rows go by candidate, then fewest broken, then as generated
    (:attr:`generated`); :attr:`nbroken`, :attr:`cost` and :meth:`screened` hold for
    evaluated rows."""

    def __init__(self, system: _System | None, blocks: list[_Block], bounds: list[np.ndarray],
                 known: list[np.ndarray], allowed: np.ndarray) -> None:
        self._lay_out(system, blocks)
        self.allowed = allowed
        self.generated = np.arange(len(self.index))
        self.bound = np.concatenate(bounds or [np.zeros(0)])
        self.known = np.concatenate(known or [np.zeros(0, bool)])
        self.nbroken = np.zeros(len(self.index), dtype=int)
        self.cost = np.zeros(len(self.index))
        self._summarise(np.flatnonzero(self.known))

    def evaluate(self, rows: np.ndarray) -> None:
        """Compute the exact errors of ``rows`` (positions in the arrays) not yet known."""
        rows = np.asarray(rows, dtype=int)
        rows = rows[~self.known[rows]]
        if not rows.size:
            return
        for b in _blocks_of(self.block[rows]):
            block = self.blocks[b]
            picked = self.row[rows[self.block[rows] == b]]
            # (compound rows are known from the start)
            residual = (_affine_residual if block.kind == "affine" else _rotation_residual)(
                self.system, block.sources[picked], block.f[picked])
            errors = _max_abs_per_slice(residual, self.system.slices)
            block.errors[picked] = errors
            block.broken[picked] = ~(errors < self.allowed)
        self.known[rows] = True
        self._summarise(rows)

    def _summarise(self, rows: np.ndarray) -> None:
        """:attr:`nbroken` and :attr:`cost` of evaluated ``rows``, as ScreenTable makes them."""
        for b in _blocks_of(self.block[rows]):
            block = self.blocks[b]
            at = rows[self.block[rows] == b]
            self.nbroken[at], self.cost[at] = _row_costs(block.broken[self.row[at]], block.errors[self.row[at]])


def _blocks_of(blocks: np.ndarray) -> list[int]:
    """The distinct block numbers among ``blocks``, ascending. (``np.unique`` would import
    ``numpy.ma`` at a process's first breaking-edit, 20-30 ms of a command's start-up.)"""
    return sorted(set(blocks.tolist()))


def breaking_table(candidates: Sequence[EditOp], moving: Mapping[str, np.ndarray],
                   others: Mapping[str, np.ndarray], constraints: Sequence[Relation], tolerance: float,
                   memo: dict | None = None) -> BreakingTable:
    """Every candidate's amount solved from each constraint alone, with a lower bound of
    its errors (their values at the last sample); compound rows, few, are evaluated at
    once (only those with finite errors are rows, as in screen_table)."""
    if not candidates or not constraints:
        return BreakingTable(None, [], [], [], np.zeros(0))
    system = _system(candidates, moving, others, constraints, memo)
    allowed = np.maximum(tolerance, system.rest_errors)
    blocks: list[_Block] = []
    bounds: list[np.ndarray] = []
    known: list[np.ndarray] = []
    last = slice(-1, None)  # the last sample
    for columns in system.slices:
        if system.affine:
            f, usable = _affine_amounts(system.r0, system.slope, columns)
            rows = np.flatnonzero(usable)
            f = f[rows]
            # The residual at the last sample, element by element the one of the whole residual
            at_end = _affine_residual(system, rows, f, last)                           # (N, 1, K)
            blocks.append(_pending("affine", rows, f, len(system.slices)))
            bounds.append(_cost_bound(_max_abs_per_slice(at_end, system.slices), allowed))
            known.append(np.zeros(len(rows), dtype=bool))
        if system.rotations:
            f_all, usable = _rotation_amounts_batch(system, columns)
            rows = np.flatnonzero(usable)
            f_all = f_all[rows]
            at_end = _rotation_residual(system, rows, f_all, last)                     # (N, 1, K)
            # (a product of another shape may round differently: the bound gives way by
            # far more than that rounding, relative to the terms summed)
            size = (np.abs(system.matrix[rows]).sum(axis=-1) + np.abs(system.r0[last])
                    + np.abs(system.offset[rows]))                                      # (N, K)
            slack = slice_maxima(1e-9 * size, system.slices)
            errors = np.maximum(_max_abs_per_slice(at_end, system.slices) - slack, 0.0)
            blocks.append(_pending("rotation", rows, f_all, len(system.slices)))
            bounds.append(_cost_bound(errors, allowed))
            known.append(np.zeros(len(rows), dtype=bool))
        for block in _compound_blocks(system, columns, allowed):
            blocks.append(block)
            bounds.append(np.zeros(1))
            known.append(np.ones(1, dtype=bool))
    return BreakingTable(system, blocks, bounds, known, allowed)


def _pending(kind: str, rows: np.ndarray, f: np.ndarray, relations: int) -> _Block:
    """A block of ``rows`` whose errors (NaN until evaluated) are still to compute."""
    return _Block(kind, rows, f, np.full((len(rows), relations), np.nan), np.zeros((len(rows), relations), dtype=bool))


def _cost_bound(errors: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """A lower bound of each row's cost from lower bounds of its errors: their sum when one
    already reaches its allowance (the row breaks a constraint), else 0; not a number: 0."""
    with np.errstate(invalid="ignore", over="ignore"):
        bound = np.where((errors >= allowed).any(axis=-1), errors.sum(axis=-1), 0.0)
    return np.where(np.isnan(bound), 0.0, bound)


def least_breaking(table: BreakingTable, constraints: int, distortion: Callable[[list[Screened]], np.ndarray],
                   best: Callable[[np.ndarray], int | None], tolerance: float,
                   high: float) -> Screened | None:
    """The breaking-edit to take: the best ranked of the rows whose total error is within
    1% of the least among the edits whose ``distortion`` is not above ``high``; ``best``
    gives the best ranked of some rows (positions in the table, in order), ``None`` for none.

    Rows that break all ``constraints`` or have no finite amounts or cost are not taken.
    Rows are evaluated in order of their bounds until the ones the choice reads are known:
    the least errors in chunks of 16 (as many as an acceptable one takes), then every row
    that may be within 1% of the least.
    """
    scan = _Scan(table, constraints)
    start, least = 0, None
    while least is None:
        ordered = scan.smallest(start + _CHUNK)
        chunk = [table.screened(i) for i in ordered[start:start + _CHUNK]]
        if not chunk:
            return None
        acceptable = np.flatnonzero(~(distortion(chunk) > high))
        if acceptable.size:
            least = chunk[int(acceptable[0])].cost
        start += _CHUNK
    limit = least * 1.01 + tolerance
    scan.through(limit)
    near = scan.pool()
    near = near[table.cost[near] <= limit]
    near = near[np.lexsort((table.generated[near], table.nbroken[near], table.index[near]))]
    chosen = best(near)
    return table.screened(chosen) if chosen is not None else None


class _Scan:
    """The rows of a :class:`BreakingTable` evaluated in order of their bounds."""

    def __init__(self, table: BreakingTable, constraints: int) -> None:
        self.table, self.constraints = table, constraints
        rows = np.flatnonzero(table.finite)
        self.by_bound = rows[np.argsort(table.bound[rows], kind="stable")]
        self.next = 0
        self.batch = _FIRST_BATCH

    def floor(self) -> float:
        """The least bound of a row not evaluated (infinite when all are)."""
        while self.next < len(self.by_bound) and self.table.known[self.by_bound[self.next]]:
            self.next += 1
        return float(self.table.bound[self.by_bound[self.next]]) if self.next < len(self.by_bound) else np.inf

    def more(self) -> None:
        self.table.evaluate(self.by_bound[self.next:self.next + self.batch])
        self.next += self.batch
        self.batch *= 2

    def pool(self) -> np.ndarray:
        """Evaluated rows that may be taken, in the arrays' order."""
        t = self.table
        return np.flatnonzero(t.known & t.finite & (t.nbroken < self.constraints) & np.isfinite(t.cost))

    def smallest(self, count: int) -> np.ndarray:
        """The ``count`` rows of least cost that may be taken (fewer if there are not as
        many), ties in the eager table's order, every row that could be among them evaluated."""
        t = self.table
        while True:
            pool = self.pool()
            floor = self.floor()
            if len(pool) >= count and floor > np.partition(t.cost[pool], count - 1)[count - 1]:
                break
            if floor == np.inf:
                break
            self.more()
        ordered = pool[np.lexsort((t.generated[pool], t.nbroken[pool], t.index[pool], t.cost[pool]))]
        return ordered[:count]

    def through(self, limit: float) -> None:
        """Evaluate every row whose cost may be at most ``limit``."""
        while self.floor() <= limit:
            self.more()
