"""A predictive std that grows with the arm's motion, fitted from a model's residuals.

A real wrist vibrates while the arm moves, and a model's error grows with speed: a std
fitted once over all training rows (the residual's spread) is too wide at rest and can be too
narrow at peak speed. :class:`MotionNoiseModel` models the variance of each wrench axis as a
function of the joint speed s = ‖q̇‖ (rad/s) and acceleration a = ‖q̈‖ (rad/s²)::

    σᵢ²(s, a) = c₀ᵢ + c₁ᵢ·s² + c₂ᵢ·s·a + c₃ᵢ·a²,      cᵢ ≥ 0

— a constant (the resting noise and the model's resting error) plus the square of a std
linear in s and a (vibration whose amplitude follows the motion: (α·s + β·a)² has these
terms). The coefficients are fitted to the squared residuals by non-negative least squares,
then re-weighted by 1/σ̂⁴ (the variance of a squared Gaussian residual grows as σ⁴) a few
times, so the rows at rest are not drowned by the noisier rows in motion.

:class:`MotionStdCompensator` puts it on a fitted compensator: the mean is the wrapped
model's, the std (``predict_std``, and the loop's ``wrench_std``) is the motion model's,
fitted from the wrapped model's training residuals (``cv`` > 0: from out-of-fold residuals,
for a model that fits its training rows closer than new ones, such as a forest). The chain's
χ² detector then whitens by a std that is small at rest and wide in motion.

Inputs are rows ``[q, q̇, q̈]`` (N × 3n; rad, rad/s, rad/s²; a temperature column last is
ignored); stds are per axis ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m (the wrapped model's frame).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls
from sklearn.base import BaseEstimator, clone
from sklearn.model_selection import KFold, cross_val_predict
from sklearn.utils.validation import check_is_fitted

from ...errors import ConfigError

__all__ = ["MotionNoiseModel", "MotionStdCompensator", "motion_levels"]


def motion_levels(X, n_joints: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(s, a): ‖q̇‖ (rad/s) and ‖q̈‖ (rad/s²) per row of `X` (N × 3n ``[q, q̇, q̈]``, or 3n + 1
    with a temperature column; `n_joints` default: from the width)."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    n = int(n_joints) if n_joints is not None else X.shape[1] // 3
    if X.shape[1] < 3 * n or n < 1:
        raise ValueError(f"motion_levels: rows need 3n columns [q, q̇, q̈] for n = {n} joints; "
                         f"got {X.shape[1]}")
    return (np.linalg.norm(X[:, n:2 * n], axis=1), np.linalg.norm(X[:, 2 * n:3 * n], axis=1))


def _basis(s: np.ndarray, a: np.ndarray) -> np.ndarray:
    """(N × 4) [1, s², s·a, a²]: the variance's terms."""
    return np.column_stack([np.ones_like(s), s * s, s * a, a * a])


class MotionNoiseModel(BaseEstimator):
    """σ per wrench axis as a function of the joint speed and acceleration (module docstring).

    Parameters
    ----------
    iterations : int
        Re-weighting passes after the first fit (0: plain non-negative least squares on the
        squared residuals).
    min_std : float
        A floor on every predicted std (N, N·m), so a coefficient fitted to 0 cannot make a
        test divide by zero.

    Fitted attributes
    -----------------
    n_joints_ : int
    coef_ : (k, 4) per output, the variance's coefficients on [1, s², s·a, a²]
        (N², N²·s²/rad², ...; ≥ 0)
    n_outputs_ : int
    """

    def __init__(self, iterations: int = 3, min_std: float = 1e-6):
        self.iterations = iterations
        self.min_std = min_std

    def fit(self, X, residuals):
        """Fits on rows `X` (N × 3n) and the model's residuals there (N × k, measured −
        predicted)."""
        if int(self.iterations) < 0 or not float(self.min_std) > 0:
            raise ConfigError(f"MotionNoiseModel: iterations ({self.iterations}) must be ≥ 0 "
                              f"and min_std ({self.min_std}) > 0")
        X = np.atleast_2d(np.asarray(X, dtype=float))
        R = np.asarray(residuals, dtype=float).reshape(len(X), -1)
        finite = np.isfinite(X).all(axis=1) & np.isfinite(R).all(axis=1)
        if finite.sum() < 8:
            raise ValueError(f"MotionNoiseModel.fit: {finite.sum()} finite rows; needs at "
                             "least 8 (rows of [q, q̇, q̈] and their residuals)")
        n = X.shape[1] // 3
        s, a = motion_levels(X[finite], n)
        A = _basis(s, a)
        # Columns scaled to unit RMS (s and a have different units and sizes).
        scale = np.sqrt(np.mean(A * A, axis=0))
        scale[scale == 0] = 1.0
        A = A / scale
        coef = np.empty((R.shape[1], 4))
        for i, r in enumerate(R[finite].T):
            target = r * r
            c, _ = nnls(A, target)
            for _ in range(int(self.iterations)):
                variance = np.maximum(A @ c, float(self.min_std) ** 2)
                w = 1.0 / variance  # 1/σ² on both sides: rows weighted by 1/σ⁴
                c, _ = nnls(A * w[:, None], target * w)
            coef[i] = c / scale
        self.n_joints_, self.n_outputs_, self.coef_ = n, R.shape[1], coef
        return self

    def predict_std(self, X) -> np.ndarray:
        """σ (N × k) at rows `X` (N × 3n)."""
        check_is_fitted(self)
        s, a = motion_levels(X, self.n_joints_)
        return self.std_at(s, a)

    def std_at(self, speed, acceleration) -> np.ndarray:
        """σ (... × k) at joint speeds ‖q̇‖ and accelerations ‖q̈‖ (arrays of one shape)."""
        check_is_fitted(self)
        s, a = np.asarray(speed, dtype=float), np.asarray(acceleration, dtype=float)
        variance = _basis(s.ravel(), a.ravel()) @ self.coef_.T
        std = np.sqrt(np.maximum(variance, float(self.min_std) ** 2))
        return std.reshape(*s.shape, self.n_outputs_)


class MotionStdCompensator(BaseEstimator):
    """A fitted compensator's mean with a std that grows with the motion (module docstring).

    Parameters
    ----------
    estimator : an ftdrake compensator (unfitted; cloned and fitted by :meth:`fit`)
    noise : MotionNoiseModel or None (None: ``MotionNoiseModel()``)
    cv : int
        0: the noise model is fitted on the training residuals; k ≥ 2: on k-fold out-of-fold
        residuals (contiguous folds, as a log's rows are in time order).

    Fitted attributes
    -----------------
    estimator_ : the fitted compensator (the mean)
    noise_ : the fitted MotionNoiseModel (the std)
    n_joints_, n_outputs_, temperature_in_, wrench_delay_s_, input_min_, input_max_ :
        the fitted compensator's (the loop contract, :mod:`ftdrake.compensation.contract`)
    """

    #: The std is that of a reading's residual (noise and model error): the χ² test's.
    provides_std = True
    std_includes_noise = True

    def __init__(self, estimator, noise=None, cv: int = 0):
        self.estimator = estimator
        self.noise = noise
        self.cv = cv

    @property
    def needs_imu(self) -> bool:
        """Whether the wrapped compensator's rows carry an IMU's nine columns."""
        inner = getattr(self, "estimator_", self.estimator)
        return bool(getattr(inner, "needs_imu", False))

    @property
    def features(self) -> str:
        """The wrapped compensator's feature set."""
        inner = getattr(self, "estimator_", self.estimator)
        return inner.features

    def fit(self, X, y, **fit_params):
        """Fits the compensator on `X` (N × 3n), `y` (N × 6) (`fit_params` passed to it),
        then the noise model on its residuals."""
        if int(self.cv) == 1 or int(self.cv) < 0:
            raise ConfigError(f"MotionStdCompensator: cv must be 0 (training residuals) or "
                              f"≥ 2 folds; got {self.cv}")
        X, Y = np.asarray(X, dtype=float), np.asarray(y, dtype=float)
        self.estimator_ = clone(self.estimator).fit(X, Y, **fit_params)
        if int(self.cv) >= 2:
            predicted = cross_val_predict(clone(self.estimator), X, Y,
                                          cv=KFold(int(self.cv)), params=fit_params)
        else:
            predicted = self.estimator_.predict(X)
        residual = Y.reshape(len(Y), -1) - np.asarray(predicted).reshape(len(Y), -1)
        noise = MotionNoiseModel() if self.noise is None else clone(self.noise)
        # The motion is the joints' [q, q̇, q̈]: an IMU model's nine columns after them are not.
        self.noise_ = noise.fit(X[:, :3 * self.estimator_.n_joints_], residual)
        for name in ("n_joints_", "n_outputs_", "temperature_in_", "wrench_delay_s_",
                     "input_min_", "input_max_"):
            setattr(self, name, getattr(self.estimator_, name))
        return self

    def predict(self, X):
        check_is_fitted(self)
        return self.estimator_.predict(X)

    def predict_std(self, X):
        check_is_fitted(self)
        return self.noise_.predict_std(np.atleast_2d(np.asarray(X, dtype=float)))

    def out_of_domain(self, X, margin: float = 0.0):
        check_is_fitted(self)
        return self.estimator_.out_of_domain(X, margin)

    # -- the loop contract ------------------------------------------------------------------
    def row_predictor(self):
        """``row → (mean, std)``: the wrapped model's mean (its own row predictor) and the
        motion model's std at the row's ‖q̇‖, ‖q̈‖."""
        check_is_fitted(self)
        mean_of = self.estimator_.row_predictor()
        noise, n = self.noise_, self.n_joints_
        coef, floor = noise.coef_, float(noise.min_std) ** 2
        basis = np.empty(4)

        def predict(row):
            mean, _ = mean_of(row)
            s = np.sqrt(np.dot(row[n:2 * n], row[n:2 * n]))
            a = np.sqrt(np.dot(row[2 * n:3 * n], row[2 * n:3 * n]))
            basis[:] = (1.0, s * s, s * a, a * a)
            return mean, np.sqrt(np.maximum(coef @ basis, floor))

        return predict

    def fused_loop_update(self):
        """None: the std needs the row in Python (the loop uses :meth:`row_predictor`)."""

    def reading_to_model_frame(self):
        return self.estimator_.reading_to_model_frame()

    def payload_reading_map(self):
        return self.estimator_.payload_reading_map()

    def robot_description(self):
        return self.estimator_.robot_description()
