"""A subsample of a long log that covers its state space: what training's ``max_rows`` fits on.

At 1 kHz consecutive rows are near duplicates: minutes of a robot log hold a few thousand
distinct states, repeated. :func:`covering_rows` picks at most `max_rows` of them in two steps:

1. **In time**: every k-th row of each recording (k = ⌈N / (`oversample` · max_rows)⌉),
   which keeps the log's time structure and drops the near duplicates cheaply.
2. **In the state space**: among those candidates, greedy farthest-point selection in the
   model's input metric — the inputs the model uses (its feature set's ``[q, q̇, q̈]``
   columns), each scaled by its spread — starting from the first row: every pick is the
   candidate farthest from all picked so far, so rare states (a fast reversal, an extreme
   pose) are kept and the dense middle of the motion is thinned. (The GP's inducing subset
   is chosen the same way.)

The rows come back in time order.
"""

from __future__ import annotations

import math

import numba
import numpy as np

OVERSAMPLE = 2


def covering_rows(X: np.ndarray, max_rows: int, *, groups: np.ndarray | None = None,
                  columns: int | None = None, oversample: int = OVERSAMPLE) -> np.ndarray:
    """Indices (sorted) of at most `max_rows` rows of `X` (N × inputs) covering its inputs.

    `columns`: how many leading columns the metric uses (the model's used inputs; default
    all). `groups`: recording ids (rows of one recording are consecutive in time).
    """
    X = np.asarray(X, dtype=float)
    n = len(X)
    if max_rows < 1:
        raise ValueError(f"max_rows must be >= 1, got {max_rows}")
    if n <= max_rows:
        return np.arange(n)
    groups = np.zeros(n) if groups is None else np.asarray(groups)
    step = max(1, math.ceil(n / (oversample * max_rows)))
    candidates = np.concatenate([np.flatnonzero(groups == g)[::step]
                                 for g in _in_order(groups)])
    used = X[candidates, :columns] if columns else X[candidates]
    spread = used.std(axis=0)
    spread[spread == 0] = 1.0
    picked = _farthest_points(np.ascontiguousarray((used - used.mean(axis=0)) / spread),
                              min(max_rows, len(candidates)))
    return np.sort(candidates[picked])


def _in_order(groups: np.ndarray) -> list:
    _, first = np.unique(groups, return_index=True)
    return list(groups[np.sort(first)])


@numba.njit(cache=True)
def _farthest_points(points, k):
    """Greedy farthest-point selection of `k` of `points`, starting from the first."""
    n = points.shape[0]
    chosen = np.empty(k, dtype=np.int64)
    nearest = np.full(n, np.inf)
    current = 0
    for j in range(k):
        chosen[j] = current
        best, best_distance = 0, -1.0
        for i in range(n):
            d = 0.0
            for c in range(points.shape[1]):
                diff = points[i, c] - points[current, c]
                d += diff * diff
            nearest[i] = min(nearest[i], d)
            if nearest[i] > best_distance:
                best, best_distance = i, nearest[i]
        current = best
    return chosen
