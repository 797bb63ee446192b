"""CompensationChain wires what its docstring says: bit for bit the compensator → bias tracker →
detector connected by hand here, port by port from the systems' port tables, on the same
random input stream."""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import (
    CompensationChain,
    CompensatorSystem,
    ContactDetector,
    OnlineBiasTracker,
    RandomForestCompensator,
    ScenarioConfig,
)

N = 7
NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])  # N, N·m: well below the detector's
PERIOD = 1e-3
STEPS = 600  # 0.6 s
OUTPUTS = ("wrench_internal", "wrench_compensated", "wrench_contact", "wrench_std",
           "out_of_domain", "fault", "contact", "contact_force", "bias", "tracker_std", "payload")


def forest(temperature: bool):
    """A small forest on q, q̇, q̈ (and the temperature as its last input column), trained on
    [-1, 2] per input, predicting a wrench of the size of NOISE."""
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 2, (200, 3 * N + temperature))
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=3, random_state=0).fit(
        X, rng.normal(size=(200, 6)) * NOISE)


def stream(seed: int = 3) -> dict:
    """Inputs sample by sample: q, v = q̇ and q̈ within the training range (q out of it for one
    sample), a 20 N contact from 0.3 to 0.4 s, a NaN reading at 0.2 s, a re-tare pulse at
    0.15 s, a grasp at 0.45 s, noisy gravity and motion of S near rest, a warming sensor."""
    rng = np.random.default_rng(seed)
    k = np.arange(STEPS + 1)
    t = k * PERIOD
    w = 1.0 + 0.5 * np.arange(N)  # rad/s: |q̈| ≤ 0.1 w² < 2
    phase = rng.uniform(0, 2 * np.pi, N)
    state = np.hstack([0.5 + 0.1 * np.sin(w * t[:, None] + phase),
                       0.1 * w * np.cos(w * t[:, None] + phase)])
    state[100, 2] = 5.0
    wrench = rng.normal(size=(len(k), 6)) * NOISE
    wrench[(t >= 0.3) & (t < 0.4), 0] += 20.0
    wrench[200] = np.nan  # a fault

    def pulse(at):
        return ((t >= at) & (t < at + 3 * PERIOD)).astype(float)[:, None]

    gravity = np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.05, (len(k), 3))
    return {"t": t, "wrench_measured": wrench, "joint_state": state,
            "temperature": 25.0 + 5.0 * t[:, None], "tared": pulse(0.15),
            "payload_changed": pulse(0.45), "gravity_S": gravity,
            "motion_S": rng.normal(0.0, 0.2, (len(k), 6))}


def configs():
    base = ScenarioConfig()
    base.chain.compensator.acceleration_cutoff_hz = 10.0  # not the systems' default
    tracked = base.with_chain(bias_tracker=dc.replace(
        base.chain.bias_tracker, initial_bias=[0.5, -0.3, 0.2, 0.01, 0.0, -0.02]))
    untracked = base.with_chain(bias_tracker=dc.replace(base.chain.bias_tracker, enabled=False))
    payload = tracked.with_chain(bias_tracker=dc.replace(
        tracked.chain.bias_tracker, track_payload=True, track_payload_motion=True,
        start_settled=False))
    return {"tracker_off": (untracked, False), "tracker_on": (tracked, False),
            "track_payload": (payload, True)}


def wire_by_hand(builder, config, model, sources) -> dict:
    """The three systems connected as their port tables say; returns output name → port."""
    comp = builder.AddSystem(CompensatorSystem(
        model, PERIOD, n_joints=N,
        acceleration_cutoff_hz=config.chain.compensator.acceleration_cutoff_hz))
    detector = builder.AddSystem(ContactDetector(config.chain.detector.for_model(model), PERIOD))
    builder.Connect(sources["wrench_measured"], comp.get_input_port_wrench_measured())
    builder.Connect(sources["joint_state"], comp.get_input_port_joint_state())
    if comp.needs_temperature:
        builder.Connect(sources["temperature"], comp.get_input_port_temperature())
    out = {"wrench_internal": comp.get_output_port_wrench_internal(),
           "wrench_compensated": comp.get_output_port_wrench_compensated(),
           "wrench_contact": comp.get_output_port_wrench_compensated(),
           "wrench_std": comp.get_output_port_wrench_std(),
           "out_of_domain": comp.get_output_port_out_of_domain(),
           "fault": comp.get_output_port_fault(),
           "contact": detector.get_output_port_contact(),
           "contact_force": detector.get_output_port_contact_force()}
    tracker = None
    if config.chain.bias_tracker.enabled:
        tracker = builder.AddSystem(OnlineBiasTracker(config.chain.bias_tracker, config.sensor,
                                                      PERIOD))
        builder.Connect(comp.get_output_port_wrench_compensated(),
                        tracker.get_input_port_wrench_compensated())
        builder.Connect(comp.get_output_port_out_of_domain(),
                        tracker.get_input_port_out_of_domain())
        builder.Connect(comp.get_output_port_fault(), tracker.get_input_port_fault())
        builder.Connect(detector.get_output_port_contact(), tracker.get_input_port_contact())
        builder.Connect(tracker.get_output_port_wrench_std(),
                        detector.get_input_port_wrench_std_tracker())
        builder.Connect(sources["tared"], tracker.get_input_port_tared())
        out["wrench_contact"] = tracker.get_output_port_wrench_contact()
        out["bias"] = tracker.get_output_port_bias()
        out["tracker_std"] = tracker.get_output_port_wrench_std()
        if config.chain.bias_tracker.track_payload:
            builder.Connect(sources["gravity_S"], tracker.get_input_port_gravity_S())
            builder.Connect(sources["motion_S"], tracker.get_input_port_motion_S())
            builder.Connect(sources["payload_changed"],
                            tracker.get_input_port_payload_changed())
            out["payload"] = tracker.get_output_port_payload()
    builder.Connect(out["wrench_contact"], detector.get_input_port_wrench_contact())
    builder.Connect(comp.get_output_port_wrench_std(), detector.get_input_port_wrench_std())
    return out, tracker


@pytest.mark.parametrize("case", list(configs()))
def test_the_chain_is_the_three_systems_wired_by_hand(case):
    config, temperature = configs()[case]
    model = forest(temperature)
    inputs = stream()
    builder = DiagramBuilder()
    sources = {name: builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
        inputs["t"], values.T))).get_output_port() for name, values in inputs.items()
        if name != "t"}
    dut = builder.AddSystem(CompensationChain(model, config.chain_config(), period=PERIOD,
                                              n_joints=N, gravity="input"))
    for i in range(dut.num_input_ports()):
        port = dut.get_input_port(i)
        builder.Connect(sources[port.get_name()], port)
    expected, tracker = wire_by_hand(builder, config, model, sources)
    names = [dut.get_output_port(i).get_name() for i in range(dut.num_output_ports())]
    assert sorted(names) == sorted(expected)
    assert set(names) <= set(OUTPUTS)
    logs = {name: (LogVectorOutput(dut.GetOutputPort(name), builder, PERIOD),
                   LogVectorOutput(expected[name], builder, PERIOD)) for name in names}
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    dut.initialize(context)
    if tracker is not None:  # the tracker's start, as BiasTrackerConfig documents it
        settings = config.chain.bias_tracker
        tracker.set_estimate(tracker.GetMyMutableContextFromRoot(context),
                             settings.initial_bias, [0.0] * 4, settled=settings.start_settled)
    simulator.AdvanceTo(STEPS * PERIOD)

    got = {name: chain.FindLog(context).data() for name, (chain, _) in logs.items()}
    for name, (_, by_hand) in logs.items():
        np.testing.assert_array_equal(got[name], by_hand.FindLog(context).data(), err_msg=name)
    # The stream exercises what is compared: a contact found, an out-of-domain sample, a
    # fault, and (with the tracker) a bias that moves.
    assert got["contact"].max() == 1.0 and got["out_of_domain"].max() == 1.0
    assert got["fault"].max() == 1.0
    if "bias" in got:
        assert np.ptp(got["bias"], axis=1).max() > 1e-3
    if "payload" in got:
        assert np.abs(got["payload"]).max() > 0.0
