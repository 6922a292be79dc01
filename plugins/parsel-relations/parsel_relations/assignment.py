"""Optimal assignment of a small square cost matrix, without scipy.

Matching the 8 corners of two boxes is an 8 x 8 assignment problem; importing
``scipy.optimize`` for it costs a third of a second, more than detecting every relation
of a shape. This is the algorithm ``scipy.optimize.linear_sum_assignment`` runs (Crouse's
shortest augmenting path, as in scipy's ``rectangular_lsap.cpp``), step for step, so
ties are broken the same way and the detected relations do not change; a test compares
the two on random and tied matrices.
"""

from __future__ import annotations

import math

import numpy as np


def _augmenting_path(cost: list[list[float]], u: list[float], v: list[float], path: list[int],
                     row4col: list[int], shortest: list[float], i: int, rows_seen: list[bool],
                     cols_seen: list[bool]) -> tuple[int, float]:
    n = len(v)
    min_val = 0.0
    remaining = [n - it - 1 for it in range(n)]  # reversed: a constant matrix gives the identity
    num_remaining = n
    for k in range(len(rows_seen)):
        rows_seen[k] = False
    for k in range(n):
        cols_seen[k] = False
        shortest[k] = math.inf
    sink = -1
    while sink == -1:
        index, lowest = -1, math.inf
        rows_seen[i] = True
        row = cost[i]
        for it in range(num_remaining):
            j = remaining[it]
            r = min_val + row[j] - u[i] - v[j]
            if r < shortest[j]:
                path[j] = i
                shortest[j] = r
            if shortest[j] < lowest or (shortest[j] == lowest and row4col[j] == -1):
                lowest = shortest[j]
                index = it
        min_val = lowest
        if min_val == math.inf:
            raise ValueError("cost matrix is infeasible")
        j = remaining[index]
        if row4col[j] == -1:
            sink = j
        else:
            i = row4col[j]
        cols_seen[j] = True
        num_remaining -= 1
        remaining[index] = remaining[num_remaining]
    return sink, min_val


def linear_sum_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and the columns assigned to them minimising the summed cost (square, finite)."""
    matrix = np.asarray(cost, dtype=float)
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"expected a square cost matrix, got shape {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise ValueError("cost matrix has non-finite entries")
    n = matrix.shape[0]
    rows = matrix.tolist()
    u, v = [0.0] * n, [0.0] * n
    shortest, path = [math.inf] * n, [-1] * n
    col4row, row4col = [-1] * n, [-1] * n
    rows_seen, cols_seen = [False] * n, [False] * n
    for current in range(n):
        sink, min_val = _augmenting_path(rows, u, v, path, row4col, shortest, current, rows_seen, cols_seen)
        u[current] += min_val
        for i in range(n):
            if rows_seen[i] and i != current:
                u[i] += min_val - shortest[col4row[i]]
        for j in range(n):
            if cols_seen[j]:
                v[j] -= min_val - shortest[j]
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            col4row[i], j = j, col4row[i]
            if i == current:
                break
    return np.arange(n), np.asarray(col4row, dtype=np.intp)
