"""The station: one diagram from one config, typed handles, a returned result (the named port
accessors of every system: tests/systems/test_ports.py)."""

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser

import ftdrake
from ftdrake import ScenarioConfig, SimResult, build_station, simulate
from ftdrake import conventions as col
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.conventions import (
    BIAS,
    WRENCH_COMPENSATED,
    WRENCH_CONTACT,
    WRENCH_INTERNAL,
    WRENCH_STD,
)
from ftdrake.data.dataset import joint_state_layout, wrench_targets


def short_free_config(duration=0.3):
    config = ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", duration
    return config


@pytest.fixture(scope="module")
def forest():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 2, (200, 21))
    return ftdrake.RandomForestCompensator(features="q", n_estimators=3, random_state=0).fit(
        X, rng.normal(size=(200, 6)))


def test_station_without_compensator_has_no_compensation_parts():
    station = build_station(short_free_config())
    assert station.compensation is None and station.arrows is None
    assert station.period == pytest.approx(1e-3)
    names = {s.get_name() for s in station.diagram.GetSystems()}
    assert {"controller", "ft_sensor", "noisy_ft_sensor", "contact_truth"} <= names
    assert "compensator" not in names


def test_simulate_returns_the_log_with_compensation_columns(forest):
    station = build_station(short_free_config(), forest)
    result = simulate(station, progress=False)
    assert isinstance(result, SimResult)
    log = result.log
    assert len(log) == result.timing["samples"] == 300  # 0.3 s at 1 kHz, t = 0 dropped
    for prefix in (WRENCH_INTERNAL, WRENCH_CONTACT, WRENCH_STD):
        assert set(col.wrench_columns(prefix)) <= set(log.columns)
    # The compensator reads the sensor's previous sample (README: it lags the sensor by one
    # sample) and the plant's state of this sample; its external estimate is measured −
    # predicted. Checked here against the model's own predict, independently of the loop.
    measured = log[col.wrench_columns(col.MEASURED)].to_numpy()
    predicted = log[col.wrench_columns(WRENCH_INTERNAL)].to_numpy()
    compensated = log[col.wrench_columns(WRENCH_COMPENSATED)].to_numpy()
    np.testing.assert_allclose(compensated[5:], measured[4:-1] - predicted[5:], atol=1e-12)
    # The bias tracker (on by default) reads that one sample later and subtracts its bias.
    bias = log[col.wrench_columns(BIAS)].to_numpy()
    np.testing.assert_allclose(log[col.wrench_columns(WRENCH_CONTACT)].to_numpy()[6:],
                               compensated[5:-1] - bias[6:], atol=1e-12)
    q = log[col.joint_columns(col.Q)].to_numpy()
    X = np.hstack([q, np.zeros_like(q), np.zeros_like(q)])
    np.testing.assert_allclose(predicted[5:], forest.predict(X[5:]), atol=1e-9)
    # The context is returned, not stored on the station: the loggers are still readable.
    logger = station.compensation.loggers["wrench_internal"]
    assert logger.FindLog(result.context).num_samples() == len(log) + 1


def test_the_log_records_the_joint_state_the_compensator_read():
    """A [q, q̇, q̈] model's prediction in the loop equals its prediction, offline, on the log's
    ``est`` layout, sample for sample: the log holds the loop's own q̇ and causal q̈
    estimate, so a model trained on logs meets in the loop the inputs it was fitted on. (The
    plant's exact q̈ is not what the loop reads: with it the prediction differs.)"""
    config = short_free_config(1.0)
    data = simulate(build_station(config), progress=False).log
    model = PhysicsPayloadCompensator().fit(joint_state_layout(data), wrench_targets(data))
    log = simulate(build_station(config, model), progress=False).log
    in_loop = log[col.wrench_columns(WRENCH_INTERNAL)].to_numpy()
    np.testing.assert_allclose(in_loop, model.predict(joint_state_layout(log)), atol=1e-9)
    assert np.abs(in_loop - model.predict(joint_state_layout(log, "plant"))).max() > 0.01


def test_building_parses_the_models_once_for_the_plant_and_once_for_the_controller(
        monkeypatch):
    calls = []
    original = Parser.AddModels

    def counting(self, *args, **kwargs):
        calls.append(kwargs.get("url") or kwargs.get("file_name") or args)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Parser, "AddModels", counting)
    config = short_free_config()
    build_station(config)
    arm = config.models.arm
    assert calls.count(arm) == 2  # the simulated plant and the controller's model
    assert len(calls) == 4  # arm, tool, environment; the controller's arm


def test_a_run_starts_where_the_controller_holds_the_arm():
    """The controller's tool model is 15 % light, so its PD law holds the arm off the desired
    pose. A run starts there — as a real controller's log does, after holding the arm — not
    at the desired pose, where the arm would drop at up to 8 rad/s² in its first steps.
    Checked against the trajectory's own acceleration, independent of how the start was
    found."""
    station = build_station(ScenarioConfig())  # the task's motion, from rest
    log = simulate(station, progress=False, duration=0.02).log
    qdd = log[col.joint_columns(col.QDD, 7)].to_numpy()
    desired = np.vstack([station.trajectory.derivative(2).value(t).ravel()
                         for t in log[col.TIME]])
    # What is left is the PD law lagging the start's jerk: 0.23 rad/s², against 8 from the pose.
    assert np.abs(qdd - desired).max() < 0.5  # rad/s², over the first 20 ms
    q0 = log[col.joint_columns(col.Q, 7)].to_numpy()[0]
    sag = np.abs(q0 - station.trajectory.value(0.0).ravel()).max()
    assert 0.005 < sag < 0.1  # rad: held off the desired pose, by a steady-state error
