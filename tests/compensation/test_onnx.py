"""ONNX export (ftdrake.compensation.files.onnx_export) run by ONNX Runtime against scikit-learn.

Tolerance: |onnxruntime − sklearn| ≤ 1e-9 · (1 + |sklearn|) element-wise; the graphs are
double throughout (trees compare float32(x), as scikit-learn does), so the differences are
summation-order rounding, ~1e-15.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import onnx
import onnxruntime
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.ensemble import RandomForestRegressor
from sklearn.exceptions import ConvergenceWarning
from sklearn.preprocessing import MinMaxScaler
from sklearn.svm import SVR

from ftdrake.compensation.compiled import CompiledForest
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.features import FEATURE_SETS, select_features
from ftdrake.compensation.files.onnx_export import export_onnx

FEATURES = st.sampled_from(sorted(FEATURE_SETS))


def run_onnx(path, X):
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(["Y"], {"X": X})[0]


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    """A directory shared by a hypothesis test's examples (tmp_path would be per test)."""
    return tmp_path_factory.mktemp("onnx")


def assert_equal_to_sklearn(ours, reference):
    np.testing.assert_allclose(ours, reference, rtol=1e-9, atol=1e-9)


def threshold_probes(forests, X_train, rng):
    """Random rows, and rows with one input at or a float32 rounding away from a threshold."""
    rows = [rng.uniform(X_train.min() - 1, X_train.max() + 1, (30, X_train.shape[1]))]
    tree = forests[0].estimators_[0].tree_
    for node in np.flatnonzero(tree.children_left >= 0)[:30]:
        t = tree.threshold[node]
        for value in (t, np.nextafter(t, np.inf), np.nextafter(t, -np.inf), t + 1e-12):
            row = X_train[rng.integers(len(X_train))].copy()
            row[tree.feature[node]] = value
            rows.append(row[None, :])
    return np.vstack(rows)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_joints=st.integers(1, 3), features=FEATURES,
       n_outputs=st.integers(1, 4), per_output=st.booleans(), n_estimators=st.integers(1, 5),
       max_depth=st.one_of(st.none(), st.integers(1, 6)), n_rows=st.integers(2, 100))
def test_forest_graph_equals_sklearn(out_dir, seed, n_joints, features, n_outputs, per_output,
                                     n_estimators, max_depth, n_rows):
    rng = np.random.default_rng(seed)
    X_train = rng.integers(-4, 5, (n_rows, 3 * n_joints)) * 0.25  # float32-exact thresholds
    Y = np.sin(X_train @ rng.normal(size=(3 * n_joints, n_outputs)))
    Z = select_features(X_train, features)

    def forest(y):
        return RandomForestRegressor(n_estimators, max_depth=max_depth, random_state=seed).fit(Z, y)

    if per_output or n_outputs == 1:
        forests = [forest(Y[:, j]) for j in range(n_outputs)]
    else:
        forests = [forest(Y)]
    X = threshold_probes(forests, X_train, rng)
    expected = np.column_stack(
        [f.predict(select_features(X, features)).reshape(len(X), -1) for f in forests]
    )

    path = export_onnx(forests, out_dir / "forest.onnx", n_joints, features)

    assert_equal_to_sklearn(run_onnx(path, X), expected)


@pytest.mark.parametrize("kernel", ["rbf", "linear", "poly", "sigmoid"])
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_joints=st.integers(1, 3), features=FEATURES,
       n_outputs=st.integers(1, 3), clip=st.booleans(),
       gamma=st.one_of(st.just("scale"), st.floats(0.05, 2.0)))
def test_svr_graph_equals_sklearn(out_dir, kernel, seed, n_joints, features, n_outputs, clip,
                                  gamma):
    rng = np.random.default_rng(seed)
    X_train = rng.uniform(-2, 2, (50, 3 * n_joints))
    Y = np.sin(X_train @ rng.normal(size=(3 * n_joints, n_outputs)))
    Z = select_features(X_train, features)
    scaler = MinMaxScaler(feature_range=(-1, 1), clip=clip).fit(Z)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        svrs = [SVR(kernel=kernel, gamma=gamma, coef0=0.5, max_iter=20000)
                .fit(scaler.transform(Z), Y[:, j]) for j in range(n_outputs)]
    target_mean, target_scale = rng.normal(size=n_outputs), rng.uniform(0.1, 5, n_outputs)
    X = rng.uniform(-3, 3, (40, 3 * n_joints))
    Zs = scaler.transform(select_features(X, features))
    expected = target_mean + target_scale * np.column_stack([s.predict(Zs) for s in svrs])

    path = export_onnx((scaler, svrs, target_mean, target_scale), out_dir / "svr.onnx",
                       features=features)

    assert_equal_to_sklearn(run_onnx(path, X), expected)


def compensator_data(n_joints=3, n_outputs=6):
    rng = np.random.default_rng(7)
    X = rng.uniform(-1, 1, (120, 3 * n_joints))
    return X, np.sin(X @ rng.normal(size=(3 * n_joints, n_outputs))) * [20, 20, 20, 1, 1, 1]


@pytest.mark.parametrize("per_output", [True, False])
def test_forest_compensator_exports(tmp_path, per_output):
    X, Y = compensator_data()
    model = RandomForestCompensator("q", n_estimators=4, per_output=per_output,
                                           random_state=1).fit(X, Y)

    path = export_onnx(model, tmp_path / "rf.onnx")

    assert_equal_to_sklearn(run_onnx(path, X), model.predict(X))
    props = {p.key: p.value for p in onnx.load(path).metadata_props}
    assert (props["features"], props["n_joints"]) == ("q", "3")


def test_svr_compensator_exports(tmp_path):
    X, Y = compensator_data()
    model = SVRCompensator("q,qd").fit(X, Y)

    assert_equal_to_sklearn(run_onnx(export_onnx(model, tmp_path / "svr.onnx"), X),
                            model.predict(X))


def test_graph_interface_is_the_full_layout(tmp_path):
    rng = np.random.default_rng(0)
    forest = RandomForestRegressor(3, random_state=0).fit(rng.normal(size=(40, 4)),
                                                          rng.normal(size=(40, 2)))
    compiled = CompiledForest(forest, "q,qd")  # 2 joints; X has 6 columns, 4 are used

    model = onnx.load(export_onnx(compiled, tmp_path / "f.onnx"))

    (x,), (y,) = model.graph.input, model.graph.output
    assert (x.name, y.name) == ("X", "Y")
    assert x.type.tensor_type.elem_type == y.type.tensor_type.elem_type == onnx.TensorProto.DOUBLE
    assert [d.dim_value for d in x.type.tensor_type.shape.dim][1:] == [6]
    assert [d.dim_value for d in y.type.tensor_type.shape.dim][1:] == [2]
    X = rng.normal(size=(5, 6))
    assert_equal_to_sklearn(run_onnx(tmp_path / "f.onnx", X), forest.predict(X[:, :4]))


def test_arguments_must_agree_with_the_model(tmp_path):
    rng = np.random.default_rng(0)
    forest = RandomForestRegressor(2).fit(rng.normal(size=(20, 6)), rng.normal(size=20))
    with pytest.raises(ValueError, match="features"):
        export_onnx(forest, tmp_path / "f.onnx", n_joints=2)  # no features given
    with pytest.raises(ValueError, match="does not fit features"):
        export_onnx(forest, tmp_path / "f.onnx", n_joints=3, features="q,qd,qdd")
    with pytest.raises(ValueError, match="features='q' was given"):
        export_onnx(CompiledForest(forest, "q,qd"), tmp_path / "f.onnx", features="q")
    assert not list(tmp_path.iterdir())


def test_export_replaces_the_file_atomically(tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    forest = RandomForestRegressor(2).fit(rng.normal(size=(20, 3)), rng.normal(size=20))
    path = tmp_path / "model.onnx"
    path.write_bytes(b"previous model")

    def failing_replace(src, dst):
        raise OSError("disk full")

    import ftdrake.io

    monkeypatch.setattr(ftdrake.io.os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        export_onnx(forest, path, features="q,qd,qdd")
    assert path.read_bytes() == b"previous model"  # untouched, and no temporary file left
    assert os.listdir(tmp_path) == ["model.onnx"]

    monkeypatch.undo()
    export_onnx(forest, path, features="q,qd,qdd")
    assert os.listdir(tmp_path) == ["model.onnx"]
    assert_equal_to_sklearn(run_onnx(path, np.ones((1, 3)))[:, 0], forest.predict(np.ones((1, 3))))


def test_trees_that_are_one_leaf(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(10, 3))
    forests = [
        RandomForestRegressor(3, random_state=0).fit(X, np.full(10, 2.5)),  # y constant: a leaf
        RandomForestRegressor(2, max_depth=2, random_state=0).fit(X, X[:, 0]),
    ]
    expected = np.column_stack([f.predict(X) for f in forests])

    assert_equal_to_sklearn(CompiledForest(forests, "q,qd,qdd").predict(X), expected)
    path = export_onnx(forests, tmp_path / "f.onnx", features="q,qd,qdd")
    assert_equal_to_sklearn(run_onnx(path, X), expected)
