"""Station over memq://: published wrench_compensated == measured − model.predict, exactly once;
the same updates as the simulation's in-loop compensator for the simulated robot's stream."""

import dataclasses as dc

import numpy as np
import pytest

from ftdrake import RandomForestCompensator, ScenarioConfig
from ftdrake.conventions import WRENCH_AXES
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import (
    decode_contact_state,
    decode_wrench,
    encode_joint_state,
    encode_wrench,
)
from ftdrake.hardware.station import build_hardware_station
from ftdrake.sim.lcm_publisher import simulate_on_lcm
from ftdrake.sim.station import build_station
from ftdrake.testing import fit_forest, push_scenario


def test_station_compensates_each_message_once():
    rng = np.random.default_rng(1)
    n = 7
    X = rng.uniform(-1, 1, size=(200, 3 * n))
    Y = np.c_[np.sin(X[:, :6]) * 3.0]
    model = RandomForestCompensator(features="q", n_estimators=5).fit(X, Y)
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=10.0, joint_state_timeout_s=10.0)
    _, handles = build_hardware_station(config, model, lcm="memq://")
    dut = handles["station"]
    out = []
    dut.lcm.subscribe(config.output_channel("wrench_compensated"),
                      lambda d: out.append(decode_wrench(d)))
    rows, meas = [], []
    for k in range(20):
        t = 0.001 * (k + 1)
        q, w = rng.uniform(-1, 1, n), rng.normal(size=6)
        dut.lcm.publish(config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q, np.zeros(n)))
        dut.lcm.publish(config.ft_channel, encode_wrench(t, w))
        dut.spin_once(0)
        rows.append(np.r_[q, np.zeros(2 * n)])
        meas.append(w)
    dut.lcm.handle(0)
    expected = np.asarray(meas) - model.predict(np.asarray(rows))
    got = np.asarray([o.wrench for o in out])
    assert len(out) == 20 and dut.processed == 20
    np.testing.assert_allclose(got, expected, atol=1e-9)
    np.testing.assert_allclose([o.t for o in out], 0.001 * np.arange(1, 21), atol=1e-12)
    assert dut.monitor.received == {"ft": 20, "joint": 20} and not dut.monitor.rejected


@pytest.mark.parametrize("kind", ["iiwa_status", "robot_state"])
def test_simulated_robot_stream_gives_the_in_simulation_numbers(kind):
    """The simulated robot publishes on memq://, the station processes it as it comes: each
    published wrench equals the in-loop compensator's ``wrench_compensated`` and the contact flag
    the in-loop detector's ``contact``, sample for sample (robot_state: float32 positions on
    the wire, so to the float32 resolution instead, and the detector may differ there). A
    second station on the same bus drives its Drake diagram per message instead of the chain
    step: it publishes the same wrenches and contact states, to 1e-12."""
    scenario = push_scenario(duration=2.0, push_at=0.6)
    model = fit_forest(scenario, duration=0.5)
    hardware = HardwareConfig(lcm_url="memq://", sensor_timeout_s=100.0,
                              joint_state_timeout_s=100.0, joint_state_type=kind,
                              joint_state_channel="ROBOT_STATE" if kind == "robot_state"
                              else "IIWA_STATUS",
                              velocity_channel="ROBOT_VELOCITY" if kind == "robot_state" else "")
    _, handles = build_hardware_station(hardware, model, scenario.chain_config(), lcm="memq://")
    dut = handles["station"]
    wrenches, contact_wrenches, biases, contacts = [], [], [], []
    for port, received in (("wrench_compensated", wrenches), ("wrench_contact", contact_wrenches),
                           ("bias", biases)):
        dut.lcm.subscribe(hardware.output_channel(port),
                          lambda d, r=received: r.append(decode_wrench(d)))
    dut.lcm.subscribe(hardware.output_channel("contact"),
                      lambda d: contacts.append(decode_contact_state(d)))
    reference = dc.replace(hardware, output_prefix="DIAGRAM_")
    _, by_diagram = build_hardware_station(reference, model, scenario.chain_config(),
                                           lcm=dut.lcm)
    by_diagram["station"].use_diagram()
    reference_out = ([], [])
    dut.lcm.subscribe(reference.output_channel("wrench_compensated"),
                      lambda d: reference_out[0].append(decode_wrench(d)))
    dut.lcm.subscribe(reference.output_channel("contact"),
                      lambda d: reference_out[1].append(decode_contact_state(d)))
    station = build_station(scenario, model)
    result = simulate_on_lcm(station, hardware, dut.lcm, progress=False)
    while dut.spin_once(0):  # the station takes what the simulation queued, then its outputs
        pass
    dut.lcm.handle(0)
    log = result.log
    K = len(log)
    assert result.timing["published"] == {"joint": K + 1, "ft": K}
    assert dut.processed == dut.published == K == len(wrenches) == len(contacts)
    assert not dut.monitor.rejected.get("unpaired")
    np.testing.assert_allclose([w.t for w in wrenches], np.arange(K) * dut.period, atol=1e-9)
    got = np.array([w.wrench for w in wrenches])
    np.testing.assert_allclose(got, [w.wrench for w in reference_out[0]], rtol=0, atol=1e-12)
    assert contacts == reference_out[1]
    expected = log[[c for c in log if c.startswith("wrench_compensated_")]].to_numpy()
    detected = np.array([c.contact for c in contacts])
    assert log["contact"].sum() > 50  # the push is detected in simulation
    if kind == "iiwa_status":
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(detected, log["contact"].to_numpy().astype(bool))
        # The other published wrenches (as ROS 2 publishes them), under the same names.
        for received, port in ((contact_wrenches, "wrench_contact"), (biases, "bias")):
            assert len(received) == K
            np.testing.assert_allclose([w.wrench for w in received],
                                       log[[f"{port}_{a}" for a in WRENCH_AXES]].to_numpy(),
                                       rtol=0, atol=1e-9)
    else:
        np.testing.assert_allclose(got, expected, rtol=0, atol=0.5)  # float32 q, v
        assert (detected == log["contact"].to_numpy().astype(bool)).mean() > 0.99


def test_the_simulated_robot_announces_its_re_tare_and_grasp_once():
    """``events.retare_at_s`` and ``grasp_at_s`` in the simulation: the driver's zero offset
    jumps, a payload is added; the simulated robot sends one message on the tare and one on
    the payload channel, stamped with those times, which the station receives (its tracker
    then re-initialises the bias or payload; tests/hardware/test_hardware_faults)."""
    from ftdrake.hardware.messages import PAYLOAD_COORD, TARE_COORD, decode_event

    scenario = ScenarioConfig()
    scenario.trajectory.kind = "fourier"
    scenario.trajectory.duration_s = 1.0
    scenario.events.retare_at_s = 0.4
    scenario.events.grasp_at_s = 0.7
    scenario.chain.bias_tracker.track_payload = True
    scenario.chain.robot.file = "ftdrake"  # a forest carries no robot: the simulated arm
    scenario.validate()
    hardware = HardwareConfig(lcm_url="memq://", tare_channel="FT_TARED",
                              payload_channel="FT_GRASP",
                              sensor_timeout_s=100.0, joint_state_timeout_s=100.0)
    model = fit_forest(scenario, duration=0.3)
    _, handles = build_hardware_station(hardware, model, scenario.chain_config(), lcm="memq://")
    dut = handles["station"]
    stamps, grasps = [], []
    dut.lcm.subscribe(hardware.tare_channel, lambda d: stamps.append(decode_event(d, TARE_COORD)))
    dut.lcm.subscribe(hardware.payload_channel,
                      lambda d: grasps.append(decode_event(d, PAYLOAD_COORD)))
    result = simulate_on_lcm(build_station(scenario), hardware, dut.lcm, progress=False)
    while dut.spin_once(0):
        pass
    assert result.timing["published"]["tare"] == result.timing["published"]["payload"] == 1
    assert dut.summary()["signals"] == {"tared": {"received": 1, "rejected": 0},
                                        "payload_changed": {"received": 1, "rejected": 0}}
    assert stamps == [pytest.approx(0.4, abs=dut.period)]
    assert grasps == [pytest.approx(0.7, abs=dut.period)]
