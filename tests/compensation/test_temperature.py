"""Sensor temperature: the simulated warm-up and zero drift, and compensators that model it."""

import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import SensorConfig
from ftdrake import conventions as col
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.systems.noisy_sensor import NoisyForceTorqueSensor
from ftdrake.testing import THETA, sinusoids


def run_sensor(config, duration, seed):
    """The noisy sensor alone, fed the ideal wrench of the payload THETA along a trajectory of
    all joints (Fourier-like): returns X, the readings, the temperature port, sample times."""
    n = round(duration * 1000) + 1  # the sensor's 1 kHz samples
    X = sinusoids(np.random.default_rng(seed), range(7), n=n, duration=duration, amplitude=0.5)
    t = np.linspace(0, duration, n)
    ideal = PhysicsPayloadCompensator().regressor(X) @ np.r_[THETA[:10], np.zeros(6)]
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, ideal.T)))
    dut = builder.AddSystem(NoisyForceTorqueSensor(config))
    builder.Connect(source.get_output_port(), dut.get_input_port_wrench_ideal())
    period = 20 * dut.period  # log at 50 Hz
    wrench = LogVectorOutput(dut.get_output_port_wrench_measured(), builder, period)
    temperature = LogVectorOutput(dut.get_output_port_temperature(), builder, period)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    ts = wrench.FindLog(context).sample_times()[1:]
    Y = wrench.FindLog(context).data().T[1:]
    T = temperature.FindLog(context).data()[0, 1:]
    rows = np.round((ts - dut.period) / dut.period).astype(int)  # logged one sample late
    return X[rows], Y, T, ts, dut


FAST = {"temperature_time_constant_s": 20.0, "temperature_rise_c": 10.0, "crosstalk": 0.0,
        "mounting_rpy_deg": [0.0] * 3}


def test_the_temperature_warms_up_and_the_zero_drifts_with_it():
    config = SensorConfig(noise_std=[0.0] * 6, resolution=[0.0] * 6, drift_std=[0.0] * 6, **FAST)
    X, Y, T, ts, dut = run_sensor(config, 40.0, seed=0)
    expected = 22.0 + 10.0 * (1 - np.exp(-(ts - dut.period) / 20.0))  # logged one sample late
    np.testing.assert_allclose(T, expected, atol=1e-6)
    ideal = PhysicsPayloadCompensator().regressor(X) @ np.r_[THETA[:10], np.zeros(6)]
    # The drift at the end: k·ΔT with ΔT ≈ 8.6 K; the wrench itself moves, so compare the
    # reading minus the (filtered, nearly equal) ideal wrench with the config's coefficients.
    offset = Y - ideal - np.asarray(config.bias)
    late = ts > 35
    k_seen = offset[late].mean(axis=0) / (T[late] - 22.0).mean()
    np.testing.assert_allclose(k_seen, config.temperature_coefficients, rtol=0.1, atol=2e-4)


def test_compensation_drifts_without_temperature_and_not_with_it():
    config = SensorConfig(drift_std=[0.0] * 6, seed=1, **FAST)  # the random walk aside
    sigma = np.asarray(config.spec().noise_std)
    X, Y, T, _, _ = run_sensor(config, 60.0, seed=1)
    X_test, Y_test, T_test, ts, _ = run_sensor(
        SensorConfig(drift_std=[0.0] * 6, seed=2, **FAST), 60.0, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        plain = PhysicsPayloadCompensator(identification="consistent").fit(X, Y)
        dut = PhysicsPayloadCompensator(identification="consistent").fit(np.c_[X, T], Y)

    def drift(model, Xm):  # the compensated wrench's 2-s means, worst |mean| in noise σ
        compensated = Y_test - model.predict(Xm)
        means = [compensated[(ts >= a) & (ts < a + 2)].mean(axis=0) for a in range(0, 58, 2)]
        return np.abs(np.array(means)).max(axis=0) / sigma

    without, with_t = drift(plain, X_test), drift(dut, np.c_[X_test, T_test])
    assert without.max() > 10, without  # measured: 9.8–15.6σ per axis
    assert with_t.max() < 2, with_t  # measured: 0.20–0.26σ
    k = dut.identified()["temperature"]["coefficients"]
    np.testing.assert_allclose(k, config.temperature_coefficients, rtol=0.1, atol=2e-4)
    # The row path (the loop's) takes the temperature as the row's last entry.
    row = dut.row_predictor()
    x = np.r_[X_test[5], T_test[5]]
    np.testing.assert_allclose(row(x)[0], dut.predict(x[None])[0], atol=1e-10)


def test_every_compensator_takes_a_temperature_column_and_says_when_it_is_missing():
    rng = np.random.default_rng(0)
    X = sinusoids(rng, range(7), n=300)
    T = np.linspace(22, 30, 300)
    Y = PhysicsPayloadCompensator().regressor(X) @ THETA + np.outer(T - 22, [0.1] * 6)
    forest = RandomForestCompensator(features="q", n_estimators=10, random_state=0)
    hybrid = HybridCompensator(residual=forest)
    for dut in (forest, hybrid):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            dut.fit(np.c_[X, T], Y)
        assert dut.temperature_in_ and dut.predict(np.c_[X, T]).shape == (300, 6)
        with pytest.raises(ValueError, match="temperature"):
            dut.predict(X)
    assert col.TEMPERATURE == "temperature"
