"""CompensationChain does what its ports promise, checked on its outputs against quantities
computed here without the chain's systems: the compensated wrench is T·(measured − model
prediction) and recovers an injected contact wrench in S; without the tracker the contact
wrench is the compensated one; with it, the compensated wrench less the published bias, which
follows an injected drift; contact rises above the detector's threshold from the config and
not below it; NaN and out-of-range inputs raise fault and out_of_domain and never reach the
outputs.

The model: a static physics model of a payload on a sensor mounted 8°, −6°, 10° off its model
(so T = reading_to_model_frame() is not the identity), fitted on static poses; it reads q only.
The chain's outputs lag its inputs by one sample (every system is sampled): output sample k is
what the chain made of input sample k − 1."""

import dataclasses as dc
import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from scipy.spatial.transform import Rotation

from ftdrake import ChainConfig, CompensationChain
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.testing import HOME, SIGMA, THETA, static_poses

N = 7
PERIOD = 1e-3
#: The sensor's mounting, R_SmS (Sm: the frame it measures in), and M on [F; T].
R_SmS = Rotation.from_euler("xyz", [8.0, -6.0, 10.0], degrees=True).as_matrix()
M = np.kron(np.eye(2), R_SmS)
BIAS = THETA[10:]  # the sensor's bias, in Sm


def payload_wrench(q):
    """The payload's wrench in S at rest in poses q (rows), from its known parameters."""
    X = np.hstack([q, np.zeros((len(q), 2 * N))])
    return PhysicsPayloadCompensator(mode="static").regressor(X) @ np.r_[THETA[:10], np.zeros(6)]


def reading(q, external_S, rng):
    """What the mounted sensor reads: M·(payload + external wrench, in S) + bias + noise σ."""
    return (payload_wrench(q) + external_S) @ M.T + BIAS + rng.normal(size=(len(q), 6)) * SIGMA


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(0)
    X = static_poses(rng, 1500)  # HOME ± 0.8 rad on every joint
    Y = reading(X[:, :N], 0.0, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation warnings are tested elsewhere
        return PhysicsPayloadCompensator(mode="static", features="q",
                                         identify_mounting=True).fit(X, Y)


def motion(seconds):
    """t, and [q; v] of a slow motion of every joint within ±0.5 rad of HOME (in domain)."""
    t = np.arange(round(seconds / PERIOD) + 1) * PERIOD
    w = 2 * np.pi * (0.3 + 0.1 * np.arange(N))
    q = HOME + 0.5 * np.sin(w * t[:, None])
    return t, np.hstack([q, 0.5 * w * np.cos(w * t[:, None])])


def config(tracker=False, **detector):
    base = ChainConfig()
    return base.replace(
        bias_tracker=dc.replace(base.bias_tracker, enabled=tracker, time_constant_s=0.2,
                                rate_bound_sigmas=float("inf")),
        detector=dc.replace(base.detector, **detector))


def run(model, chain_config, t, inputs):
    """The chain fed `inputs` (port name → samples) at t; its outputs logged, name → rows."""
    builder = DiagramBuilder()
    chain = builder.AddSystem(CompensationChain(model, chain_config, period=PERIOD, n_joints=N))
    for name, values in inputs.items():
        source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
            t, np.asarray(values, dtype=float).T)))
        builder.Connect(source.get_output_port(), chain.GetInputPort(name))
    names = [chain.get_output_port(i).get_name() for i in range(chain.num_output_ports())]
    loggers = {name: LogVectorOutput(chain.GetOutputPort(name), builder, PERIOD)
               for name in names}
    simulator = Simulator(builder.Build())
    chain.initialize(simulator.get_mutable_context())
    simulator.AdvanceTo(t[-1])
    context = simulator.get_context()
    out = {name: logger.FindLog(context).data().T for name, logger in loggers.items()}
    assert all(len(rows) == len(t) for rows in out.values())
    return chain, out


def lagged(values):
    """Input samples aligned with the outputs they make: row k holds input sample k − 1."""
    return np.vstack([np.full((1, values.shape[1]), np.nan), values[:-1]])


def test_the_compensated_wrench_is_T_times_measured_minus_the_prediction(model):
    rng = np.random.default_rng(1)
    t, state = motion(0.5)
    external = np.zeros((len(t), 6))
    external[t >= 0.2] = [12.0, -8.0, 15.0, 0.4, 0.3, -0.5]  # N, N·m in S, about So
    measured = reading(state[:, :N], external, rng)
    _, out = run(model, config(), t, {"wrench_measured": measured, "joint_state": state})

    T = model.reading_to_model_frame()
    assert np.abs(T @ M - np.eye(6)).max() < 1e-3  # T undoes the mounting
    row = np.hstack([state, np.zeros((len(t), N))])  # the model reads q only
    predicted = lagged(model.predict(row))
    compensated = (lagged(measured) - predicted) @ T.T
    np.testing.assert_allclose(out["wrench_internal"][1:], predicted[1:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out["wrench_compensated"][1:], compensated[1:], rtol=0, atol=1e-9)
    # In S: the external wrench injected, to within the sensor's noise and the model's error.
    error = (out["wrench_compensated"] - lagged(external))[1:]
    assert np.all(np.abs(error) < 6 * SIGMA + 1e-3 * np.abs(lagged(external)[1:])), (
        np.abs(error).max(axis=0))
    # Without the tracker the detector judges the compensated wrench itself.
    np.testing.assert_array_equal(out["wrench_contact"], out["wrench_compensated"])
    assert "bias" not in out and "tracker_std" not in out


def test_with_the_tracker_the_contact_wrench_is_compensated_less_a_bias_that_follows_drift(
        model):
    """A drift of the reading (1.5 N/s on Fx) is followed by the bias, not taken for contact."""
    rng = np.random.default_rng(2)
    t, state = motion(2.0)
    rate = np.array([1.5, -1.0, 1.2, 0.01, -0.01, 0.02])  # N/s, N·m/s in S
    drift = np.outer(t, rate)
    measured = reading(state[:, :N], drift, rng)
    _, out = run(model, config(tracker=True),
                 t, {"wrench_measured": measured, "joint_state": state, "tared": np.zeros(
                     (len(t), 1))})

    # Each sample: the compensated wrench the tracker read (one sample earlier) less the bias
    # it published.
    np.testing.assert_allclose(out["wrench_contact"][2:],
                               out["wrench_compensated"][1:-1] - out["bias"][2:],
                               rtol=0, atol=1e-12)
    # The bias follows the drift (within its lag of rate·τ and the noise); the contact wrench
    # is left near zero while the compensated one carries the drift.
    end = drift[-2]
    assert np.all(np.abs(out["bias"][-1] - end) < 0.25 * np.abs(end) + 3 * SIGMA), (
        out["bias"][-1], end)
    assert np.all(np.abs(out["wrench_contact"][-1]) < 0.25 * np.abs(end) + 6 * SIGMA)
    assert np.all(np.abs(out["wrench_compensated"][-1] - end) < 6 * SIGMA)
    # The detector judges the contact wrench: the drift, past its threshold in the
    # compensated wrench by the end, is no contact.
    assert np.linalg.norm(out["wrench_compensated"][-1, :3]) > 1.5 * config().detector.force_on
    assert out["contact"].max() == 0.0


@pytest.mark.parametrize("times_threshold", [1.2, 0.8])
def test_contact_rises_above_the_configured_threshold_and_not_below(model, times_threshold):
    rng = np.random.default_rng(3)
    t, state = motion(0.6)
    chain_config = config(test="norm")
    threshold = chain_config.detector.force_on  # N, on ‖F‖ (std_gain 0: a fixed threshold)
    assert chain_config.detector.std_gain == 0.0
    external = np.zeros((len(t), 6))
    pressed = (t >= 0.2) & (t < 0.3)
    external[pressed, :3] = times_threshold * threshold * np.array([0.6, 0.0, 0.8])
    measured = reading(state[:, :N], external, rng)
    chain, out = run(model, chain_config, t, {"wrench_measured": measured,
                                              "joint_state": state})

    assert chain.config.detector.test == "norm" and chain.config.detector.force_on == threshold
    contact = out["contact"][:, 0]
    if times_threshold < 1:
        assert contact.max() == 0.0 and out["contact_force"].max() == 0.0
        return
    first = np.flatnonzero(contact)[0]
    k0, debounce = np.flatnonzero(pressed)[0], chain_config.detector.debounce_on
    assert k0 + debounce <= first <= k0 + debounce + 2, (k0, first)
    assert contact[np.flatnonzero(pressed)[-1] + chain_config.detector.debounce_off + 3:].max() \
        == 0.0  # released after the press
    # While in contact, contact_force is ‖F‖ of the wrench judged (one sample earlier).
    on = contact == 1.0
    force = np.linalg.norm(lagged(out["wrench_contact"][:, :3]), axis=1)
    np.testing.assert_allclose(out["contact_force"][on, 0], force[on], rtol=1e-12)
    assert np.all(out["contact_force"][~on] == 0.0)


def test_nan_and_out_of_range_inputs_raise_fault_and_out_of_domain_and_stay_out(model):
    rng = np.random.default_rng(4)
    t, state = motion(0.3)
    measured = reading(state[:, :N], 0.0, rng)
    measured[100] = np.nan
    state[150, 3] = np.nan
    state[200:205, 0] = HOME[0] + 1.5  # beyond the training range of HOME ± 0.8 rad
    _, out = run(model, config(tracker=True), t, {"wrench_measured": measured,
                                                  "joint_state": state,
                                                  "tared": np.zeros((len(t), 1))})

    fault, ood = out["fault"][:, 0], out["out_of_domain"][:, 0]
    assert np.flatnonzero(fault).tolist() == [101, 151]
    assert np.flatnonzero(ood).tolist() == list(range(201, 206))
    for name, rows in out.items():
        assert np.all(np.isfinite(rows)), name
    # A faulted sample holds the outputs of the last good one.
    for k in (101, 151):
        for name in ("wrench_internal", "wrench_compensated"):
            np.testing.assert_array_equal(out[name][k], out[name][k - 1], err_msg=name)
    assert out["contact"].max() == 0.0
