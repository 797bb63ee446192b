"""A model trained with the sensor temperature, in the loop: CompensatorSystem's temperature port,
the station's wiring, the compiled row paths with T, and the error when the port is missing."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from ftdrake import CompensatorSystem, ScenarioConfig, build_station, simulate
from ftdrake import conventions as col
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.conventions import WRENCH_INTERNAL, WRENCH_STD
from ftdrake.errors import ConfigError
from ftdrake.testing import THETA, static_poses

K = np.array([0.039, -0.026, 0.12, 0.003, -0.0025, 0.002])  # the sensor's defaults, N/K


@pytest.fixture(scope="module")
def hybrid():
    """Static physics (gravity + biases + temperature) and a forest residual on [q, T]."""
    rng = np.random.default_rng(0)
    X = static_poses(rng, 400)
    T = rng.uniform(22, 33, 400)
    physics = PhysicsPayloadCompensator(mode="static", features="q")
    Y = (physics.regressor(X) @ THETA + np.outer(T - 22, K)
         + 0.05 * np.sin(3 * X[:, [0, 1, 2, 3, 5, 6]]))  # something for the residual
    model = HybridCompensator(physics=physics, residual=RandomForestCompensator(
        features="q", per_output=False, n_estimators=20, min_samples_leaf=5, random_state=0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return model.fit(np.c_[X, T], Y)


def test_the_compiled_row_paths_take_the_temperature(hybrid):
    rng = np.random.default_rng(1)
    rows = np.c_[static_poses(rng, 50), rng.uniform(20, 35, 50)]
    forest, physics = hybrid.residual_, hybrid.physics_
    assert forest.temperature_in_ and physics.temperature_in_
    for dut in (forest, physics, hybrid):
        row = dut.row_predictor()
        got = np.array([np.r_[row(r)[0], row(r)[1]] for r in rows])
        np.testing.assert_allclose(got[:, :6], dut.predict(rows), atol=1e-9)
        np.testing.assert_allclose(got[:, 6:], dut.predict_std(rows), atol=1e-9)
    # The forest's is the compiled walk, not a wrapper around predict.
    assert forest.row_predictor().__qualname__.startswith("temperature_row_predictor")


def test_a_temperature_model_in_the_loop_matches_its_offline_predict(hybrid):
    config = ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", 0.5
    config.sensor.temperature_time_constant_s = 0.2  # warm up by 9 K within the run
    station = build_station(config, hybrid)
    assert station.compensation.compensator.needs_temperature
    log = simulate(station, progress=False).log
    T = log[col.TEMPERATURE].to_numpy()
    assert T[-1] - T[0] > 8
    # The compensator reads the sensor's previous sample (the README's one-sample lag): its
    # temperature too. Features are q (and T), so the offline row is [q, 0, 0, T_prev].
    q = log[col.joint_columns(col.Q)].to_numpy()
    X = np.c_[q, np.zeros_like(q), np.zeros_like(q), np.r_[np.nan, T[:-1]]][5:]
    predicted = log[col.wrench_columns(WRENCH_INTERNAL)].to_numpy()[5:]
    np.testing.assert_allclose(predicted, hybrid.predict(X), atol=1e-9)
    np.testing.assert_allclose(log[col.wrench_columns(WRENCH_STD)].to_numpy()[5:],
                               hybrid.predict_std(X), atol=1e-9)
    # The temperature term is really applied: at the ambient temperature the prediction
    # would differ by about k·ΔT (1.10 N on Fz at the end; the forest residual's own split
    # on T adds up to 0.01 N, measured).
    cold = X.copy()
    cold[:, -1] = 22.0
    shift = predicted - hybrid.predict(cold)
    assert shift[-1, 2] > 1.0
    np.testing.assert_allclose(shift[-1], K * (X[-1, -1] - 22.0), atol=0.02)


def test_a_temperature_model_without_the_port_connected_is_named():
    rng = np.random.default_rng(0)
    X, T = static_poses(rng, 100), rng.uniform(22, 30, 100)
    model = RandomForestCompensator(features="q", n_estimators=3, random_state=0).fit(
        np.c_[X, T], rng.normal(size=(100, 6)))
    builder = DiagramBuilder()
    dut = builder.AddNamedSystem("compensator", CompensatorSystem(model, 1e-3))
    assert dut.needs_temperature
    assert dut.get_input_port_temperature().size() == 1
    wrench = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
    state = builder.AddSystem(ConstantVectorSource(np.r_[X[0, :7], np.zeros(7)]))
    builder.Connect(wrench.get_output_port(), dut.get_input_port_wrench_measured())
    builder.Connect(state.get_output_port(), dut.get_input_port_joint_state())
    simulator = Simulator(builder.Build())
    with pytest.raises(ConfigError, match="'temperature' input port is not connected"):
        simulator.AdvanceTo(0.005)
    # Connected, a NaN temperature is a fault (outputs hold), a finite one is used.
    builder = DiagramBuilder()
    dut = builder.AddNamedSystem("compensator", CompensatorSystem(model, 1e-3))
    for value, port in ((np.zeros(6), dut.get_input_port_wrench_measured()),
                        (np.r_[X[0, :7], np.zeros(7)], dut.get_input_port_joint_state()),
                        ([np.nan], dut.get_input_port_temperature())):
        builder.Connect(builder.AddSystem(ConstantVectorSource(value)).get_output_port(), port)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.005)
    context = dut.GetMyContextFromRoot(simulator.get_context())
    assert dut.get_output_port_fault().Eval(context)[0] == 1.0
