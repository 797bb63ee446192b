"""RandomForestCompensator and SVRCompensator: shapes, accuracy, scaling, sklearn contract."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sklearn.base import clone
from sklearn.metrics import explained_variance_score
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.utils.estimator_checks import check_estimator

from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.features import FEATURE_SETS

# -- synthetic free-motion data ------------------------------------------------------------
# A 7-joint arm whose joints alternate z/y axes carries a 1.2 kg tool; the sensor reads the
# tool's weight rotated into the sensor frame, the torque of that weight about the sensor
# origin, a small inertial force from joint accelerations, and white noise.
N_JOINTS = 7
OFFSET = np.array([0.0, -0.6, 0.3, -1.2, 0.2, 0.9, 0.0])  # rad
AMPLITUDE = np.array([0.4, 0.3, 0.3, 0.4, 0.3, 0.5, 0.5])  # rad
FREQUENCY = np.array([0.31, 0.47, 0.59, 0.73, 0.89, 1.03, 1.21])  # rad/s
BASE_PHASE = np.random.default_rng(0).uniform(0, 2 * np.pi, size=(N_JOINTS, 3))
NOISE_STD = np.array([0.05, 0.05, 0.05, 0.003, 0.003, 0.003])  # N, N·m


def gravity_wrench(q: np.ndarray, qdd: np.ndarray, mass=1.2, p_SoCm=(0.01, -0.02, 0.08)):
    """[Fx Fy Fz Tx Ty Tz] (N, N·m) in the sensor frame, for rows of joint angles q."""
    R_WS = Rotation.identity(len(q))
    for i, axis in enumerate("zyzyzyz"):
        R_WS = R_WS * Rotation.from_euler(axis, q[:, i : i + 1])
    f_S = mass * R_WS.inv().apply([0.0, 0.0, -9.81]) - 0.3 * mass * qdd[:, [0, 1, 3]]
    return np.hstack([f_S, np.cross(p_SoCm, f_S)])


def excitation(seed: int, seconds=10.0, rate_hz=50.0, phase_jitter=0.3) -> np.ndarray:
    """[q, qd, qdd] of one repetition of a Fourier excitation, re-timed by random phases."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1 / rate_hz)[:, None, None]
    w = FREQUENCY[:, None] * np.array([1.0, 1.7, 2.9])
    a = AMPLITUDE[:, None] * np.array([1.0, 0.5, 0.25])
    arg = w * t + BASE_PHASE + rng.normal(0, phase_jitter, size=BASE_PHASE.shape)
    q = OFFSET + (a * np.sin(arg)).sum(-1)
    qd = (a * w * np.cos(arg)).sum(-1)
    qdd = (-a * w**2 * np.sin(arg)).sum(-1)
    return np.hstack([q, qd, qdd])


def free_motion(seeds, seconds=10.0):
    """(X, Y_measured, Y_true, trajectory_id) for repetitions `seeds`, stacked in time order."""
    X = [excitation(s, seconds) for s in seeds]
    truth = [gravity_wrench(x[:, :N_JOINTS], x[:, 2 * N_JOINTS :]) for x in X]
    noisy = [
        y + np.random.default_rng(1000 + s).normal(0, NOISE_STD, y.shape)
        for s, y in zip(seeds, truth, strict=True)
    ]
    ids = np.concatenate([np.full(len(x), s) for s, x in zip(seeds, X, strict=True)])
    return np.vstack(X), np.vstack(noisy), np.vstack(truth), ids


@pytest.fixture(scope="module")
def train():
    return free_motion(range(1, 9))  # 8 repetitions × 500 rows


@pytest.fixture(scope="module")
def held_out():
    return free_motion([98, 99])


@pytest.fixture(scope="module")
def small():
    X, Y, _, _ = free_motion([1], seconds=4.0)
    return X, Y


def small_forest(**kw):
    return RandomForestCompensator(n_estimators=5, random_state=0, **kw)


# -- shapes ----------------------------------------------------------------------------------
@pytest.mark.parametrize("features", sorted(FEATURE_SETS))
@pytest.mark.parametrize(
    "make",
    [small_forest, lambda **kw: small_forest(per_output=False, **kw), SVRCompensator],
    ids=["rf_per_output", "rf_multi_output", "svr"],
)
def test_shapes(make, features, small):
    X, Y = small
    n_used = FEATURE_SETS[features] * N_JOINTS
    dut = make(features=features).fit(X, Y)
    assert dut.predict(X[:7]).shape == (7, 6)
    assert dut.n_joints_ == N_JOINTS and dut.n_outputs_ == 6
    one = make(features=features).fit(X, Y[:, 2])
    assert one.predict(X[:7]).shape == (7,)
    if isinstance(dut, RandomForestCompensator):
        assert len(dut.forests_) == (6 if dut.per_output else 1)
        assert dut.feature_importances_.shape == (6, n_used)
        np.testing.assert_allclose(dut.feature_importances_.sum(axis=1), 1.0)
    else:
        assert len(dut.svrs_) == 6
        assert dut.scaler_.n_features_in_ == n_used


def test_per_output_forests_are_independent_single_output_models(small):
    X, Y = small
    dut = small_forest().fit(X, Y)
    for j, forest in enumerate(dut.forests_):
        assert forest.n_outputs_ == 1
        np.testing.assert_array_equal(dut.predict(X)[:, j], forest.predict(X))


# -- accuracy ---------------------------------------------------------------------------------
def test_forest_predicts_held_out_repetition(train, held_out):
    # The study's best setting (joint angles only, one forest per axis) on unseen
    # repetitions of the excitation: explained variance >= 0.9 on every axis.
    X, Y, _, _ = train
    Xt, Yt, _, _ = held_out
    dut = RandomForestCompensator(features="q", n_estimators=30, random_state=0, n_jobs=2)
    score = explained_variance_score(Yt, dut.fit(X, Y).predict(Xt), multioutput="raw_values")
    assert score.min() >= 0.9, score


def test_feature_importances_find_the_joint_that_matters():
    # Axis 0 depends on q_3 only, axis 1 on qd_5 only: each forest must rank that column first.
    rng = np.random.default_rng(4)
    X = rng.uniform(-1, 1, size=(400, 3 * N_JOINTS))
    Y = np.column_stack([np.sin(3 * X[:, 3]), X[:, N_JOINTS + 5] ** 2])
    dut = RandomForestCompensator(n_estimators=10, random_state=0).fit(X, Y)
    assert dut.feature_importances_.argmax(axis=1).tolist() == [3, N_JOINTS + 5]


def test_svr_target_scaling_helps_the_small_torque_axis(train, held_out):
    # Tz is ~40× smaller than the forces: with raw targets the default epsilon tube swallows
    # much of it; standardised targets fit it as well as the other axes.
    X, Y, _, _ = train
    Xt, Yt, _, _ = held_out
    scaled = SVRCompensator().fit(X, Y[:, 5]).predict(Xt)
    raw = SVRCompensator(scale_targets=False).fit(X, Y[:, 5]).predict(Xt)
    mse_scaled, mse_raw = np.mean((scaled - Yt[:, 5]) ** 2), np.mean((raw - Yt[:, 5]) ** 2)
    assert mse_scaled < 0.7 * mse_raw, (mse_scaled, mse_raw)


# -- SVR input scaling ------------------------------------------------------------------------
def test_svr_scaler_maps_training_min_max_to_unit_interval(small):
    X, Y = small
    dut = SVRCompensator(features="q,qd").fit(X, Y)
    Zs = dut.scaler_.transform(X[:, : 2 * N_JOINTS])
    # MinMaxScaler computes x·scale + offset, exact up to one rounding step.
    np.testing.assert_allclose(Zs.min(axis=0), -1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(Zs.max(axis=0), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(dut.target_mean_, Y.mean(axis=0))
    np.testing.assert_allclose(dut.target_scale_, Y.std(axis=0))


def test_svr_without_target_scaling_keeps_targets_raw(small):
    X, Y = small
    dut = SVRCompensator(scale_targets=False).fit(X, Y)
    np.testing.assert_array_equal(dut.target_mean_, 0.0)
    np.testing.assert_array_equal(dut.target_scale_, 1.0)


def test_svr_constant_target_column_stays_finite(small):
    X, Y = small
    Y = Y.copy()
    Y[:, 3] = 0.25
    pred = SVRCompensator().fit(X, Y).predict(X)
    np.testing.assert_allclose(pred[:, 3], 0.25, atol=1e-9)


# -- scikit-learn contract -------------------------------------------------------------------
_LAYOUT = "feeds a column count that is not 3n; [q, qd, qdd] input is refused by design"
_LAYOUT_CHECKS = [
    "check_estimators_overwrite_params",
    "check_estimators_fit_returns_self",
    "check_readonly_memmap_input",
    "check_n_features_in_after_fitting",
    "check_positive_only_tag_during_fit",
    "check_estimators_dtypes",
    "check_dtype_object",
    "check_regressors_train",
    "check_regressor_data_not_an_array",
    "check_regressor_multioutput",
    "check_regressors_no_decision_function",
    "check_regressors_int",
    "check_fit2d_1sample",
    "check_fit2d_1feature",
    "check_fit_idempotent",
    "check_fit_check_is_fitted",
    "check_n_features_in",
]


@pytest.mark.parametrize(
    "dut",
    [small_forest(), small_forest(per_output=False), SVRCompensator()],
    ids=["rf_per_output", "rf_multi_output", "svr"],
)
def test_check_estimator(dut):
    check_estimator(dut, expected_failed_checks={name: _LAYOUT for name in _LAYOUT_CHECKS})


def _tripled(X):
    # Any m columns → [X, X, X]: a valid layout for m "joints". Leaves non-2-D input alone
    # so that the checks of bad input still reach the estimator's own validation.
    A = np.asarray(X)
    return np.hstack([A, A, A]) if A.ndim == 2 else X


class _AnyWidth:
    """Test adapter: lets the column-count checks above run through the real fit/predict."""

    def fit(self, X, y):
        return super().fit(_tripled(X), y)

    def predict(self, X):
        return super().predict(_tripled(X))


class AnyWidthForest(_AnyWidth, RandomForestCompensator):
    pass


class AnyWidthSVR(_AnyWidth, SVRCompensator):
    pass


@pytest.mark.parametrize("dut", [AnyWidthForest(n_estimators=5, random_state=0), AnyWidthSVR()])
def test_check_estimator_through_layout_adapter(dut):
    width = "the adapter triples the columns, so n_features_in_ is 3× what the check passes"
    check_estimator(
        dut,
        expected_failed_checks={
            "check_n_features_in_after_fitting": width,
            "check_n_features_in": width,
        },
    )


def test_clone_and_grid_search(small):
    X, Y = small
    dut = RandomForestCompensator(features="q", n_estimators=4, random_state=1)
    twin = clone(dut)
    assert twin.get_params() == dut.get_params() and twin is not dut
    search = GridSearchCV(
        dut, {"min_samples_leaf": [2, 50]}, cv=KFold(3), scoring="neg_mean_squared_error"
    ).fit(X, Y)
    assert search.best_estimator_.predict(X).shape == Y.shape
    svr = GridSearchCV(SVRCompensator(), {"C": [1.0, 10.0]}, cv=KFold(3)).fit(X, Y[:, 0])
    assert svr.best_params_["C"] in (1.0, 10.0)


# -- bad input -------------------------------------------------------------------------------
@pytest.mark.parametrize("make", [small_forest, SVRCompensator])
def test_nonfinite_rows_are_refused_with_counts(make, small):
    X, Y = small
    X = X.copy()
    X[[3, 9], 2] = np.nan
    X[11, 0] = np.inf
    with pytest.raises(ValueError, match=r"3 of \d+ rows \(first at row 3\)"):
        make().fit(X, Y)
    dut = make().fit(small[0], Y)
    with pytest.raises(ValueError, match=r"NaN or infinity.*before predicting"):
        dut.predict(X)


@pytest.mark.parametrize("make", [small_forest, SVRCompensator])
def test_wrong_column_count_at_predict_is_refused(make, small):
    X, Y = small
    dut = make().fit(X, Y)
    with pytest.raises(ValueError, match="features"):
        dut.predict(X[:, :-3])


@pytest.mark.parametrize("make", [small_forest, SVRCompensator])
def test_unknown_feature_set_is_refused(make, small):
    X, Y = small
    with pytest.raises(ValueError, match=r"'features' parameter .* among .* Got 'q,qdd'"):
        make(features="q,qdd").fit(X, Y)
