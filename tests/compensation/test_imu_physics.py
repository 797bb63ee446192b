"""The physics payload model with its kinematics from an IMU at the sensor.

(a) On the rigid rig with an ideal IMU it identifies the tool's true inertial parameters (from
    Drake's model of the tool) and predicts the ideal reading.
(b) On the compliant rig, where the wrist vibrates on the gearbox springs and the loop reads
    the motor-side encoders, it predicts the reading far better than the same model on the
    joints: the IMU sees the motion the encoders miss.
"""

import dataclasses as dc
import warnings

import numpy as np
import pytest

from ftdrake import conventions as col
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.features import stack_layout
from ftdrake.config import ScenarioConfig
from ftdrake.errors import ConfigError
from ftdrake.physics.rigid_body import tool_inertia
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station


def _rows(log):
    q, qd, qdd = (log[col.joint_columns(p)].to_numpy() for p in (col.Q, col.QD, col.QDD))
    X = stack_layout(q, qd, qdd)
    return X, np.hstack([X, log[list(col.IMU_INPUTS)].to_numpy()])


def _config(duration, compliant):
    config = ScenarioConfig()
    config.cable.enabled = False
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = duration
    config.sensor = dc.replace(config.sensor, crosstalk=0.0, temperature_rise_c=0.0,
                               drift_std=[0.0] * 6, mounting_rpy_deg=[0.0] * 3)
    config.imu.enabled = True
    if compliant:
        config.transmission = dc.replace(config.transmission, enabled=True,
                                         chain_reads_motors=True,
                                         transmission_error=[3e-5] * 7)
    return config


@pytest.fixture(scope="module")
def rigid():
    config = _config(1.5, compliant=False)
    config.sensor.imperfections = False
    config.imu = dc.replace(config.imu.without_noise(), enabled=True, alpha_cutoff_hz=100.0)
    station = build_station(config)
    return station, simulate(station, progress=False).log.iloc[100:]


def test_identifies_the_tools_true_parameters_from_an_ideal_imu(rigid):
    station, log = rigid
    _, X = _rows(log)
    Y = log[col.wrench_columns(col.MEASURED)].to_numpy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a short run leaves some inertia poorly excited
        model = ImuPayloadCompensator().fit(X, Y)
    plant = station.scene.plant
    m, p, _ = tool_inertia(plant, plant.CreateDefaultContext(), station.scene.sensor_frame,
                           station.scene.tool_bodies)
    assert model.parameters_[0] == pytest.approx(m, rel=2e-3)
    np.testing.assert_allclose(model.parameters_[1:4], m * p, rtol=0, atol=2e-3)
    np.testing.assert_allclose(model.parameters_[10:16], 0.0, atol=5e-3)  # no sensor bias
    # It reads the reading: a few mN and 0.1 mN·m, the IMU's sample and the reaction's
    # step being one plant step apart.
    residual = Y - model.predict(X)
    assert np.abs(residual[:, :3]).std(axis=0).max() < 0.01
    assert np.abs(residual[:, 3:]).std(axis=0).max() < 1e-3


@pytest.fixture(scope="module")
def compliant():
    config = _config(2.5, compliant=True)
    return config, simulate(build_station(config), progress=False).log.iloc[200:]


def test_imu_sees_the_vibration_the_encoders_miss(compliant):
    config, log = compliant
    X_joints, X_imu = _rows(log)
    Y = log[col.wrench_columns(col.MEASURED)].to_numpy()
    noise = np.asarray(config.sensor.spec().noise_std)
    train, test = slice(0, len(Y) * 7 // 10), slice(len(Y) * 7 // 10, None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        joints = PhysicsPayloadCompensator().fit(X_joints[train], Y[train])
        imu = ImuPayloadCompensator().fit(X_imu[train], Y[train])
    joint_error = (Y[test] - joints.predict(X_joints[test])).std(axis=0) / noise
    imu_error = (Y[test] - imu.predict(X_imu[test])).std(axis=0) / noise
    assert joint_error.max() > 4.0  # the vibration is real in the joint model's error
    vibrating = joint_error > 3.0
    assert np.all(imu_error[vibrating] < joint_error[vibrating] / 2)
    assert np.all(imu_error < 2.5)


def test_refuses_a_layout_without_the_imu_and_static_mode():
    X = np.zeros((50, 21))
    with pytest.raises(ValueError, match=r"imu_acc \(3\), imu_gyro \(3\), imu_alpha \(3\)"):
        ImuPayloadCompensator().fit(X, np.zeros((50, 6)))
    with pytest.raises(ConfigError, match="mode"):
        ImuPayloadCompensator(mode="static").fit(np.zeros((50, 30)), np.zeros((50, 6)))


def test_predicts_only_rows_with_the_imu(rigid):
    _, log = rigid
    X_joints, X = _rows(log)
    Y = log[col.wrench_columns(col.MEASURED)].to_numpy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ImuPayloadCompensator().fit(X, Y)
    assert model.n_joints_ == 7
    with pytest.raises(ValueError, match="features"):
        model.predict(X_joints)
    row = X[10]
    mean, std = model.row_predictor()(row)
    np.testing.assert_allclose(mean, model.predict(X[10:11])[0])
    np.testing.assert_allclose(std, model.predict_std(X[10:11])[0])
    assert model.out_of_domain(X).sum() == 0


def test_the_loop_view_says_it_needs_the_imu(rigid):
    from ftdrake.compensation.contract import loop_view

    _, log = rigid
    _, X = _rows(log)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ImuPayloadCompensator().fit(X, log[col.wrench_columns(col.MEASURED)].to_numpy())
    assert loop_view(model).needs_imu
    assert not loop_view(PhysicsPayloadCompensator().fit(X[:, :21], model.predict(X))).needs_imu
