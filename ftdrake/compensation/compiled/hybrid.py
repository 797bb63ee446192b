"""Physics + forest residual in one compiled call: a ``HybridCompensator``'s row.

Two compiled calls (the payload kernel, then the forest) combined in numpy cost more Python
per row than the forest's walk. Here one numba call computes the payload model's mean and
parameter variance (:func:`.payload.payload_mean_var`, the residual's error variance packed
as its σ²) and walks the forest (:func:`.forest.forest_accumulate`, mean only: a forest's
spread is not the hybrid's std):

    mean = B·θ + w · forest(row),    std = √(‖B F‖² + w σ²_in + (1 − w) σ²_far + g² d)

with w = exp(−(d/ℓ)²) the residual's support at the row, d its distance to the training
inputs (:func:`.kdtree.nearest_distance` on the standardised leading columns; see
:mod:`ftdrake.compensation.estimators.domain`), equal to the hybrid's ``predict`` and
``predict_std`` to round-off. ``CompensatorSystem`` calls :func:`hybrid_row` inside its own
fused update.
"""

from __future__ import annotations

import numba
import numpy as np

from .forest import FlatForest, forest_accumulate
from .kdtree import nearest_distance
from .payload import payload_mean_var
from .rows import checked_row, checked_rows, nonfinite_error


@numba.njit(cache=True, nogil=True)
def support_distance(x, points, kd_nodes, splits, center, scale) -> float:
    """d of row x's leading ``len(center)`` columns, standardised, to the support's points
    (0 without any: a model saved before the support term)."""
    if len(points) == 0:
        return 0.0
    z = np.empty(len(center))
    for i in range(len(center)):
        z[i] = (x[i] - center[i]) / scale[i]
    return nearest_distance(z, points, kd_nodes, splits)


@numba.njit(cache=True, nogil=True)
def hybrid_row(x, reals, ints, nodes, leaf_values, trees, n_trees, points, kd_nodes, splits,
               center, scale, var, length, mean, std):
    """One full-layout row x (3n) → mean (6), std (6) (see the module docstring); `var`
    (3, 6) holds σ²_in, σ²_far and g², the payload part's σ² is 0; w = 1 when ℓ
    (``length[0]``) is ∞."""
    payload_mean_var(x, reals, ints, mean, std)  # std holds the variance until the end
    residual = np.empty(6)
    forest_accumulate(x, nodes, leaf_values, trees, n_trees, residual)
    d = support_distance(x, points, kd_nodes, splits, center, scale)
    w = np.exp(-(d / length[0]) ** 2) if np.isfinite(length[0]) else 1.0
    for j in range(6):
        mean[j] += w * residual[j]
        std[j] = np.sqrt(std[j] + w * var[0, j] + (1.0 - w) * var[1, j] + var[2, j] * d)


@numba.njit(cache=True, nogil=True)
def _hybrid_rows(X, reals, ints, nodes, leaf_values, trees, n_trees, points, kd_nodes, splits,
                 center, scale, var, length, mean, std):
    for r in range(len(X)):
        hybrid_row(X[r], reals, ints, nodes, leaf_values, trees, n_trees, points, kd_nodes,
                   splits, center, scale, var, length, mean[r], std[r])


class CompiledHybrid:
    """A hybrid's payload model and forest residual, compiled into one call per row.

    Parameters
    ----------
    payload : (reals, ints) from :func:`.payload.pack_payload_row`, with σ² = 0.
    forest : the residual's :class:`~.forest.FlatForest` (6 outputs; it indexes the
        ``[q, q̇, q̈]`` row's columns: a forest on q reads the first n).
    n_joints : n, the row has 3n columns.
    support : the support term's ``(points, kd_nodes, splits, center, scale, var (3, 6),
        length (1,))`` (``HybridCompensator._domain_arrays``); None: no support term (w = 1)
        and σ²_in = σ²_far = 0.

    ``arrays`` holds the kernel's arguments after the row, in :func:`hybrid_row`'s order.
    The kernel is compiled (or loaded from numba's cache) and run once here.
    """

    def __init__(self, payload, forest: FlatForest, n_joints: int, support=None):
        if forest.n_outputs != 6:
            raise ValueError(f"the residual forest has {forest.n_outputs} outputs; a wrench "
                             "needs 6")
        self.n_joints = int(n_joints)
        if forest.n_inputs > 3 * self.n_joints:
            raise ValueError(f"the residual forest takes {forest.n_inputs} inputs; a row has "
                             f"{3 * self.n_joints}")
        self.n_outputs = 6
        if support is None:
            support = (np.zeros((0, 1)), np.zeros((0, 5), np.int64), np.zeros(0), np.zeros(1),
                       np.ones(1), np.zeros((3, 6)), np.array([np.inf]))
        self.arrays = (*payload, forest.nodes, forest.leaf_values, forest.trees,
                       forest.n_trees, *support)
        self.predict_one_with_std(np.zeros(3 * self.n_joints))
        self.predict_with_std(np.zeros((2, 3 * self.n_joints)))

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns the mean (N, 6)."""
        return self.predict_with_std(X)[0]

    def predict_with_std(self, X) -> tuple[np.ndarray, np.ndarray]:
        """X: (N, 3n). Returns (mean, std), each (N, 6)."""
        X = checked_rows(X, self.n_joints)
        mean, std = np.empty((len(X), 6)), np.empty((len(X), 6))
        _hybrid_rows(X, *self.arrays, mean, std)
        return mean, std

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row. Returns the mean (6,), written into `out` if given."""
        return self.predict_one_with_std(x, out)[0]

    def predict_one_with_std(self, x, mean: np.ndarray | None = None,
                             std: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """x: (3n,). Returns (mean (6,), std (6,)), written into `mean`, `std` if given
        (C-contiguous float64)."""
        x = checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise nonfinite_error(x)
        mean = np.empty(6) if mean is None else mean
        std = np.empty(6) if std is None else std
        hybrid_row(x, *self.arrays, mean, std)
        return mean, std
