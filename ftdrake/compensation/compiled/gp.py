"""A Gaussian process compensator's mean and standard deviation for one row, by numba."""

from __future__ import annotations

import numpy as np
from numba import njit

from .rows import checked_row, checked_rows, nonfinite_error


class CompiledGaussianProcess:
    """A fitted ``GPRCompensator``'s mean and std for one row at a time, compiled by numba.

    Per kernel g, with the row standardised as the model does it (z), its training rows X
    (m, d), ARD length scales l, signal variance s, noise variance n and Cholesky factor L of
    ``K + n I``: ``r = s exp(-½ |(z - X) / l|²)``, mean ``r · alpha``, ``v = L⁻¹ r`` by
    forward substitution, std ``sqrt(max(s - |v|², 0) [+ n])``; then the model's target
    scale and offset. This is the model's own formula (see ``GPRCompensator``), evaluated
    without its input validation and chunking, one kernel row at a time: O(g·m²) per row.

    The substitution runs along contiguous rows of L (vectorised). The numba function is
    compiled (or loaded from numba's cache) and run once here, so the first call in a
    control loop is as fast as the rest. The std costs O(g·m²) per row whatever the code:
    measured by ``benchmarks/compensator_latency.py``.
    """

    def __init__(self, model):
        for name in ("X_train_", "L_", "alpha_", "length_scale_", "signal_variance_",
                     "noise_variance_", "input_mean_", "input_scale_"):
            if not hasattr(model, name):
                raise ValueError(f"{type(model).__name__} is not a fitted GPRCompensator "
                                 f"(no {name})")
        self.features = model.features
        self.n_joints = int(model.n_joints_)
        self.n_outputs = int(model.n_outputs_)
        groups = model.output_groups()
        kernel_of_output = np.empty(self.n_outputs, dtype=np.int64)
        for g, cols in enumerate(groups):
            kernel_of_output[cols] = g
        f8 = np.float64
        self._arrays = (
            np.ascontiguousarray(model.input_mean_, dtype=f8),
            np.ascontiguousarray(model.input_scale_, dtype=f8),
            np.ascontiguousarray(np.asarray(model.X_train_, dtype=f8).T),
            np.ascontiguousarray(1.0 / np.asarray(model.length_scale_, dtype=f8)),
            np.ascontiguousarray(model.signal_variance_, dtype=f8),
            np.ascontiguousarray(
                model.noise_variance_ if model.include_noise else
                np.zeros_like(model.noise_variance_), dtype=f8),
            np.ascontiguousarray(model.L_, dtype=f8),
            np.ascontiguousarray(np.asarray(model.alpha_, dtype=f8).T),
            kernel_of_output,
            np.ascontiguousarray(model.target_mean_, dtype=f8),
            np.ascontiguousarray(model.target_scale_, dtype=f8),
        )
        self.predict_one_with_std(np.zeros(3 * self.n_joints))

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns the mean (N, k)."""
        return self.predict_with_std(X)[0]

    def predict_with_std(self, X) -> tuple[np.ndarray, np.ndarray]:
        """X: (N, 3n). Returns (mean, std), each (N, k)."""
        X = checked_rows(X, self.n_joints)
        mean, std = np.empty((len(X), self.n_outputs)), np.empty((len(X), self.n_outputs))
        for i, x in enumerate(X):
            _gp_predict_one(x, *self._arrays, mean[i], std[i])
        return mean, std

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns the mean (k,), written into `out` if given."""
        mean, _ = self.predict_one_with_std(x, out)
        return mean

    def predict_one_with_std(self, x, mean: np.ndarray | None = None,
                             std: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """x: (3n,). Returns (mean (k,), std (k,)), written into `mean`, `std` if given."""
        x = checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise nonfinite_error(x)
        mean = np.empty(self.n_outputs) if mean is None else mean
        std = np.empty(self.n_outputs) if std is None else std
        _gp_predict_one(x, *self._arrays, mean, std)
        return mean, std


# Reassociation lets LLVM vectorise the dot products (the substitution's inner loop is one):
# results move by rounding only (~1e-16 relative), which the equality tests bound.
@njit(cache=True, fastmath={"reassoc", "contract"})
def _gp_predict_one(x, input_mean, input_scale, points_T, inv_length, signal, noise, L,
                    alpha_T, kernel_of_output, target_mean, target_scale, mean, std):
    d, m = points_T.shape
    z = (x[:d] - input_mean) / input_scale
    r = np.empty(m)
    v = np.empty(m)
    for g in range(L.shape[0]):
        # r: the signal covariance of z with every training row; the loop over points is
        # innermost (contiguous in points_T), so it vectorises.
        r[:] = 0.0
        for c in range(d):
            zc, inv = z[c], inv_length[g, c]
            for i in range(m):
                t = (zc - points_T[c, i]) * inv
                r[i] += t * t
        for i in range(m):
            r[i] = signal[g] * np.exp(-0.5 * r[i])
        # v = L⁻¹ r by forward substitution, a row of L (contiguous) at a time.
        Lg = L[g]
        for i in range(m):
            row = Lg[i]
            acc = 0.0
            for j in range(i):
                acc += row[j] * v[j]
            v[i] = (r[i] - acc) / row[i]
        var = signal[g] - np.dot(v, v)
        sd = np.sqrt(max(var, 0.0) + noise[g])
        for o in range(len(kernel_of_output)):
            if kernel_of_output[o] == g:
                mean[o] = np.dot(r, alpha_T[o]) * target_scale[o] + target_mean[o]
                std[o] = sd * target_scale[o]
