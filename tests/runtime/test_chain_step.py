"""ChainStep equals the Drake diagram it is made from: every exported output, every sample, to
1e-12, for the physics and the hybrid model, over a simulated run with a press and a fault
sequence (NaN and inf inputs, joints out of the training domain, re-tares, a grasp signal),
tracker off and on (with payload tracking), with delay lines and the payload-change monitor;
the diagram driven as the live station drove it (inputs fixed, the Simulator advanced half a
period past each update). And the station's step path publishes what its diagram path does."""

import dataclasses as dc
import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from ftdrake import CompensationChain
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.conventions import MEASURED, QD, QDD, Q, joint_columns, wrench_columns
from ftdrake.errors import ConfigError
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import (
    PAYLOAD_COORD,
    TARE_COORD,
    decode_contact_state,
    decode_wrench,
    encode_event,
    encode_joint_state,
    encode_wrench,
)
from ftdrake.hardware.station import HardwareStation
from ftdrake.runtime.step import ChainStep
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.testing import push_scenario
from tests.helpers import CHAIN_PERIOD, chain_configs, chain_forest, chain_stream

N = 7
TARE_AT, GRASP_AT = (5, 1700), 1800  # samples where a tared / payload_changed pulse starts
MAIN_INPUTS = ("wrench_measured", "joint_state")  # ChainStep.update's positional inputs


@pytest.fixture(scope="module")
def press():
    """A 2 s simulated run of free motion with a press at the tool (0.8 s on) and a physics
    and a hybrid model trained on its contact-free rows: (scenario, log, models)."""
    scenario = push_scenario(duration=2.0, push_at=0.8)
    log = simulate(build_station(scenario), progress=False).log
    free = log["push_force"].to_numpy() == 0.0
    X = log[[*joint_columns(Q, N), *joint_columns(QD, N), *joint_columns(QDD, N)]].to_numpy()
    Y = log[wrench_columns(MEASURED)].to_numpy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation warnings: a short run, tested elsewhere
        models = {
            "physics": PhysicsPayloadCompensator().fit(X[free], Y[free]),
            "hybrid": HybridCompensator(PhysicsPayloadCompensator(), RandomForestCompensator(
                features="q", n_estimators=5, per_output=False, random_state=0)).fit(
                    X[free], Y[free]),
        }
    return scenario, log, models


def faulted_inputs(log) -> dict:
    """The run's inputs sample by sample with a fault sequence laid over them: NaN and inf
    readings, a NaN joint state, joint 0 far out of the training range for 30 samples, a
    re-tare at the start (the bias block resets) and after the press (estimated as a jump),
    a grasp signal."""
    K = len(log)
    wrench = log[wrench_columns(MEASURED)].to_numpy().copy()
    state = log[[*joint_columns(Q, N), *joint_columns(QD, N)]].to_numpy().copy()
    wrench[300:303] = np.nan
    wrench[310, 4] = np.inf
    state[400, 2] = np.nan
    state[500:530, 0] += 4.0

    def pulse(*starts):
        out = np.zeros(K)
        for k in starts:
            out[k:k + 3] = 1.0
        return out

    return {"wrench_measured": wrench, "joint_state": state, "tared": pulse(*TARE_AT),
            "payload_changed": pulse(GRASP_AT)}


def run_both(chain, inputs: dict, period: float):
    """The chain's exported outputs per sample (K × size per name), from the diagram driven as
    the live station drove it and from a ChainStep made from the same chain."""
    return drive(chain, inputs, period)[:2]


def drive(chain, inputs: dict, period: float):
    """run_both's outputs, then the diagram's context and the step at the end."""
    simulator = Simulator(chain)
    context = simulator.get_mutable_context()
    chain.initialize(context)
    simulator.Initialize()
    step = ChainStep(chain, context)
    fixed = {}
    for i in range(chain.num_input_ports()):
        name = chain.get_input_port(i).get_name()
        fixed[name] = chain.get_input_port(i).FixValue(context, np.atleast_1d(inputs[name][0]))
    names = [chain.get_output_port(i).get_name() for i in range(chain.num_output_ports())]
    diagram = {name: [] for name in names}
    stepped = {name: [] for name in names}
    for k in range(len(inputs["wrench_measured"])):
        for name, value in fixed.items():
            value.GetMutableData().get_mutable_value().SetFromVector(
                np.atleast_1d(inputs[name][k]))
        simulator.AdvanceTo((k + 0.5) * period)
        others = {name: inputs[name][k] for name in fixed if name not in MAIN_INPUTS}
        out = step.update(k * period, *(inputs[name][k] for name in MAIN_INPUTS), **others)
        for name in names:
            diagram[name].append(chain.GetOutputPort(name).Eval(context))
            stepped[name].append(out[name].copy())
    return ({name: np.array(v) for name, v in diagram.items()},
            {name: np.array(v) for name, v in stepped.items()}, context, step)


def assert_equal_outputs(diagram, stepped):
    assert sorted(stepped) == sorted(diagram)
    for name in diagram:
        np.testing.assert_allclose(stepped[name], diagram[name], rtol=0, atol=1e-12,
                                   err_msg=name)


def configs(scenario) -> dict:
    # Settle windows (in which contact does not freeze the tracker) shorter than the time
    # from the first re-tare to the press, so that the press freezes it.
    chain = scenario.chain_config()
    tracker = dc.replace(chain.bias_tracker, enabled=True, tare_settle_s=0.3,
                         payload_settle_s=0.3)
    base = dc.replace(chain, bias_tracker=tracker)
    return {
        "tracker_off": dc.replace(base, bias_tracker=dc.replace(tracker, enabled=False)),
        "tracker_on": base,
        "chi2_test": dc.replace(base, detector=dc.replace(base.detector, test="chi2")),
        "track_payload": dc.replace(base, bias_tracker=dc.replace(
            tracker, track_payload=True, track_payload_motion=True, start_settled=False)),
    }


@pytest.mark.parametrize("case", ["tracker_off", "tracker_on", "chi2_test", "track_payload"])
@pytest.mark.parametrize("kind", ["physics", "hybrid"])
def test_the_step_equals_the_diagram_over_a_press_and_faults(press, kind, case):
    scenario, log, models = press
    config = configs(scenario)[case]
    chain = CompensationChain(models[kind], config, n_joints=N)
    diagram, stepped = run_both(chain, faulted_inputs(log), chain.period)
    assert_equal_outputs(diagram, stepped)
    # What is compared was exercised: the press found, a fault, an out-of-domain stretch, a
    # tracked bias that moved (and its re-tares), a payload estimated after the grasp.
    assert diagram["contact"][800:1500].max() == 1.0
    assert diagram["fault"].max() == 1.0 and diagram["out_of_domain"][500:530].min() == 1.0
    if "bias" in diagram:
        assert np.ptp(diagram["bias"], axis=0).max() > 1e-3
    if "payload" in diagram:
        assert np.abs(diagram["payload"][GRASP_AT:]).max() > 1e-3


@pytest.mark.parametrize("delay", [0.0025, -0.0013])
def test_the_step_equals_the_diagram_with_a_delay_line(press, delay):
    """A wrench stream 2.5 ms behind the joint states (the joint state delayed, gravity too)
    and one 1.3 ms ahead (the wrench delayed): fractional delays, interpolated."""
    scenario, log, models = press
    config = configs(scenario)["track_payload"]
    config.sensor.wrench_delay_s = delay
    chain = CompensationChain(models["physics"], config, n_joints=N)
    assert chain.delay_line is not None
    assert_equal_outputs(*run_both(chain, faulted_inputs(log), chain.period))


@pytest.mark.parametrize("case", ["press_delayed", "grasp_nobody_signalled"])
def test_the_step_writes_its_state_into_a_context_as_the_diagram_holds_it(press, case):
    """After a run, every discrete state of the chain (compensator, tracker, detector,
    joint-state gravity, delay line; the payload monitor after it decided) written by the
    step into a fresh context equals the diagram's, so any port evaluates there as in the
    diagram (here the tracker's payload_inertia, which the chain does not export)."""
    scenario, log, models = press
    if case == "press_delayed":
        config = configs(scenario)["track_payload"]
        config.sensor.wrench_delay_s = 0.0025
        chain = CompensationChain(models["hybrid"], config, n_joints=N)
        inputs = faulted_inputs(log)
    else:
        chain = CompensationChain(models["physics"], monitored(scenario), n_joints=N,
                                  gravity="input")
        inputs = grasp_nobody_signalled(log, models["physics"], chain.period)
    *_, context, step = drive(chain, inputs, chain.period)
    written = chain.CreateDefaultContext()
    step.write_state(written)
    got, expected = (np.concatenate([c.get_discrete_state().get_vector(i).CopyToVector()
                                     for i in range(c.num_discrete_state_groups())])
                     for c in (written, context))
    np.testing.assert_array_equal(got, expected)
    inertia = chain.tracker.get_output_port_payload_inertia()
    np.testing.assert_array_equal(inertia.Eval(chain.tracker.GetMyContextFromRoot(written)),
                                  inertia.Eval(chain.tracker.GetMyContextFromRoot(context)))
    if chain.payload_monitor is not None:  # its decision's estimate is part of the state
        estimate = chain.payload_monitor.get_output_port_payload_change_estimate()
        assert np.abs(estimate.Eval(chain.payload_monitor.GetMyContextFromRoot(written))).max(
        ) > 0


def monitored(scenario):
    """Payload tracking (gravity only) with the unsignalled payload change's monitor."""
    chain = scenario.chain_config()
    tracker = dc.replace(chain.bias_tracker, enabled=True, track_payload=True,
                         track_payload_motion=False, payload_change=dc.replace(
                             chain.bias_tracker.payload_change, enabled=True))
    return dc.replace(chain, bias_tracker=tracker)


def grasp_nobody_signalled(log, model, period):
    """Inputs for a chain with gravity from inputs: the run's joint states, readings the model
    predicts for them (no press), and from 1 s on a 0.5 kg payload (centre of mass 0.1 m
    along z in S) whose gravity wrench the reading carries while g_S turns 40° about x over
    the next second; no grasp signal."""
    rows = log[[*joint_columns(Q, N), *joint_columns(QD, N), *joint_columns(QDD, N)]].to_numpy()
    K = len(rows)
    t = np.arange(K) * period
    angle = np.radians(40.0) * np.clip(t - 1.0, 0.0, 1.0)
    g = 9.81 * np.column_stack([np.zeros(K), np.sin(angle), -np.cos(angle)])
    mass, com = 0.5, np.array([0.0, 0.0, 0.1])
    carried = (t >= 1.0)[:, None] * np.hstack([mass * g, np.cross(mass * com, g)])
    return {"wrench_measured": model.predict(rows) + carried,
            "joint_state": rows[:, :2 * N], "tared": np.zeros(K), "payload_changed": np.zeros(K),
            "gravity_S": g}


def test_the_step_equals_the_diagram_when_the_monitor_announces_a_payload(press):
    scenario, log, models = press
    chain = CompensationChain(models["physics"], monitored(scenario), n_joints=N,
                              gravity="input")
    diagram, stepped = run_both(chain, grasp_nobody_signalled(log, models["physics"],
                                                              chain.period), chain.period)
    assert_equal_outputs(diagram, stepped)
    assert diagram["payload_change"].max() == 1.0  # the monitor decided, the tracker heard it
    # Undecided before the turn, then a payload change; the detector, which reads the
    # previous sample's decision, reports no contact while a payload change is decided.
    state = diagram["payload_state"][:, 0]
    assert {1.0, 2.0} <= set(np.unique(state)) and 3.0 not in state
    assert diagram["contact"][:-1, 0].any()
    assert not diagram["contact"][1:, 0][state[:-1] == 2.0].any()


@pytest.mark.parametrize("case", ["tracker_on", "track_payload"])
def test_the_step_equals_the_diagram_with_temperature_and_gravity_inputs(case):
    """test_chain's stream (a warming sensor, g_S and motion_S as inputs, a contact, a NaN
    reading, a re-tare, a grasp) through a forest trained with the temperature, on a chain
    built with ``gravity="input"`` (the simulation's way)."""
    config = chain_configs()[case][0].chain_config()
    chain = CompensationChain(chain_forest(temperature=True), config, period=CHAIN_PERIOD,
                              n_joints=N, gravity="input")
    inputs = chain_stream()
    inputs = {name: inputs[name].squeeze(1) if name in ("temperature", "tared",
                                                          "payload_changed") else inputs[name]
              for name in inputs if name != "t"}
    diagram, stepped = run_both(chain, inputs, CHAIN_PERIOD)
    assert_equal_outputs(diagram, stepped)
    assert diagram["contact"].max() == 1.0 and diagram["fault"].max() == 1.0


def test_the_step_refuses_what_it_cannot_reproduce_and_names_it(press):
    scenario, _, models = press
    base = scenario.chain_config()
    tracker = dc.replace(base.bias_tracker, track_payload=True, payload_change=dc.replace(
        base.bias_tracker.payload_change, enabled=True, sample_period_s=0.0125))
    chain = CompensationChain(models["physics"], dc.replace(base, bias_tracker=tracker),
                              n_joints=N)
    with pytest.raises(ConfigError, match=r"payload_change\.sample_period_s"):
        ChainStep(chain)
    step = ChainStep(CompensationChain(models["physics"], base, n_joints=N))
    with pytest.raises(ValueError, match="joint_state 14"):
        step.update(0.0, np.zeros(6), np.zeros(12))
    step = ChainStep(CompensationChain(chain_forest(temperature=True), base, n_joints=N))
    with pytest.raises(ConfigError, match="temperature"):
        step.update(0.0, np.zeros(6), np.zeros(2 * N))
    config = chain_configs()["track_payload"][0].chain_config()
    step = ChainStep(CompensationChain(chain_forest(temperature=False), config, n_joints=N,
                                       gravity="input"))
    with pytest.raises(ConfigError, match="gravity_S"):
        step.update(0.0, np.zeros(6), np.zeros(2 * N))


def test_the_station_publishes_the_same_by_the_step_and_by_the_diagram(press):
    """Two LCM stations on one memq:// bus, one driving its diagram: each F/T message gives
    the same published wrench and contact state (to 1e-12), through faulted messages, a
    re-tare and a grasp signal."""
    scenario, log, models = press
    config = configs(scenario)["track_payload"]
    hardware = {path: HardwareConfig(
        lcm_url="memq://", sensor_timeout_s=100.0, joint_state_timeout_s=100.0,
        tare_channel="FT_TARED", payload_channel="FT_GRASP",
        external_wrench_channel=f"FT_EXTERNAL_{path}", contact_channel=f"FT_CONTACT_{path}")
        for path in ("step", "diagram")}
    step = HardwareStation(hardware["step"], models["hybrid"], config, "memq://")
    diagram = HardwareStation(hardware["diagram"], models["hybrid"], config, step.lcm)
    diagram.use_diagram()
    got = {path: ([], []) for path in hardware}
    for path, c in hardware.items():
        step.lcm.subscribe(c.external_wrench_channel,
                           lambda d, out=got[path][0]: out.append(decode_wrench(d)))
        step.lcm.subscribe(c.contact_channel,
                           lambda d, out=got[path][1]: out.append(decode_contact_state(d)))
    inputs = faulted_inputs(log)
    c = hardware["step"]
    for k in range(len(log)):
        t = (k + 1) * step.period
        q, v = np.split(inputs["joint_state"][k], 2)
        step.lcm.publish(c.joint_state_channel, encode_joint_state("iiwa_status", t, q, v))
        if inputs["tared"][k] and not inputs["tared"][k - 1]:
            step.lcm.publish(c.tare_channel, encode_event(t, TARE_COORD))
        if inputs["payload_changed"][k] and not inputs["payload_changed"][k - 1]:
            step.lcm.publish(c.payload_channel, encode_event(t, PAYLOAD_COORD))
        step.lcm.publish(c.ft_channel, encode_wrench(t, inputs["wrench_measured"][k]))
        while step.spin_once(0):
            pass
    assert step.processed == diagram.processed > 1900 and step.published > 1900
    assert step.summary()["rejected"] == diagram.summary()["rejected"] != {}
    (w_step, c_step), (w_diagram, c_diagram) = got["step"], got["diagram"]
    assert len(w_step) == len(w_diagram) == step.published
    np.testing.assert_array_equal([w.t for w in w_step], [w.t for w in w_diagram])
    np.testing.assert_allclose([w.wrench for w in w_step], [w.wrench for w in w_diagram],
                               rtol=0, atol=1e-12)
    assert [(s.t, s.contact, s.fault, s.out_of_domain) for s in c_step] == [
        (s.t, s.contact, s.fault, s.out_of_domain) for s in c_diagram]
    np.testing.assert_allclose([s.contact_force for s in c_step],
                               [s.contact_force for s in c_diagram], rtol=0, atol=1e-12)
    assert any(s.contact for s in c_step)
