"""NoisyForceTorqueSensor: its statistics, quantization, saturation and rate match its config."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from scipy.spatial.transform import Rotation

from ftdrake import ConfigError, NoisyForceTorqueSensor, SensorConfig

W = np.array([3.0, -2.0, 15.0, 0.2, -0.1, 0.05])
ZERO6 = [0.0] * 6
# A sensor mounted exactly as modelled and at constant temperature (tests of other effects).
ALIGNED = {"mounting_rpy_deg": [0.0] * 3, "temperature_rise_c": 0.0}


def run_sensor(config, source_system, duration, log_period=None):
    builder = DiagramBuilder()
    source = builder.AddSystem(source_system)
    dut = builder.AddSystem(NoisyForceTorqueSensor(config))
    builder.Connect(source.get_output_port(), dut.GetInputPort("wrench_ideal"))
    period = log_period or dut.period
    measured = LogVectorOutput(dut.GetOutputPort("wrench_measured"), builder, period)
    saturated = LogVectorOutput(dut.GetOutputPort("saturated"), builder, period)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    t = measured.FindLog(context).sample_times()
    keep = t > 0  # the first sample is taken at t = 0 but logged before it lands
    return (t[keep], measured.FindLog(context).data().T[keep],
            saturated.FindLog(context).data().T[keep, 0], dut)


def test_mean_and_std_match_config():
    config = SensorConfig(drift_std=ZERO6, seed=3)
    t, y, _, dut = run_sensor(config, ConstantVectorSource(W), 5.0)
    spec = config.spec()
    sigma = np.asarray(spec.noise_std)
    res = np.asarray(spec.resolution)
    expected_std = np.sqrt(sigma**2 + res**2 / 12)  # white noise + quantization
    n = len(y)
    assert n == pytest.approx(5000, abs=2)
    # The reading logged at t was sampled at t − period; the thermal drift moves its mean.
    expected = dut.deterministic_reading(W, t - dut.period).mean(axis=0)
    mean_error = np.abs(y.mean(axis=0) - expected)
    assert np.all(mean_error <= 5 * expected_std / np.sqrt(n)), mean_error
    np.testing.assert_allclose(y.std(axis=0), expected_std, rtol=0.08)


def test_readings_are_quantized_to_resolution():
    config = SensorConfig(seed=1)
    _, y, _, _ = run_sensor(config, ConstantVectorSource(W), 0.5)
    res = np.asarray(config.spec().resolution)
    steps = y / res
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert np.all(np.ptp(y, axis=0) > 0)  # noise really moves the quantized reading


def test_saturation_clips_and_flags():
    config = SensorConfig(preset="ati_gamma", seed=0)
    big = W.copy()
    big[2] = 1000.0  # beyond the Gamma's ±400 N in Fz
    _, y, sat, _ = run_sensor(config, ConstantVectorSource(big), 0.1)
    assert np.all(sat == 1.0)
    np.testing.assert_allclose(y[:, 2], 400.0)
    _, _, sat_ok, _ = run_sensor(config, ConstantVectorSource(W), 0.1)
    assert np.all(sat_ok == 0.0)


def test_output_is_sampled_at_rate_and_held():
    config = SensorConfig(preset="robotiq_ft300", seed=2)
    assert config.spec().rate_hz == 100.0
    t, y, _, _ = run_sensor(config, ConstantVectorSource(W), 1.0, log_period=1e-3)
    changes = np.flatnonzero(np.any(np.diff(y, axis=0) != 0, axis=1))
    assert 90 <= len(changes) <= 100  # one new reading per 10 ms
    np.testing.assert_allclose(np.diff(t[changes + 1]), 0.01, atol=1e-9)


def test_same_seed_reproduces_other_seed_differs():
    a = run_sensor(SensorConfig(seed=5), ConstantVectorSource(W), 0.3)[1]
    b = run_sensor(SensorConfig(seed=5), ConstantVectorSource(W), 0.3)[1]
    c = run_sensor(SensorConfig(seed=6), ConstantVectorSource(W), 0.3)[1]
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)


def test_drift_is_a_random_walk_of_configured_rate():
    drift = [0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3]
    config = SensorConfig(noise_std=ZERO6, resolution=ZERO6, drift_std=drift, crosstalk=0.0,
                          bias=ZERO6, seed=4)
    _, y, _, dut = run_sensor(config, ConstantVectorSource(np.zeros(6)), 4.0)
    steps = np.diff(y, axis=0)
    np.testing.assert_allclose(steps.std(axis=0), np.asarray(drift) * np.sqrt(dut.period),
                               rtol=0.08)


def test_bandwidth_first_order_step_response():
    fc = 10.0
    config = SensorConfig(noise_std=ZERO6, resolution=ZERO6, drift_std=ZERO6, crosstalk=0.0,
                          bias=ZERO6, bandwidth_hz=fc, **ALIGNED)
    step = PiecewisePolynomial.ZeroOrderHold([0.0, 0.5, 2.0],
                                             np.column_stack([np.zeros(6), W, W]))
    t, y, _, _ = run_sensor(config, TrajectorySource(step), 1.5)
    tau = 1.0 / (2 * np.pi * fc)
    k = np.argmin(np.abs(t - (0.5 + tau)))
    np.testing.assert_allclose(y[k] / W, 1 - np.exp(-1), atol=0.04)
    np.testing.assert_allclose(y[-1], W, rtol=1e-6)


def test_crosstalk_couples_axes():
    config = SensorConfig(noise_std=ZERO6, resolution=ZERO6, drift_std=ZERO6, bias=ZERO6,
                          crosstalk=0.02, **ALIGNED)
    force_only = np.array([0.0, 0.0, 20.0, 0.0, 0.0, 0.0])
    _, y, _, dut = run_sensor(config, ConstantVectorSource(force_only), 0.05)
    C = dut.crosstalk_matrix
    assert np.all(np.abs(np.diag(C) - 1) == 0) and np.abs(C - np.eye(6)).max() > 0
    np.testing.assert_allclose(y[-1], C @ force_only, rtol=1e-9)
    assert np.abs(y[-1, [0, 1, 3, 4, 5]]).max() > 0.01  # leaks into other axes


def test_a_mounting_error_rotates_the_reading_about_the_sensor_origin():
    rpy = [3.0, -2.0, 5.0]
    config = SensorConfig(noise_std=ZERO6, resolution=ZERO6, drift_std=ZERO6, bias=ZERO6,
                          crosstalk=0.0, mounting_rpy_deg=rpy, temperature_rise_c=0.0)
    _, y, _, _ = run_sensor(config, ConstantVectorSource(W), 0.05)
    # Independent rotation: scipy's extrinsic xyz = Drake's RollPitchYaw (Rz·Ry·Rx).
    R_SSm = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
    np.testing.assert_allclose(y[-1], np.r_[R_SSm.T @ W[:3], R_SSm.T @ W[3:]], rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(y[-1, :3]), np.linalg.norm(W[:3]), rtol=1e-12)


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("noise_std", [-0.1] + [0.0] * 5, "noise_std"),
        ("range", [0.0] * 6, "range"),
        ("bias", [0.0] * 5, "bias: must have 6 entries"),
        ("preset", "nope", "unknown preset"),
        ("rate_hz", -5.0, "rate_hz"),
    ],
)
def test_bad_sensor_config_names_the_field(field, value, message):
    config = SensorConfig(**{field: value})
    with pytest.raises(ConfigError, match=message):
        NoisyForceTorqueSensor(config)


def test_runs_sharing_one_sensor_each_get_the_draws_of_their_own_samples():
    # Noise is a pure function of (seed, sample number). The sensor keeps one block of 4096
    # samples' draws; a run past a block boundary, and a second run starting over with the same
    # system, must each read the draws of their own sample numbers.
    config = SensorConfig(seed=9, resolution=ZERO6, drift_std=ZERO6, crosstalk=0.0, bias=ZERO6,
                          **ALIGNED)
    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource(W))
    dut = builder.AddSystem(NoisyForceTorqueSensor(config))
    builder.Connect(source.get_output_port(), dut.GetInputPort("wrench_ideal"))
    logger = LogVectorOutput(dut.GetOutputPort("wrench_measured"), builder, dut.period)
    diagram = builder.Build()
    long_run, short_run = Simulator(diagram), Simulator(diagram)
    long_run.AdvanceTo(5.0)  # 5000 samples: into the second block
    short_run.AdvanceTo(0.3)  # back to the first
    sigma = np.asarray(config.spec().noise_std)
    draws = np.vstack([np.random.default_rng([9, block]).standard_normal((4096, 12))
                       for block in (0, 1)])
    for run in (long_run, short_run):
        log = logger.FindLog(run.get_context()).data().T
        k = np.arange(len(log) - 1)  # row i holds sample i - 1 (logged before the update lands)
        # The filter starts at the first input, so with a constant input only noise remains.
        np.testing.assert_allclose(log[1:], W + sigma * draws[k, :6], rtol=1e-12, atol=1e-12)


def test_a_stream_delay_publishes_each_reading_whole_samples_late():
    quiet = dict(noise_std=ZERO6, resolution=ZERO6, drift_std=ZERO6, seed=1, **ALIGNED)
    ramp = PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([np.zeros(6), W]))
    _, on_time, _, _ = run_sensor(SensorConfig(**quiet), TrajectorySource(ramp), 0.2)
    _, late, _, dut = run_sensor(SensorConfig(stream_delay_s=0.0071, **quiet),
                                 TrajectorySource(ramp), 0.2)
    assert dut.delay_samples == 7  # 7.1 ms at 1 kHz, rounded
    np.testing.assert_array_equal(late[7:], on_time[:-7])
    np.testing.assert_array_equal(late[:8], np.tile(on_time[0], (8, 1)))  # first one held
    with pytest.raises(ConfigError, match="stream_delay_s"):
        SensorConfig(stream_delay_s=-0.01).validate()


def run_vibrating(config, speed, acceleration, duration=2.0, n=3):
    """The sensor with vibration fed a constant wrench and a constant joint motion: every
    joint at `speed` rad/s and `acceleration` rad/s² (‖v‖ = √n·speed); the readings."""
    builder = DiagramBuilder()
    dut = builder.AddSystem(NoisyForceTorqueSensor(config, n_joints=n))
    inputs = {"wrench_ideal": W, "joint_state": np.r_[np.zeros(n), np.full(n, speed)],
              "joint_acceleration": np.full(n, acceleration)}
    for name, value in inputs.items():
        if not dut.HasInputPort(name):  # a sensor without vibration has only the wrench
            continue
        port = dut.GetInputPort(name)
        builder.Connect(builder.AddSystem(ConstantVectorSource(value)).get_output_port(), port)
    measured = LogVectorOutput(dut.get_output_port_wrench_measured(), builder, dut.period)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(duration)
    return measured.FindLog(simulator.get_context()).data().T[1:], dut


PER_SPEED = [0.1, 0.1, 0.15, 0.004, 0.004, 0.004]
PER_ACCELERATION = [0.05, 0.05, 0.05, 0.002, 0.002, 0.002]


def test_vibration_grows_with_speed_and_acceleration_and_leaves_the_rest_alone():
    """The reading minus the same run's without vibration is white noise of σ = a·‖v‖ + b·‖v̇‖
    per axis; at rest the reading is bit-identical to the sensor without vibration."""
    base = SensorConfig(**ALIGNED, resolution=ZERO6, seed=4)
    vibrating = SensorConfig(**ALIGNED, resolution=ZERO6, seed=4,
                             vibration_per_speed=PER_SPEED,
                             vibration_per_acceleration=PER_ACCELERATION)
    quiet, _ = run_vibrating(base, 0.0, 0.0)
    at_rest, _ = run_vibrating(vibrating, 0.0, 0.0)
    np.testing.assert_array_equal(at_rest, quiet)
    moving, dut = run_vibrating(vibrating, 0.5, 2.0)
    difference = moving - quiet
    speed, acceleration = np.sqrt(3) * 0.5, np.sqrt(3) * 2.0
    expected = (speed * np.asarray(PER_SPEED) + acceleration * np.asarray(PER_ACCELERATION))
    np.testing.assert_allclose(dut.vibration_std(speed, acceleration), expected, rtol=1e-12)
    np.testing.assert_allclose(difference.std(axis=0), expected, rtol=0.05)
    assert np.all(np.abs(difference.mean(axis=0)) < 4 * expected / np.sqrt(len(difference)))
    # White: consecutive samples uncorrelated.
    lag1 = [np.corrcoef(difference[1:, i], difference[:-1, i])[0, 1] for i in range(6)]
    assert np.abs(lag1).max() < 0.1


def test_without_vibration_the_sensor_takes_no_joint_inputs_and_a_vibrating_one_needs_them():
    assert not NoisyForceTorqueSensor(SensorConfig()).HasInputPort("joint_state")
    config = SensorConfig(vibration_per_speed=PER_SPEED)
    with pytest.raises(ConfigError, match="n_joints"):
        NoisyForceTorqueSensor(config)
    with pytest.raises(ConfigError, match="vibration_per_acceleration"):
        NoisyForceTorqueSensor(SensorConfig(vibration_per_acceleration=[-0.1, *ZERO6[1:]]))
