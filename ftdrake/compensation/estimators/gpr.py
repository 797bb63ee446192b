"""Gaussian-process compensator: a predictive mean *and* standard deviation per output.

Model (per output j, on standardised inputs z and standardised targets)::

    y_j(z) = f_j(z) + e,   f_j ~ GP(0, s_j · exp(-½ Σ_d (z_d - z'_d)² / l_jd²)),   e ~ N(0, n_j)

an ARD RBF kernel scaled by a constant (signal variance s_j) plus a WhiteKernel (noise
variance n_j). The hyperparameters maximise the log marginal likelihood
(``sklearn.gaussian_process.GaussianProcessRegressor``), as in §2.1 of the seed paper.

Three choices keep it usable on 10k+-row logs on a 2-core machine:

* **A data subset, chosen to cover the trajectory.** An exact GP on m rows costs O(m³) to fit
  and O(m²) memory; a prediction costs O(m·d) for the mean and O(m²) for the std. So the GP
  is trained on at most ``max_points`` rows, picked by greedy farthest-point selection: each
  new row is the one farthest from all rows picked so far, in the kernels' own metric (the
  standardised inputs divided by the fitted ARD length scales, per input the shortest over
  the outputs' kernels; the hyperparameters are fitted first, see below). As an RBF GP's
  predictive variance grows with that distance to the nearest training row, this is a cheap
  stand-in for "add the row with the largest predictive variance". The subset spreads evenly
  along the trajectory instead of piling up where the robot lingered, and its covering radius
  (largest distance from any row to its nearest chosen row) is within 2× of the best possible
  (Gonzalez 1985). Selection costs O(N·m·d) time and O(N) memory. Measured in the kernels'
  metric, an input the kernel ignores does not spread the subset (spikes of a numerically
  differentiated q̈ are not picked first when the kernel ignores q̈); outliers in inputs the
  kernel does use are still picked first: filter them. We chose a subset
  of data over a sparse inducing-point method (SGPR/FITC/VFE) because scikit-learn has none;
  a subset keeps the exact GP algebra, so sklearn fits it and the fitted arrays below are all
  a fast predictor needs.
* **Hyperparameters from a smaller random sample.** sklearn's likelihood gradient builds an
  m × m × (d + 2) array (0.7 GB for m = 2000, d = 21) at every optimiser step, so the
  hyperparameters are fitted on ``optimize_points`` rows drawn at random from all training
  rows; the final model then uses the whole subset with those hyperparameters fixed. Random,
  not the farthest-point prefix: that prefix has by construction no close pairs of rows, and
  close pairs are what separate noise from signal.
* **One GP per output by default.** sklearn's multi-output GP shares the kernel *including
  the noise level*, which after per-output standardisation forces the same signal-to-noise
  ratio on every axis; a force axis and a torque axis rarely have it, and a contact detector
  thresholds each axis by its own σ, so a shared noise level miscalibrates some axes.
  Independent GPs cost k× the fit time, memory (k Cholesky factors, 32 MB each for
  m = 2000) and std-prediction time; ``shared_kernel=True`` trades that calibration for a
  k× cheaper model (one kernel, one Cholesky factor, one triangular solve for all outputs).

The std of a single row costs k triangular solves reading k·m² numbers (one with
`shared_kernel`).

What the std means. ``include_noise=True`` (default) gives the std of a new *measurement*
around the prediction, √(var f + n): the spread of ``measured − predicted`` without contact,
which is what a contact detector compares a residual against. ``include_noise=False`` gives
only the uncertainty of the internal-wrench prediction itself, √(var f), which shrinks towards
zero in well-covered regions; use it to judge the model, or when the detector filters the
measurement and accounts for the (reduced) noise itself with ``noise_std_``. Either way the
std grows towards the prior std √(s + n) away from the training data.
"""

from __future__ import annotations

import warnings
from numbers import Integral, Real
from typing import ClassVar

import numpy as np
from scipy.linalg import cho_solve, cholesky, solve_triangular
from scipy.optimize import minimize
from scipy.spatial.distance import cdist
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import Interval, StrOptions

from ..compiled.gp import CompiledGaussianProcess
from .base import Compensator

SUBSETS = ("greedy", "random", "all")
# Bounds in standardised units: inputs and targets have unit variance.
LENGTH_SCALE_BOUNDS = (1e-2, 1e3)  # above ~1e2 an input no longer matters
SIGNAL_VARIANCE_BOUNDS = (1e-3, 1e2)
NOISE_LEVEL_BOUNDS = (1e-8, 1.0)
# L-BFGS-B stops when a step improves the log marginal likelihood by < 1e-6 of its value (~1e-3
# nats for a few hundred rows): far below a meaningful difference, and half the steps of
# scipy's default (2.2e-9).
LIKELIHOOD_FTOL = 1e-6
JITTER = 1e-10  # added to the kernel diagonal before the Cholesky factorisation, as sklearn does
CHUNK_ENTRIES = 2**22  # rows × m kernel entries evaluated at once when predicting (32 MB)


def farthest_point_subset(Z: np.ndarray, m: int) -> np.ndarray:
    """Greedy farthest-point selection: `m` row indices of `Z` covering it evenly.

    Starts at the row nearest the column means; each further row is the one farthest (in
    Euclidean distance) from every row already chosen. Every prefix of the result is itself
    such a cover.

    Z: (N, d) inputs, already scaled so that Euclidean distance is meaningful.
    Returns: (min(m, N),) int indices, in the order chosen. O(N·m·d) time, O(N) memory.
    """
    m = min(int(m), len(Z))
    sq_norms = np.einsum("ij,ij->i", Z, Z)

    def sq_dist_to(i):  # |Z - Z[i]|² for every row, via one matrix-vector product
        return np.maximum(sq_norms - 2.0 * (Z @ Z[i]) + sq_norms[i], 0.0)

    chosen = np.empty(m, dtype=np.intp)
    chosen[0] = np.argmin(((Z - Z.mean(axis=0)) ** 2).sum(axis=1))
    nearest = sq_dist_to(chosen[0])  # squared distance of each row to the chosen set
    for k in range(1, m):
        chosen[k] = np.argmax(nearest)
        np.minimum(nearest, sq_dist_to(chosen[k]), out=nearest)
    return chosen


def _lbfgs(obj_func, initial_theta, bounds):
    """sklearn's default optimiser (L-BFGS-B) with the looser LIKELIHOOD_FTOL."""
    result = minimize(
        obj_func,
        initial_theta,
        method="L-BFGS-B",
        jac=True,
        bounds=bounds,
        options={"ftol": LIKELIHOOD_FTOL},
    )
    if not result.success:
        warnings.warn(f"hyperparameter optimisation: {result.message}", ConvergenceWarning,
                      stacklevel=2)
    return result.x, result.fun


def _scale(std: np.ndarray) -> np.ndarray:
    """Standard deviations with zeros (constant columns) replaced by 1."""
    return np.where(std > 0, std, 1.0)


class GPRCompensator(Compensator):
    """Exact Gaussian process on a covering subset of the data; mean and std per output.

    Parameters
    ----------
    features : {"q", "q,qd", "q,qd,qdd"}
        Which blocks of ``X = [q, q̇, q̈]`` the model uses.
    max_points : int
        Most training rows the GP keeps (m). Fit O(m³), memory O(k·m²), predict O(m²)/row.
    subset : {"greedy", "random", "all"}
        How to pick the m rows when there are more: farthest-point cover, uniform random
        sample, or every row (ignores `max_points`; O(N³)).
    length_scale : float
        Initial ARD length scale of every input, in standardised units (input stds).
    noise_level : float
        Initial noise variance, as a fraction of each target's variance.
    n_restarts_optimizer : int
        Extra optimiser runs from random hyperparameters (each costs as much as the first).
    optimize_points : int
        Rows (a random sample of all rows) on which the hyperparameters are fitted. 0 keeps
        `length_scale`, `noise_level` and a unit signal variance fixed (e.g. to grid-search
        them).
    shared_kernel : bool
        One kernel and noise level for all outputs (k× cheaper) instead of one GP per output.
    include_noise : bool
        Whether `predict_std` includes the observation noise (std of a measurement) or not
        (std of the internal-wrench prediction); see the module docstring.
    random_state : int, RandomState or None
        Seeds the random subset, the hyperparameter sample and the optimiser restarts.

    Fitted attributes (besides the base class's)
    -----------------
    input_mean_, input_scale_ : (d,)   standardisation of the d used input columns
    target_mean_, target_scale_ : (k,) standardisation of the targets, in target units
    subset_indices_ : (m,)             training rows the GP keeps, in the order chosen
    X_train_ : (m, d)                  those rows, standardised
    alpha_ : (m, k)                    (K + n I)⁻¹ y per output, standardised targets
    L_ : (g, m, m)                     lower Cholesky factor of K + n I per kernel
    length_scale_ : (g, d), signal_variance_ : (g,), noise_variance_ : (g,)
                                       kernel hyperparameters, standardised units
    kernels_ : list of g fitted sklearn kernels (the same hyperparameters)
    noise_std_ : (k,)                  observation-noise std per output, in target units
    residual_rms_ : (k,)               RMS of ``y - predict(X)`` on all training rows

    g = 1 with `shared_kernel` (kernel 0 serves every output), else g = k (kernel j serves
    output j). In standardised units, with r = exp(-½ |(z - X_train_) / l|²) (m,)::

        mean = s r·alpha_,    var f = s - |L⁻¹ (s r)|²,    var y = var f + n

    then ``mean · target_scale_ + target_mean_`` and ``std · target_scale_``.
    """

    provides_std = True
    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        "max_points": [Interval(Integral, 1, None, closed="left")],
        "subset": [StrOptions(set(SUBSETS))],
        "length_scale": [Interval(Real, 0, None, closed="neither")],
        "noise_level": [Interval(Real, 0, None, closed="neither")],
        "n_restarts_optimizer": [Interval(Integral, 0, None, closed="left")],
        "optimize_points": [Interval(Integral, 0, None, closed="left")],
        "shared_kernel": ["boolean"],
        "include_noise": ["boolean"],
        "random_state": ["random_state"],
    }

    @property
    def std_includes_noise(self) -> bool:
        """Whether ``predict_std`` is the std of a new reading (``include_noise``)."""
        return bool(self.include_noise)

    def __init__(
        self,
        features: str = "q,qd,qdd",
        max_points: int = 2000,
        subset: str = "greedy",
        length_scale: float = 1.0,
        noise_level: float = 0.01,
        n_restarts_optimizer: int = 0,
        optimize_points: int = 300,
        shared_kernel: bool = False,
        include_noise: bool = True,
        random_state=None,
    ):
        super().__init__(features=features)
        self.max_points = max_points
        self.subset = subset
        self.length_scale = length_scale
        self.noise_level = noise_level
        self.n_restarts_optimizer = n_restarts_optimizer
        self.optimize_points = optimize_points
        self.shared_kernel = shared_kernel
        self.include_noise = include_noise
        self.random_state = random_state

    # -- fitting --------------------------------------------------------------------------
    def _fit(self, Z: np.ndarray, Y: np.ndarray) -> None:
        rng = check_random_state(self.random_state)
        self.input_mean_, self.input_scale_ = Z.mean(axis=0), _scale(Z.std(axis=0))
        self.target_mean_, self.target_scale_ = Y.mean(axis=0), _scale(Y.std(axis=0))
        Zs = (Z - self.input_mean_) / self.input_scale_
        Ys = (Y - self.target_mean_) / self.target_scale_

        # Hyperparameters first (from a random sample of all rows), then the subset, chosen
        # in the kernels' own metric: see the module docstring.
        sample = rng.choice(len(Zs), min(self.optimize_points, len(Zs)), replace=False)
        self.kernels_ = []
        for cols in self.output_groups():
            kernel = self._initial_kernel(Z.shape[1])
            if len(sample) > 0:
                kernel = self._optimized_kernel(kernel, Zs[sample], Ys[sample][:, cols], rng)
            self.kernels_.append(kernel)

        # Each kernel is ConstantKernel * RBF + WhiteKernel, i.e. (k1.k1 * k1.k2) + k2.
        self.signal_variance_ = np.array([k.k1.k1.constant_value for k in self.kernels_])
        self.length_scale_ = np.array(
            [np.broadcast_to(k.k1.k2.length_scale, Z.shape[1:]) for k in self.kernels_]
        )
        self.noise_variance_ = np.array([k.k2.noise_level for k in self.kernels_])

        self.subset_indices_ = self._choose_subset(Zs / self.length_scale_.min(axis=0), rng)
        self.X_train_ = Zs[self.subset_indices_]
        Y_train = Ys[self.subset_indices_]
        m = len(self.X_train_)
        self.L_ = np.empty((len(self.kernels_), m, m))
        self.alpha_ = np.empty((m, Y.shape[1]))
        for g, (kernel, cols) in enumerate(zip(self.kernels_, self.output_groups(), strict=True)):
            K = kernel(self.X_train_)  # includes the noise variance on the diagonal
            K[np.diag_indices_from(K)] += JITTER
            self.L_[g] = cholesky(K, lower=True, check_finite=False)
            self.alpha_[:, cols] = cho_solve((self.L_[g], True), Y_train[:, cols])
        self.noise_std_ = np.sqrt(self._per_output(self.noise_variance_)) * self.target_scale_
        # What the std is compared with to flag predictions as uncertain (``evaluate``).
        self.residual_rms_ = np.sqrt(np.mean((self._predict(Z) - Y) ** 2, axis=0))

    def _choose_subset(self, Zs: np.ndarray, rng) -> np.ndarray:
        if self.subset == "all" or len(Zs) <= self.max_points:
            return np.arange(len(Zs))
        if self.subset == "random":
            return rng.choice(len(Zs), self.max_points, replace=False)
        return farthest_point_subset(Zs, self.max_points)

    def _initial_kernel(self, n_inputs: int):
        return ConstantKernel(1.0, SIGNAL_VARIANCE_BOUNDS) * RBF(
            np.full(n_inputs, float(self.length_scale)), LENGTH_SCALE_BOUNDS
        ) + WhiteKernel(self.noise_level, NOISE_LEVEL_BOUNDS)

    def _optimized_kernel(self, kernel, Zs: np.ndarray, Ys: np.ndarray, rng):
        """The kernel with hyperparameters maximising the marginal likelihood of (Zs, Ys)."""
        gp = GaussianProcessRegressor(
            kernel,
            alpha=JITTER,
            optimizer=_lbfgs,
            n_restarts_optimizer=self.n_restarts_optimizer,
            copy_X_train=False,
            random_state=rng,
        )
        with warnings.catch_warnings():
            # A length scale at its upper bound just means "this input does not matter" and a
            # noise level at its lower bound "noise-free data"; both are expected, not errors.
            warnings.filterwarnings(
                "ignore", message=".*close to the specified", category=ConvergenceWarning
            )
            gp.fit(Zs, Ys)
        return gp.kernel_

    # -- prediction -----------------------------------------------------------------------
    def compiled_predictor(self):
        """A :class:`~ftdrake.compensation.compiled.CompiledGaussianProcess` (mean and std)."""
        return CompiledGaussianProcess(self)

    def _predict(self, Z: np.ndarray) -> np.ndarray:
        return self._standardised(Z, "mean") * self.target_scale_ + self.target_mean_

    def _predict_std(self, Z: np.ndarray) -> np.ndarray:
        return self._standardised(Z, "std") * self.target_scale_

    def _standardised(self, Z: np.ndarray, what: str) -> np.ndarray:
        """(N, k) mean or std in standardised target units, a chunk of rows at a time."""
        Zs = (Z - self.input_mean_) / self.input_scale_
        out = np.empty((len(Zs), self.n_outputs_))
        rows = max(1, CHUNK_ENTRIES // len(self.X_train_))  # bounds the (rows, m) kernel block
        for start in range(0, len(Zs), rows):
            chunk = slice(start, start + rows)
            for g, cols in enumerate(self.output_groups()):
                Ks = self._cross_kernel(g, Zs[chunk])
                if what == "mean":
                    out[chunk, cols] = Ks @ self.alpha_[:, cols]
                else:
                    out[chunk, cols] = self._std(g, Ks)[:, None]
        return out

    def _std(self, g: int, Ks: np.ndarray) -> np.ndarray:
        """(rows,) std of kernel `g` given its cross-covariances `Ks` (rows, m)."""
        V = solve_triangular(self.L_[g], Ks.T, lower=True, check_finite=False)
        var = np.maximum(self.signal_variance_[g] - np.einsum("ij,ij->j", V, V), 0.0)
        return np.sqrt(var + self.noise_variance_[g] if self.include_noise else var)

    def _cross_kernel(self, g: int, Zs: np.ndarray) -> np.ndarray:
        """Signal covariance between rows `Zs` (standardised) and the training rows: (N, m)."""
        scale = self.length_scale_[g]
        sq_dist = cdist(Zs / scale, self.X_train_ / scale, "sqeuclidean")
        return self.signal_variance_[g] * np.exp(-0.5 * sq_dist)

    # -- helpers --------------------------------------------------------------------------
    def output_groups(self) -> list[list[int]]:
        """Output columns each kernel serves: all of them, or one each."""
        k = self.n_outputs_
        return [list(range(k))] if self.shared_kernel else [[j] for j in range(k)]

    def _per_output(self, per_kernel: np.ndarray) -> np.ndarray:
        """A (g,) hyperparameter array spread to the k outputs."""
        return np.broadcast_to(per_kernel, (self.n_outputs_,)) if self.shared_kernel else per_kernel
