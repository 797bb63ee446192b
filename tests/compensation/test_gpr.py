"""GPRCompensator: calibrated std, out-of-domain growth, covering subsets, sklearn contract.

The data are a 7-joint arm's tool-gravity wrench (plus a cable pull) as smooth nonlinear
functions of q, with white noise of known σ per axis, along a sum-of-sines excitation.
"""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest
from scipy.spatial import cKDTree
from sklearn.base import clone
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.utils.estimator_checks import check_estimator
from threadpoolctl import threadpool_limits

import ftdrake.compensation.estimators.base as base_module
import ftdrake.compensation.features as features_module
from ftdrake.compensation.estimators.gpr import GPRCompensator, farthest_point_subset

N_JOINTS = 7
AXES = "zyzyzyz"  # joint axes of an iiwa-like arm
TOOL_MASS = 1.5  # kg
P_SoToolcm_S = np.array([0.01, -0.02, 0.08])  # m
SIGMA = np.array([0.3, 0.3, 0.3, 0.02, 0.02, 0.02])  # sensor noise std, N and N·m
COVERAGE_BAND = (0.90, 0.99)  # accepted fraction of held-out errors inside mean ± 1.96 std


def rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by `angle` (N,) about the x, y or z axis."""
    c, s = np.cos(angle), np.sin(angle)
    i = "xyz".index(axis)
    j, k = (a for a in range(3) if a != i)
    R = np.zeros((*angle.shape, 3, 3))
    R[:, i, i] = 1.0
    R[:, j, j] = R[:, k, k] = c
    R[:, j, k], R[:, k, j] = -s, s
    return R


def internal_wrench(q: np.ndarray) -> np.ndarray:
    """(N, 6) [Fx Fy Fz Tx Ty Tz] the tool exerts on the sensor, in S, for joint angles q."""
    R_WS = np.broadcast_to(np.eye(3), (len(q), 3, 3))
    for i, axis in enumerate(AXES):
        R_WS = R_WS @ rotation(axis, q[:, i])
    F_S = TOOL_MASS * np.einsum("nji,j->ni", R_WS, [0.0, 0.0, -9.81])
    F_S[:, 0] += 2.0 * np.sin(q[:, 5])  # a cable pulling harder as joint 5 bends
    return np.hstack([F_S, np.cross(P_SoToolcm_S, F_S)])


def excitation(n: int, seed: int = 0) -> np.ndarray:
    """(n, 21) [q, qd, qdd] of a 5-harmonic sum-of-sines trajectory sampled at 100 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    w, a, phase = (
        rng.uniform(lo, hi, (5, N_JOINTS)) for lo, hi in ((0.1, 0.6), (0.1, 0.35), (0.0, 2 * np.pi))
    )
    arg = w * t[:, None, None] + phase
    q = (a * np.sin(arg)).sum(axis=1)
    qd = (a * w * np.cos(arg)).sum(axis=1)
    qdd = -(a * w**2 * np.sin(arg)).sum(axis=1)
    return np.hstack([q, qd, qdd])


def measured(X: np.ndarray, seed: int = 0) -> np.ndarray:
    """Internal wrench plus white noise of std SIGMA."""
    noise = np.random.default_rng(seed).standard_normal((len(X), 6))
    return internal_wrench(X[:, :N_JOINTS]) + SIGMA * noise


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    """These 100-800-row problems gain nothing from BLAS threads, and on a busy 2-core machine
    OpenBLAS threads waiting for a core made the fits 3-10x slower."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


@pytest.fixture(scope="module")
def split():
    """3000 training rows and 1500 held-out rows, shuffled from one trajectory."""
    X = excitation(4500)
    Y = measured(X)
    order = np.random.default_rng(1).permutation(len(X))
    train, test = order[:3000], order[3000:]
    return X[train], Y[train], X[test], Y[test]


@pytest.fixture(scope="module", params=["q", "q,qd,qdd"])
def fitted(request, split):
    X, Y, _, _ = split
    dut = GPRCompensator(request.param, max_points=800, optimize_points=200, random_state=0)
    return dut.fit(X, Y)


# -- calibration ---------------------------------------------------------------------------
def test_95_percent_interval_covers_about_95_percent_of_held_out_errors(fitted, split):
    """Per axis, held-out |measured - mean| <= 1.96 std for 90-99% of rows (measured: 93-96%)."""
    _, _, X_test, Y_test = split
    dut = fitted
    inside = np.abs(Y_test - dut.predict(X_test)) <= 1.96 * dut.predict_std(X_test)
    coverage = inside.mean(axis=0)
    assert np.all((COVERAGE_BAND[0] <= coverage) & (coverage <= COVERAGE_BAND[1])), coverage


def test_learned_noise_matches_the_sensor_noise(fitted):
    np.testing.assert_allclose(fitted.noise_std_, SIGMA, rtol=0.25)


def test_std_widens_out_of_domain(fitted, split):
    """Joint angles 2 range widths beyond the training data: std > 3x the largest in domain."""
    X, _, X_test, _ = split
    dut = fitted
    X_in = X_test[~dut.out_of_domain(X_test)][:200]
    q_width = np.where(np.arange(X.shape[1]) < N_JOINTS, X.max(axis=0) - X.min(axis=0), 0.0)
    X_far = X_in + 2.0 * q_width
    assert dut.out_of_domain(X_far).all()
    std_in, std_far = dut.predict_std(X_in), dut.predict_std(X_far)
    assert np.all(std_far.min(axis=0) > 3.0 * std_in.max(axis=0))
    # 10 widths away the GP has reverted to its prior: std² = (signal + noise variance)·scale².
    prior = np.sqrt(dut.signal_variance_ + dut.noise_variance_) * dut.target_scale_
    std_very_far = dut.predict_std(X_in + 10.0 * q_width)
    np.testing.assert_allclose(std_very_far, np.broadcast_to(prior, std_far.shape), rtol=1e-9)


def test_include_noise_adds_the_observation_noise_variance(fitted, split):
    X_test = split[2][:100]
    dut = fitted
    without = copy.copy(dut).set_params(include_noise=False)
    np.testing.assert_allclose(
        dut.predict_std(X_test) ** 2,
        without.predict_std(X_test) ** 2 + dut.noise_std_**2,
        rtol=1e-9,
    )
    assert np.all(without.predict_std(X_test) < dut.noise_std_)  # in domain: well below noise


def test_fitted_arrays_reproduce_sklearn_gp(fitted, split):
    """The exposed arrays are all a predictor needs: same answer as sklearn's own GP."""
    X, Y, X_test, _ = split
    dut = fitted
    Y_train = (Y[dut.subset_indices_] - dut.target_mean_) / dut.target_scale_
    d = dut.X_train_.shape[1]
    Z_test = (X_test[:, :d] - dut.input_mean_) / dut.input_scale_
    np.testing.assert_allclose(
        dut.X_train_, (X[dut.subset_indices_, :d] - dut.input_mean_) / dut.input_scale_
    )
    for j in (0, 5):
        reference = GaussianProcessRegressor(dut.kernels_[j], alpha=1e-10, optimizer=None)
        mean, std = reference.fit(dut.X_train_, Y_train[:, j]).predict(Z_test, return_std=True)
        np.testing.assert_allclose(
            dut.predict(X_test)[:, j],
            mean * dut.target_scale_[j] + dut.target_mean_[j],
            rtol=1e-7,
            atol=1e-9 * dut.target_scale_[j],
        )
        np.testing.assert_allclose(
            dut.predict_std(X_test)[:, j], std * dut.target_scale_[j], rtol=1e-7
        )


def test_std_is_in_target_units(split):
    """Targets in mN instead of N: mean and std ×1000, hyperparameters unchanged."""
    X, Y = split[0][:400], split[1][:400]
    X_test = split[2][:100]
    fixed = GPRCompensator(features="q", optimize_points=0).fit(X, Y)
    fixed_mN = clone(fixed).fit(X, 1000.0 * Y)
    np.testing.assert_allclose(fixed_mN.predict_std(X_test), 1e3 * fixed.predict_std(X_test))
    np.testing.assert_allclose(fixed_mN.predict(X_test), 1e3 * fixed.predict(X_test))
    # With optimised hyperparameters the optimiser stops at a relative change of 1e-6 in the
    # likelihood, so the two fits agree to its tolerance rather than to rounding.
    dut = GPRCompensator(features="q", optimize_points=150, n_restarts_optimizer=1, random_state=0)
    dut_mN = clone(dut).fit(X, 1000.0 * Y)
    dut.fit(X, Y)
    np.testing.assert_allclose(dut_mN.predict_std(X_test), 1e3 * dut.predict_std(X_test), rtol=1e-3)
    in_target_stds = 1e3 * Y.std(axis=0)  # a mean near zero has no useful relative error
    np.testing.assert_allclose(
        dut_mN.predict(X_test) / in_target_stds,
        1e3 * dut.predict(X_test) / in_target_stds,
        atol=1e-3,
    )


# -- data subsets --------------------------------------------------------------------------
def covering_radius(Z: np.ndarray, chosen: np.ndarray) -> float:
    """Largest distance from any row of Z to its nearest chosen row."""
    return float(cKDTree(Z[chosen]).query(Z)[0].max())


def test_greedy_subset_of_10k_rows_covers_better_than_random():
    X = excitation(12_000, seed=2)
    Y = measured(X, seed=2)
    common = {"max_points": 300, "optimize_points": 0, "random_state": 0}
    dut = GPRCompensator(subset="greedy", **common).fit(X, Y)
    rand = GPRCompensator(subset="random", **common).fit(X, Y)
    for model in (dut, rand):
        assert len(model.subset_indices_) == len(np.unique(model.subset_indices_)) == 300
        assert model.X_train_.shape == (300, 21) and model.L_.shape == (6, 300, 300)
    Zs = (X - dut.input_mean_) / dut.input_scale_
    r_greedy = covering_radius(Zs, dut.subset_indices_)
    r_random = covering_radius(Zs, rand.subset_indices_)
    assert r_greedy < 0.5 * r_random, (r_greedy, r_random)  # measured: 0.57 vs 2.30


def test_farthest_point_subset_picks_the_extremes_of_a_line_first():
    Z = np.linspace(0.0, 1.0, 101)[:, None]
    np.testing.assert_array_equal(farthest_point_subset(Z, 5), [50, 0, 100, 25, 75])
    assert len(farthest_point_subset(Z, 500)) == 101


def test_subset_all_and_small_data_keep_every_row():
    X = excitation(150)
    Y = measured(X)
    for subset, max_points in (("all", 10), ("greedy", 150), ("random", 1000)):
        dut = GPRCompensator(subset=subset, max_points=max_points, optimize_points=0).fit(X, Y)
        np.testing.assert_array_equal(dut.subset_indices_, np.arange(150))


@pytest.mark.parametrize("bad", [{"subset": "kmeans"}, {"max_points": 0}, {"optimize_points": -1}])
def test_bad_parameters_are_named(bad):
    X = excitation(30)
    with pytest.raises(ValueError, match=next(iter(bad))):
        GPRCompensator(**bad).fit(X, measured(X))


# -- shapes --------------------------------------------------------------------------------
@pytest.mark.parametrize("shared_kernel", [False, True])
@pytest.mark.parametrize("features, d", [("q", 7), ("q,qd", 14), ("q,qd,qdd", 21)])
def test_shapes_for_every_feature_set(features, d, shared_kernel):
    X = excitation(120)
    Y = measured(X)
    dut = GPRCompensator(
        features, max_points=100, optimize_points=40, shared_kernel=shared_kernel, random_state=0
    ).fit(X, Y)
    g = 1 if shared_kernel else 6
    assert dut.predict(X[:7]).shape == dut.predict_std(X[:7]).shape == (7, 6)
    assert dut.X_train_.shape == (100, d) and dut.alpha_.shape == (100, 6)
    assert dut.L_.shape == (g, 100, 100) and dut.length_scale_.shape == (g, d)
    assert dut.signal_variance_.shape == dut.noise_variance_.shape == (g,)
    assert len(dut.kernels_) == g and dut.noise_std_.shape == (6,)
    assert np.all(dut.predict_std(X[:7]) > 0)
    one = clone(dut).fit(X, Y[:, 2])
    assert one.predict(X[:7]).shape == one.predict_std(X[:7]).shape == (7,)


def test_prediction_in_chunks_matches_one_block(fitted, split, monkeypatch):
    X_test = split[2][:300]
    mean, std = fitted.predict(X_test), fitted.predict_std(X_test)
    # 64 rows a chunk
    monkeypatch.setattr("ftdrake.compensation.estimators.gpr.CHUNK_ENTRIES", 64 * 800)
    np.testing.assert_allclose(fitted.predict(X_test), mean, rtol=1e-12)
    np.testing.assert_allclose(fitted.predict_std(X_test), std, rtol=1e-12)


# -- scikit-learn contract -----------------------------------------------------------------
def test_clone_and_pickle(fitted, split):
    X_test = split[2][:20]
    assert clone(fitted).get_params() == fitted.get_params()
    restored = pickle.loads(pickle.dumps(fitted))
    np.testing.assert_array_equal(restored.predict_std(X_test), fitted.predict_std(X_test))


def test_grid_search_over_fixed_hyperparameters(split):
    X, Y = split[0][:300], split[1][:300]
    search = GridSearchCV(
        GPRCompensator(features="q", optimize_points=0),
        {"length_scale": [0.3, 3.0], "noise_level": [1e-3, 1e-1]},
        cv=KFold(3),
    ).fit(X, Y)
    # The likelihood picks length scales of 2-7 input stds and noise ~1e-3 of each variance.
    assert search.best_params_ == {"length_scale": 3.0, "noise_level": 1e-3}


# Each expected failure is the base class refusing an X that is not the [q, q̇, q̈] layout
# (3n columns): the check fits on as many columns as the reason says.
EXPECTED_FAILED_CHECKS = {
    "check_dtype_object": "10 columns are not a [q, qd, qdd] layout",
    "check_estimators_dtypes": "5 columns are not a [q, qd, qdd] layout",
    "check_estimators_fit_returns_self": "2 columns are not a [q, qd, qdd] layout",
    "check_estimators_overwrite_params": "2 columns are not a [q, qd, qdd] layout",
    "check_fit2d_1feature": "1 column: the layout error comes before the 1-feature one",
    "check_fit2d_1sample": "10 columns: the layout error comes before the 1-sample one",
    "check_fit_check_is_fitted": "2 columns are not a [q, qd, qdd] layout",
    "check_fit_idempotent": "2 columns are not a [q, qd, qdd] layout",
    "check_n_features_in": "2 columns are not a [q, qd, qdd] layout",
    "check_n_features_in_after_fitting": "4 columns are not a [q, qd, qdd] layout",
    "check_positive_only_tag_during_fit": "iris' 4 columns are not a [q, qd, qdd] layout",
    "check_readonly_memmap_input": "2 columns are not a [q, qd, qdd] layout",
    "check_regressor_data_not_an_array": "10 columns are not a [q, qd, qdd] layout",
    "check_regressor_multioutput": "10 columns are not a [q, qd, qdd] layout",
    "check_regressors_int": "10 columns are not a [q, qd, qdd] layout",
    "check_regressors_no_decision_function": "4 columns are not a [q, qd, qdd] layout",
    "check_regressors_train": "10 columns are not a [q, qd, qdd] layout",
}


def test_check_estimator():
    dut = GPRCompensator(features="q", optimize_points=20, random_state=0)
    check_estimator(dut, expected_failed_checks=EXPECTED_FAILED_CHECKS, on_skip=None)


def test_check_estimator_passes_every_check_once_any_width_is_a_layout(monkeypatch):
    """The expected failures above are the layout check and nothing else in this estimator."""
    for module in (base_module, features_module):
        monkeypatch.setattr(module, "joints_in_layout", lambda n_columns: n_columns)
    dut = GPRCompensator(features="q", optimize_points=20, random_state=0)
    check_estimator(dut, on_skip=None)
