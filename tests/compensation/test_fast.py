"""Compiled predictors (ftdrake.compensation.compiled) against scikit-learn's own predict.

Tolerance: |ours − sklearn| ≤ 1e-9 · (1 + |sklearn|) element-wise. The forests agree to
rounding (~1e-16): same float32 input cast, same `<=` rule, same summation order; the kernel
models differ only in summation order.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.ensemble import ExtraTreesRegressor, RandomForestRegressor
from sklearn.exceptions import ConvergenceWarning
from sklearn.preprocessing import MinMaxScaler
from sklearn.svm import SVR

from ftdrake.compensation.compiled import (
    CompiledForest,
    CompiledGaussianProcess,
    FastKernelModel,
)
from ftdrake.compensation.compiled import forest as compiled_forest
from ftdrake.compensation.compiled import kernel as compiled_kernel
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.gpr import GPRCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.features import FEATURE_SETS, select_features

RTOL = ATOL = 1e-9
FEATURES = st.sampled_from(sorted(FEATURE_SETS))


def assert_equal_to_sklearn(ours, reference):
    np.testing.assert_allclose(ours, reference, rtol=RTOL, atol=ATOL)


def fit_forests(seed, n_joints, features, n_outputs, per_output, kind=RandomForestRegressor,
                n_rows=80, on_grid=True, **params):
    """Forests on [q, qd, qdd] rows; on_grid puts inputs on a 0.25 grid, so every threshold is
    a float32-exact midpoint that probe rows can sit on or a hair next to."""
    rng = np.random.default_rng(seed)
    n_cols = 3 * n_joints
    if on_grid:
        X = rng.integers(-4, 5, (n_rows, n_cols)) * 0.25
    else:
        X = rng.normal(size=(n_rows, n_cols))
    Y = np.sin(X @ rng.normal(size=(n_cols, n_outputs)))
    Y += 0.1 * rng.normal(size=Y.shape)
    Z = select_features(X, features)
    if per_output:
        forests = [kind(random_state=seed, **params).fit(Z, Y[:, j]) for j in range(n_outputs)]
    else:  # a 1-output forest is fitted on a 1-D y, as scikit-learn asks
        forests = [kind(random_state=seed, **params).fit(Z, Y[:, 0] if n_outputs == 1 else Y)]
    return forests, X


def sklearn_forest_predict(forests, X, features):
    Z = select_features(X, features)
    return np.column_stack([f.predict(Z).reshape(len(Z), -1) for f in forests])


def probe_rows(forests, X_train, rng, n=40):
    """Random rows, plus rows with one input at, or within a float32 rounding of, a threshold:
    where comparing float64(x) instead of float32(x) would take the other branch."""
    rows = [rng.uniform(X_train.min() - 1, X_train.max() + 1, (n, X_train.shape[1]))]
    tree = forests[0].estimators_[0].tree_
    interior = np.flatnonzero(tree.children_left >= 0)[:n]
    for node in interior:
        t = tree.threshold[node]
        t32 = np.float64(np.float32(t))
        for value in (t, np.nextafter(t, np.inf), np.nextafter(t, -np.inf), t + 1e-12, t32,
                      np.float64(np.nextafter(np.float32(t), np.float32(np.inf)))):
            row = X_train[rng.integers(len(X_train))].copy()
            row[tree.feature[node]] = value
            rows.append(row[None, :])
    return np.vstack(rows)


forest_shapes = {
    "seed": st.integers(0, 2**31 - 1),
    "n_joints": st.integers(1, 3),
    "features": FEATURES,
    "n_outputs": st.integers(1, 4),
    "per_output": st.booleans(),
    "kind": st.sampled_from([RandomForestRegressor, ExtraTreesRegressor]),
    "n_estimators": st.integers(1, 6),
    "max_depth": st.one_of(st.none(), st.integers(1, 8)),
    "min_samples_leaf": st.integers(1, 3),
    "n_rows": st.integers(2, 300),
    "on_grid": st.booleans(),
}


@settings(max_examples=150, deadline=None)
@given(**forest_shapes)
def test_compiled_forest_equals_sklearn(seed, n_joints, features, n_outputs, per_output, kind,
                                        n_estimators, max_depth, min_samples_leaf, n_rows,
                                        on_grid):
    forests, X_train = fit_forests(
        seed, n_joints, features, n_outputs, per_output, kind, n_rows, on_grid,
        n_estimators=n_estimators, max_depth=max_depth, min_samples_leaf=min_samples_leaf,
    )
    X = probe_rows(forests, X_train, np.random.default_rng(seed))
    expected = sklearn_forest_predict(forests, X, features)

    dut = CompiledForest(forests, features)

    assert (dut.n_joints, dut.n_outputs) == (n_joints, n_outputs)
    assert_equal_to_sklearn(dut.predict(X), expected)
    out = np.empty(n_outputs)
    for i in range(0, len(X), 7):
        assert dut.predict_one(X[i], out) is out
        assert_equal_to_sklearn(out, expected[i])


def test_compiled_forest_takes_a_bare_forest_and_unlimited_depth():
    forests, X = fit_forests(0, 7, "q,qd,qdd", 6, False, n_rows=400, on_grid=False,
                             n_estimators=10)
    dut = CompiledForest(forests[0])  # not in a list; max_depth=None, min_samples_leaf=1
    assert max(e.tree_.max_depth for e in forests[0].estimators_) > 8
    assert_equal_to_sklearn(dut.predict(X), forests[0].predict(X))


def test_construction_compiles_so_the_first_call_does_not():
    forests, X = fit_forests(1, 2, "q,qd", 3, True, n_estimators=3)
    dut = CompiledForest(forests, "q,qd")
    compiled = (len(compiled_forest._forest_predict_one.signatures),
                len(compiled_forest._forest_predict.signatures))

    dut.predict_one(X[0])
    dut.predict(X)

    assert (len(compiled_forest._forest_predict_one.signatures),
            len(compiled_forest._forest_predict.signatures)) == compiled


def test_forest_rejects_non_forests_and_a_wrong_feature_set():
    forests, _ = fit_forests(2, 1, "q,qd,qdd", 1, True, n_estimators=2)  # 3 inputs
    with pytest.raises(ValueError, match="not a fitted forest"):
        CompiledForest([RandomForestRegressor()])
    with pytest.raises(ValueError, match="does not fit features"):
        CompiledForest(forests, "q,qd")  # 3 inputs are not 2 blocks of n
    with pytest.raises(ValueError, match="does not fit features"):
        CompiledForest(forests, "q,qd,qdd", n_joints=3)


# -- kernel models ----------------------------------------------------------------------------
def fit_svrs(seed, kernel, n_joints, features, n_outputs, gamma, C, degree, coef0, clip):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (60, 3 * n_joints))
    Y = np.sin(X @ rng.normal(size=(3 * n_joints, n_outputs)))
    Z = select_features(X, features)
    scaler = MinMaxScaler(feature_range=(-1, 1), clip=clip).fit(Z)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        svrs = [
            SVR(kernel=kernel, gamma=gamma, C=C, degree=degree, coef0=coef0, max_iter=20000)
            .fit(scaler.transform(Z), Y[:, j])
            for j in range(n_outputs)
        ]
    target_mean = rng.normal(size=n_outputs) * 10
    target_scale = rng.uniform(0.1, 5, n_outputs)
    return scaler, svrs, target_mean, target_scale


def sklearn_svr_predict(scaler, svrs, target_mean, target_scale, X, features):
    Zs = scaler.transform(select_features(X, features))
    return target_mean + target_scale * np.column_stack([svr.predict(Zs) for svr in svrs])


svr_shapes = {
    "seed": st.integers(0, 2**31 - 1),
    "n_joints": st.integers(1, 3),
    "features": FEATURES,
    "n_outputs": st.integers(1, 3),
    "gamma": st.one_of(st.sampled_from(["scale", "auto"]), st.floats(0.05, 2.0)),
    "C": st.floats(0.1, 10.0),
    "degree": st.integers(1, 4),
    "coef0": st.floats(-1.0, 1.0),
    "clip": st.booleans(),
}


@pytest.mark.parametrize("kernel", ["rbf", "linear", "poly", "sigmoid"])
@settings(max_examples=40, deadline=None)
@given(**svr_shapes)
def test_fast_svr_equals_sklearn(kernel, seed, n_joints, features, n_outputs, gamma, C, degree,
                                 coef0, clip):
    parts = fit_svrs(seed, kernel, n_joints, features, n_outputs, gamma, C, degree, coef0, clip)
    X = np.random.default_rng(seed + 1).uniform(-3, 3, (50, 3 * n_joints))  # beyond training
    expected = sklearn_svr_predict(*parts, X, features)

    dut = FastKernelModel.from_svrs(*parts[:2], features, *parts[2:])

    assert_equal_to_sklearn(dut.predict(X), expected)
    assert_equal_to_sklearn(dut.predict_one(X[3]), expected[3])


def test_fast_svr_predicts_in_chunks(monkeypatch):
    parts = fit_svrs(3, "rbf", 2, "q,qd,qdd", 2, "scale", 1.0, 3, 0.0, False)
    X = np.random.default_rng(0).uniform(-2, 2, (30, 6))
    dut = FastKernelModel.from_svrs(*parts[:2], "q,qd,qdd", *parts[2:])
    monkeypatch.setattr(compiled_kernel, "CHUNK_ENTRIES", 1)  # one row at a time

    assert_equal_to_sklearn(dut.predict(X), sklearn_svr_predict(*parts, X, "q,qd,qdd"))


def test_fast_svr_rejects_unsupported_kernels():
    X = np.random.default_rng(0).uniform(-1, 1, (20, 3))
    scaler = MinMaxScaler((-1, 1)).fit(X)
    svr = SVR(kernel="precomputed").fit(X @ X.T, X[:, 0])
    with pytest.raises(ValueError, match="unsupported kernel"):
        FastKernelModel.from_svrs(scaler, [svr], "q,qd,qdd")


# -- through the compensators -----------------------------------------------------------------
def compensator_data(n_joints=3, n_outputs=6, n_rows=150):
    rng = np.random.default_rng(5)
    X = rng.uniform(-1, 1, (n_rows, 3 * n_joints))
    return X, np.sin(X @ rng.normal(size=(3 * n_joints, n_outputs))) * [20, 20, 20, 1, 1, 1]


@pytest.mark.parametrize("per_output", [True, False])
def test_compiled_predictor_of_a_forest_compensator(per_output):
    X, Y = compensator_data()
    model = RandomForestCompensator("q,qd", n_estimators=5, per_output=per_output,
                                           random_state=0).fit(X, Y)
    dut = model.compiled_predictor()
    assert isinstance(dut, CompiledForest)
    assert_equal_to_sklearn(dut.predict(X), model.predict(X))


def test_compiled_predictor_of_an_svr_compensator():
    X, Y = compensator_data()
    model = SVRCompensator("q,qd,qdd").fit(X, Y)
    dut = model.compiled_predictor()
    assert isinstance(dut, FastKernelModel)
    assert_equal_to_sklearn(dut.predict(X), model.predict(X))


gp_shapes = {
    "seed": st.integers(0, 2**31 - 1),
    "n_joints": st.integers(1, 3),
    "features": FEATURES,
    "n_outputs": st.integers(1, 4),
    "shared_kernel": st.booleans(),
    "include_noise": st.booleans(),
    "one_d_target": st.booleans(),
}


@settings(max_examples=25, deadline=None)
@given(**gp_shapes)
def test_compiled_gp_equals_predict_and_predict_std(seed, n_joints, features, n_outputs,
                                                    shared_kernel, include_noise, one_d_target):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, (60, 3 * n_joints))
    Y = np.sin(X @ rng.normal(size=(3 * n_joints, n_outputs))) * rng.uniform(0.1, 30, n_outputs)
    Y += rng.normal(scale=0.05, size=Y.shape) + rng.normal(scale=10, size=n_outputs)
    y = Y[:, 0] if one_d_target else Y
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model = GPRCompensator(features, max_points=40, optimize_points=30,
                               shared_kernel=shared_kernel, include_noise=include_noise,
                               random_state=seed).fit(X, y)
    # Training rows (where a noise-free std nearly vanishes), rows between them, rows beyond.
    probe = np.vstack([X[model.subset_indices_[:5]], rng.uniform(-3, 3, (15, 3 * n_joints))])
    mean_ref = np.asarray(model.predict(probe)).reshape(len(probe), -1)
    std_ref = np.asarray(model.predict_std(probe)).reshape(len(probe), -1)

    dut = model.compiled_predictor()
    assert isinstance(dut, CompiledGaussianProcess)
    mean, std = dut.predict_with_std(probe)
    assert_equal_to_sklearn(mean, mean_ref)
    # Compare variances: where the noise-free std nearly vanishes its square root amplifies
    # rounding, and the variance is what the formula computes.
    scale = model.target_scale_[: std.shape[1]] ** 2 * model.signal_variance_.max()
    np.testing.assert_allclose(std**2, std_ref**2, rtol=RTOL, atol=ATOL * scale.max())
    one_mean, one_std = dut.predict_one_with_std(probe[7])
    assert_equal_to_sklearn(one_mean, mean_ref[7])
    assert_equal_to_sklearn(one_std, std_ref[7])
    assert_equal_to_sklearn(dut.predict_one(probe[8]), mean_ref[8])


def test_compiled_gp_rejects_bad_rows_and_non_gps():
    X, Y = compensator_data(n_joints=2, n_rows=40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model = GPRCompensator("q", max_points=20, optimize_points=0).fit(X, Y)
    dut = CompiledGaussianProcess(model)
    with pytest.raises(ValueError, match="6 columns for 2 joints"):
        dut.predict_one_with_std(np.zeros(4))
    row = np.zeros(6)
    row[5] = np.nan  # a column "q" does not use: the state is still broken
    with pytest.raises(ValueError, match="NaN or infinity"):
        dut.predict_one_with_std(row)
    with pytest.raises(ValueError, match="not a fitted GPRCompensator"):
        CompiledGaussianProcess(GPRCompensator())


def test_models_without_a_compiled_form_say_so_and_still_run_row_by_row():
    model = PhysicsPayloadCompensator("q", mode="static")
    assert model.compiled_predictor() is None
    with pytest.raises(TypeError, match="has no ONNX export"):
        model.onnx_parts()


def test_row_predictor_of_an_unfitted_compensator_is_refused():
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        RandomForestCompensator().row_predictor()


# -- bad input --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def predictors():
    forests, _ = fit_forests(4, 2, "q,qd", 2, True, n_estimators=3)
    svr_parts = fit_svrs(4, "rbf", 2, "q", 2, "scale", 1.0, 3, 0.0, False)
    return [CompiledForest(forests, "q,qd"),
            FastKernelModel.from_svrs(*svr_parts[:2], "q", *svr_parts[2:])]


@settings(max_examples=30, deadline=None)
@given(which=st.integers(0, 1), n_columns=st.integers(0, 12).filter(lambda c: c != 6))
def test_wrong_column_count_is_a_value_error(predictors, which, n_columns):
    dut = predictors[which]
    with pytest.raises(ValueError, match="6 columns for 2 joints"):
        dut.predict(np.zeros((3, n_columns)))
    with pytest.raises(ValueError, match="6 columns for 2 joints"):
        dut.predict_one(np.zeros(n_columns))


@pytest.mark.parametrize("which", [0, 1])
def test_wrong_dimensions_are_value_errors(predictors, which):
    dut = predictors[which]
    with pytest.raises(ValueError, match="shape"):
        dut.predict(np.zeros(6))
    with pytest.raises(ValueError, match="shape"):
        dut.predict_one(np.zeros((1, 6)))


@settings(max_examples=30, deadline=None)
@given(which=st.integers(0, 1), row=st.integers(0, 4), column=st.integers(0, 5),
       bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_nan_or_inf_rows_are_value_errors(predictors, which, row, column, bad):
    dut = predictors[which]
    X = np.zeros((5, 6))
    X[row, column] = bad  # also in columns the feature set does not use: the state is broken
    with pytest.raises(ValueError, match=f"NaN or infinity in 1 of 5 rows \\(first at row {row}"):
        dut.predict(X)
    with pytest.raises(ValueError, match=f"first at column {column}"):
        dut.predict_one(X[row])
