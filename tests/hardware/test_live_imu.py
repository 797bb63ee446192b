"""A live LCM station (memq://) with a model that takes an IMU at the sensor: the IMU channel
is required, each F/T sample is compensated with the IMU sample of its stamp, and a missing
or stale IMU publishes no wrench (a fault) until fresh IMU samples come back; that fault is
the inputs' (the status message's reason, one fault episode, the summary's IMU counts)."""

import numpy as np
import pytest

from ftdrake import ConfigError, ScenarioConfig
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.live_imu import ImuPairing
from ftdrake.hardware.live_inputs import CLOCK_RESTART_S, REASONS
from ftdrake.hardware.messages import (
    decode_contact_state,
    decode_imu,
    decode_status,
    decode_wrench,
    encode_imu,
    encode_joint_state,
    encode_temperature,
    encode_wrench,
)
from tests.helpers import imu_rows

N = 7


def _imu_model():
    """The IMU model fitted to the wrench a rigid 0.8 kg tool gives at random IMU readings."""
    return ImuPayloadCompensator().fit(*imu_rows())


def test_the_imu_message_round_trips_and_refuses_other_signals():
    t, values = decode_imu(encode_imu(1.25, [0.1, 0.2, 9.8], [0.01, -0.02, 0.03]))
    assert t == 1.25
    np.testing.assert_array_equal(values, [0.1, 0.2, 9.8, 0.01, -0.02, 0.03])
    with pytest.raises(ValueError, match="not an IMU signal"):
        decode_imu(encode_temperature(1.0, 25.0))


def test_pairing_takes_the_nearest_stamp_and_refuses_stale_or_out_of_order_samples():
    pairing = ImuPairing(0.002)
    assert np.isnan(pairing.pair(0.0)).all() and pairing.unpaired == 1
    assert pairing.on_imu((0.010, np.arange(6.0))) and pairing.on_imu((0.011, np.ones(6)))
    assert not pairing.on_imu((0.011, np.zeros(6)))  # the same stamp again
    assert not pairing.on_imu((0.012, np.full(6, np.nan)))
    assert pairing.rejected == {"out_of_order": 1, "not_finite": 1}
    np.testing.assert_array_equal(pairing.pair(0.0104), np.arange(6.0))
    np.testing.assert_array_equal(pairing.pair(0.0112), np.ones(6))
    assert np.isnan(pairing.pair(0.0135)).all() and "0.013500" in pairing.detail


def test_the_station_compensates_with_the_imu_of_the_stamp_and_faults_without_it():
    model = _imu_model()
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    with pytest.raises(ConfigError, match=r"hardware\.imu_channel"):
        HardwareStation(HardwareConfig(lcm_url="memq://"), model, scenario.chain_config(),
                        "memq://")
    config = HardwareConfig(lcm_url="memq://", imu_channel="FT_IMU")
    now = [0.0]
    dut = HardwareStation(config, model, scenario.chain_config(), "memq://",
                          clock=lambda: now[0])
    wrenches = []
    dut.lcm.subscribe(config.output_channel("wrench_compensated"),
                      lambda d: wrenches.append(decode_wrench(d)))
    q = np.linspace(-0.5, 0.5, N)
    acc, gyro = np.array([0.3, -0.2, 9.7]), np.array([0.05, 0.1, -0.2])  # constant: α = 0
    measured = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])

    def step(t, imu_t=None):
        now[0] = t
        if imu_t is not None:
            dut.lcm.publish(config.imu_channel, encode_imu(imu_t, acc, gyro))
        dut.lcm.publish(config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q, np.zeros(N)))
        dut.lcm.publish(config.ft_channel, encode_wrench(t, measured))
        dut.spin_once(0)
        dut.lcm.handle(0)

    step(0.000)  # no IMU yet: a fault, nothing published
    assert not wrenches and dut.output("fault")[0] == 1.0
    for k in range(1, 6):
        step(0.001 * k, imu_t=0.001 * k)
    assert len(wrenches) == 5
    row = np.concatenate([q, np.zeros(2 * N), acc, gyro, np.zeros(3)])
    expected = measured - model.predict(row[None])[0]
    np.testing.assert_allclose(wrenches[-1].wrench, expected, atol=1e-9)
    step(0.010)  # the IMU went silent 5 ms ago (> imu_max_skew_s): not compensated
    step(0.011)
    assert len(wrenches) == 5 and dut.output("fault")[0] == 1.0 and dut.imu.unpaired == 3
    step(0.012, imu_t=0.012)  # back
    assert len(wrenches) == 6 and dut.output("fault")[0] == 0.0


class ImuRig:
    """An LCM station on memq:// with the IMU model and a test clock; records the wrenches,
    contact states and status messages it publishes and its fault episodes."""

    def __init__(self):
        scenario = ScenarioConfig()
        scenario.chain.bias_tracker.enabled = False
        self.config = config = HardwareConfig(lcm_url="memq://", imu_channel="FT_IMU")
        self.now = 0.0
        self.events = []
        self.dut = HardwareStation(config, _imu_model(), scenario.chain_config(), "memq://",
                                   clock=lambda: self.now, on_event=self.events.append)
        self.got = {"wrench": [], "contact": [], "status": []}
        for name, channel, decode in (
                ("wrench", config.output_channel("wrench_compensated"), decode_wrench),
                ("contact", config.output_channel("contact"), decode_contact_state),
                ("status", config.status_channel, decode_status)):
            self.dut.lcm.subscribe(channel, lambda d, n=name, f=decode: self.got[n].append(f(d)))

    def step(self, t, imu=True, data=None):
        """At wall time t: an IMU message stamped t (`data`: these bytes instead; none
        without `imu`), a joint state and an F/T message stamped t, spun through."""
        self.now = t
        if imu:
            self.dut.lcm.publish(self.config.imu_channel, data if data is not None else
                                 encode_imu(t, [0.3, -0.2, 9.7], [0.05, 0.1, -0.2]))
        self.dut.lcm.publish(self.config.joint_state_channel, encode_joint_state(
            "iiwa_status", t, np.linspace(-0.5, 0.5, N), np.zeros(N)))
        self.dut.lcm.publish(self.config.ft_channel, encode_wrench(t, np.ones(6)))
        self.dut.spin_once(0)
        self.dut.lcm.handle(0)

    def status(self):
        """The last status message's reason (a name, "" without a fault) and fault flag."""
        values = self.got["status"][-1][1]
        index = int(values["reason"])
        return (REASONS[index - 1] if index > 0 else ""), bool(values["fault"])


def test_an_imu_that_never_arrives_faults_the_inputs_once_and_names_the_imu():
    rig = ImuRig()
    rig.step(0.000, data=b"not an imu message")  # one IMU message, rejected
    for k in range(1, 20):
        rig.step(0.001 * k, imu=False)
    m = rig.dut.monitor
    assert m.fault and m.reason == "imu_missing"
    assert "no IMU sample received yet (1 malformed rejected)" in m.detail
    assert "lcm.imu_channel 'FT_IMU'" in m.detail
    assert rig.status() == ("imu_missing", True)
    assert [(e.kind, e.reason) for e in rig.events] == [("fault", "imu_missing")]
    assert rig.events[0].detail == m.detail
    assert not rig.got["wrench"] and rig.dut.published == 0
    assert len(rig.got["contact"]) == 20 and all(c.fault for c in rig.got["contact"])
    summary = rig.dut.summary()
    assert summary["reason"] == "imu_missing" and summary["fault_episodes"] == {"imu_missing": 1}
    assert summary["imu"] == {"accepted": 0, "rejected": {"malformed": 1}, "unpaired": 20,
                              "clock_restarts": 0}


def test_an_imu_that_stops_mid_stream_faults_then_recovers_when_it_resumes():
    rig = ImuRig()
    for k in range(5):
        rig.step(0.001 * k)
    assert not rig.dut.monitor.fault and len(rig.got["wrench"]) == 5
    assert [e.kind for e in rig.events] == ["recovered"]  # from "no data yet"
    assert rig.status() == ("", False)
    for k in range(5, 15):  # the IMU goes silent; 2 ms later no IMU sample pairs
        rig.step(0.001 * k, imu=False)
    m = rig.dut.monitor
    assert m.fault and m.reason == "imu_stamp_gap"
    assert "newest IMU sample is 10.0 ms older: the IMU is late or silent" in m.detail
    assert "lcm.imu_max_skew_s" in m.detail
    assert rig.status() == ("imu_stamp_gap", True)
    faults = [e for e in rig.events if e.kind == "fault"]
    assert [(e.reason, round(e.t, 6)) for e in faults] == [("imu_stamp_gap", 0.007)]
    assert len(rig.got["wrench"]) == 7  # 5 and 6 pair with the IMU sample at 4 ms
    assert [c.fault for c in rig.got["contact"][7:]] == [True] * 8
    rig.step(0.015)  # the IMU is back
    assert not m.fault and rig.status() == ("", False) and len(rig.got["wrench"]) == 8
    assert [e.kind for e in rig.events] == ["recovered", "fault", "recovered"]
    assert not rig.got["contact"][-1].fault
    assert rig.dut.summary()["imu"] == {"accepted": 6, "rejected": {}, "unpaired": 8,
                                        "clock_restarts": 0}


def test_an_imu_clock_that_restarts_is_taken_up_again():
    """An IMU stamp CLOCK_RESTART_S or more before the last (a looped bag, a restarted
    driver) starts the history again from it, counted; one back by less is out of order."""
    pairing = ImuPairing(max_skew_s=0.002)
    values = np.arange(6.0)
    for t in (1.0, 1.001, 1.002):
        assert pairing.on_imu((t, values))
    assert not pairing.on_imu((1.002 - 0.9 * CLOCK_RESTART_S, values))
    assert pairing.counts()["rejected"] == {"out_of_order": 1}
    assert pairing.on_imu((0.001, values + 1))
    assert pairing.counts()["clock_restarts"] == 1
    np.testing.assert_array_equal(pairing.pair(0.0015), values + 1)  # the new sample only
    assert pairing.on_imu((0.002, values + 2))
