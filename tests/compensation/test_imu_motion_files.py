"""Model files of the IMU payload model and of a std of the motion: saved, loaded, and
predicting the same (mean and std) after the round trip; the manifest names the IMU inputs."""

import numpy as np
import pytest

from ftdrake import conventions as col
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.compensation.estimators.motion_std import MotionStdCompensator
from ftdrake.compensation.files.persistence import load_model, read_manifest, save_model
from tests.helpers import imu_rows


def _imu_rows(n=300, seed=0):
    """IMU rows and a rigid tool's wrench there, with noise."""
    X, Y = imu_rows(n, seed)
    return X, Y + np.random.default_rng(seed + 1).normal(0, 0.02, Y.shape)


def test_the_imu_model_round_trips_and_names_its_imu_inputs(tmp_path):
    X, Y = _imu_rows()
    model = ImuPayloadCompensator().fit(X, Y)
    path = save_model(model, tmp_path / "imu.ftd")
    loaded = load_model(path)
    assert isinstance(loaded, ImuPayloadCompensator) and loaded.needs_imu
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.predict_std(X), model.predict_std(X))
    ranges = read_manifest(path)["input_range"]
    assert list(ranges)[-9:] == list(col.IMU_INPUTS)
    assert ranges["imu_acc_z"] == [X[:, 23].min(), X[:, 23].max()]


@pytest.mark.parametrize("inner", ["forest", "imu"])
def test_a_std_of_the_motion_round_trips(tmp_path, inner):
    if inner == "imu":
        X, Y = _imu_rows()
        estimator = ImuPayloadCompensator()
    else:
        rng = np.random.default_rng(1)
        X = rng.uniform(-1, 1, (300, 21))
        Y = np.sin(X[:, :6]) + rng.normal(0, 0.05, (300, 6)) * (1 + np.abs(X[:, 7:13]))
        estimator = RandomForestCompensator(n_estimators=10, random_state=0)
    model = MotionStdCompensator(estimator).fit(X, Y)
    loaded = load_model(save_model(model, tmp_path / "motion.ftd"))
    assert type(loaded) is MotionStdCompensator
    assert loaded.needs_imu == (inner == "imu")
    assert loaded.noise_.n_joints_ == 7  # the motion is the joints', not the IMU's columns
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.predict_std(X), model.predict_std(X))
    # The std is the motion's: it differs from row to row.
    assert np.ptp(loaded.predict_std(X)[:, 0]) > 0
