"""Kernel models (SVRs) as an input affine map, kernel expansions against stored points, and
an output affine map, in numpy."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rows import checked_row, checked_rows, joints_for, nonfinite_error

CHUNK_ENTRIES = 2**22  # kernel-model rows × points × features evaluated at once (32 MB)
KERNELS = ("linear", "poly", "rbf", "sigmoid")


@dataclass(frozen=True, eq=False)  # holds arrays: no field-wise ==
class KernelExpansion:
    """``K(Z, points) @ weights``: one kernel evaluated against stored points.

    The shared core of kernel models: an SVR's support vectors and dual coefficients, or a
    GP's training points and ``alpha`` (its mean; its std needs `matrix` too, then a
    triangular solve with the stored Cholesky factor).

    kernel: one of KERNELS, as libsvm defines them for rows z, p:
        linear ``z·p``; poly ``(gamma z·p + coef0)^degree``; rbf ``exp(-gamma |z-p|²)``;
        sigmoid ``tanh(gamma z·p + coef0)``.
    points: (m, d) in the model's (scaled) input space.
    weights: (m, k); a column is zero for points that do not belong to that output.
    """

    kernel: str
    points: np.ndarray
    weights: np.ndarray
    gamma: float = 1.0
    coef0: float = 0.0
    degree: int = 3

    def __post_init__(self):
        if self.kernel not in KERNELS:
            raise ValueError(f"unsupported kernel {self.kernel!r}; expected one of {KERNELS}")

    def matrix(self, Z: np.ndarray) -> np.ndarray:
        """Z: (N, d). Returns the kernel matrix (N, m)."""
        if self.kernel == "rbf":
            # Differences, not |z|² + |p|² - 2 z·p: no cancellation for nearby points.
            diff = Z[:, None, :] - self.points[None, :, :]
            return np.exp(-self.gamma * np.einsum("nmd,nmd->nm", diff, diff))
        dot = Z @ self.points.T
        if self.kernel == "linear":
            return dot
        if self.kernel == "poly":
            return _powi(self.gamma * dot + self.coef0, self.degree)
        return np.tanh(self.gamma * dot + self.coef0)

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        """Z: (N, d). Returns (N, k)."""
        return self.matrix(Z) @ self.weights


@dataclass(frozen=True, eq=False)  # holds arrays: no field-wise ==
class FastKernelModel:
    """``y = target_mean + target_scale * (Σ_e e(z) + intercept)``, ``z = x_sel * scale + offset``.

    x_sel are the `features` columns of the [q, q̇, q̈] row; z is clipped to `clip` if given
    (MinMaxScaler's ``clip=True``). Build an SVR's with :meth:`from_svrs`.

    input_scale, input_offset: (d,); clip: (low, high) or None;
    expansions: tuple of KernelExpansion, each (N, d) → (N, k);
    intercept, target_mean, target_scale: (k,).
    """

    features: str
    n_joints: int
    input_scale: np.ndarray
    input_offset: np.ndarray
    clip: tuple[float, float] | None
    expansions: tuple[KernelExpansion, ...]
    intercept: np.ndarray
    target_mean: np.ndarray
    target_scale: np.ndarray

    @property
    def n_outputs(self) -> int:
        return len(self.intercept)

    @property
    def n_inputs(self) -> int:
        """The selected feature columns it takes."""
        return len(self.input_scale)

    def onnx_parts(self) -> FastKernelModel:
        """Itself: the form :mod:`ftdrake.compensation.files.onnx_export` writes."""
        return self

    @classmethod
    def from_svrs(
        cls, scaler, svrs, features: str = "q,qd,qdd", target_mean=None, target_scale=None,
        n_joints: int | None = None,
    ) -> FastKernelModel:
        """From a fitted ``MinMaxScaler`` and one fitted ``sklearn.svm.SVR`` per output.

        Outputs whose SVRs share kernel parameters share one expansion (their support
        vectors stacked). `target_mean`, `target_scale` (k,) undo a target standardisation
        (``SVRCompensator``'s ``target_mean_``, ``target_scale_``); default 0 and 1.
        """
        svrs = list(svrs)
        groups: dict[tuple, list[int]] = {}
        for j, svr in enumerate(svrs):
            if not hasattr(svr, "support_vectors_"):
                raise ValueError(f"output {j}: {svr!r} is not a fitted SVR")
            if svr.kernel not in KERNELS:
                raise ValueError(f"output {j}: unsupported kernel {svr.kernel!r}")
            key = (svr.kernel, float(svr._gamma), float(svr.coef0), int(svr.degree))
            groups.setdefault(key, []).append(j)
        k = len(svrs)
        expansions = []
        for (kernel, gamma, coef0, degree), outputs in groups.items():
            points = np.vstack([_dense(svrs[j].support_vectors_) for j in outputs])
            weights = np.zeros((len(points), k))
            start = 0
            for j in outputs:
                m = len(svrs[j].support_vectors_)
                weights[start : start + m, j] = _dense(svrs[j].dual_coef_)[0]
                start += m
            expansions.append(KernelExpansion(kernel, points, weights, gamma, coef0, degree))
        n_used = len(scaler.scale_)
        if any(svr.n_features_in_ != n_used for svr in svrs):
            raise ValueError(f"the SVRs and the scaler ({n_used} inputs) disagree on inputs")
        return cls(
            features=features,
            n_joints=joints_for(n_used, features, n_joints),
            input_scale=np.asarray(scaler.scale_, dtype=np.float64),
            input_offset=np.asarray(scaler.min_, dtype=np.float64),
            clip=tuple(map(float, scaler.feature_range)) if scaler.clip else None,
            expansions=tuple(expansions),
            intercept=np.array([svr.intercept_[0] for svr in svrs], dtype=np.float64),
            target_mean=np.zeros(k) if target_mean is None else np.asarray(target_mean, float),
            target_scale=np.ones(k) if target_scale is None else np.asarray(target_scale, float),
        )

    def predict(self, X) -> np.ndarray:
        """X: (N, 3n) rows of [q, q̇, q̈]. Returns (N, k)."""
        X = checked_rows(X, self.n_joints)
        m = sum(len(e.points) for e in self.expansions)
        step = max(1, CHUNK_ENTRIES // max(1, m * len(self.input_scale)))
        out = np.empty((len(X), self.n_outputs))
        for start in range(0, len(X), step):
            out[start : start + step] = self._predict(X[start : start + step])
        return out

    def predict_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """x: (3n,) one row of [q, q̇, q̈]. Returns (k,), written into `out` if given."""
        x = checked_row(x, self.n_joints)
        if not np.isfinite(x).all():
            raise nonfinite_error(x)
        y = self._predict(x[None, :])[0]
        if out is None:
            return y
        out[:] = y
        return out

    def _predict(self, X: np.ndarray) -> np.ndarray:
        Z = X[:, : len(self.input_scale)] * self.input_scale  # the selected features
        Z += self.input_offset
        if self.clip is not None:
            np.clip(Z, *self.clip, out=Z)
        s = self.intercept + sum(expansion(Z) for expansion in self.expansions)
        return self.target_mean + self.target_scale * s


def _powi(base: np.ndarray, n: int) -> np.ndarray:
    """base**n for an int n >= 0 by repeated squaring, as libsvm computes it (and faster than
    numpy's float power)."""
    result, power = np.ones_like(base), base
    while n > 0:
        if n % 2:
            result = result * power
        n //= 2
        if n:
            power = power * power
    return result


def _dense(a) -> np.ndarray:
    return np.asarray(a.toarray() if hasattr(a, "toarray") else a, dtype=np.float64)
