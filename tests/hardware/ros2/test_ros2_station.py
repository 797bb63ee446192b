"""The ROS 2 station over Cyclone DDS on loopback, in one process, with a clock the test
moves: joint states in another order are reordered (same output), an unknown or a missing
joint name, NaN, time going back and silence fault it (diagnostics say why, at once; no
stale wrench, contact or force is published), and it recovers on the next good messages. The
published wrench is the F/T message's minus the model's prediction for the joints in the
model's order (bias tracker off), with the input's frame_id and stamp."""

import os
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from ftdrake import ConfigError, RandomForestCompensator, ScenarioConfig
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.hardware.overload import CpuMeter
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.dds import Ros2Node
from ftdrake.hardware.ros2.messages import (
    from_stamp,
    header,
    ros2_type,
    wrench_of,
    wrench_stamped,
)
from ftdrake.hardware.ros2.station import ERROR, OK, WARN, Ros2Station
from tests.helpers import imu_message, imu_rows, wait_for

N = 7
NAMES = [f"arm_joint_{k + 1}" for k in range(N)]
DOMAIN = 100 + os.getpid() % 100
JointState = ros2_type("sensor_msgs/msg/JointState")


class Rig:
    """A Ros2Station on loopback DDS with a test clock, a driver node writing its inputs and
    a listener recording what it publishes (`model`: a small random forest unless given)."""

    def __init__(self, scenario=None, model=None, **config):
        rng = np.random.default_rng(0)
        X = rng.uniform(-1, 1, size=(200, 3 * N))
        self.model = model if model is not None else RandomForestCompensator(
            features="q", n_estimators=3).fit(X, np.sin(X[:, :6]))
        if scenario is None:
            scenario = ScenarioConfig()
            scenario.chain.bias_tracker.enabled = False  # published wrench = measured − predicted
        self.config = Ros2Config(joint_names=list(NAMES), domain_id=DOMAIN,
                                 output_namespace=f"/ftdrake_{os.getpid()}", **config)
        self.now = 0.0
        self.events = []
        self.dut = Ros2Station(self.config, self.model, scenario.chain_config(),
                               clock=lambda: self.now, on_event=self.events.append)
        self.driver = Ros2Node(DOMAIN)
        self.joints = self.driver.publisher(self.config.joint_state_topic,
                                            "sensor_msgs/msg/JointState")
        self.ft = self.driver.publisher(self.config.wrench_topic,
                                        "geometry_msgs/msg/WrenchStamped")
        self.listener = Ros2Node(DOMAIN)
        # "wrench": the contact wrench the detector judges (= measured − predicted here).
        self.got = {name: [] for name in ("wrench", "contact", "contact_force", "diagnostics")}
        for name, topic, msgtype in (
                ("wrench", "wrench_contact", "geometry_msgs/msg/WrenchStamped"),
                ("contact", "contact", "std_msgs/msg/Bool"),
                ("contact_force", "contact_force", "std_msgs/msg/Float64")):
            self.listener.subscribe(self.config.output_topic(topic), msgtype,
                                    lambda m, _a, n=name: self.got[n].append(m))
        self.listener.subscribe(self.config.diagnostics_topic,
                                "diagnostic_msgs/msg/DiagnosticArray",
                                lambda m, _a: self.got["diagnostics"].append(m))
        wait_for(lambda: all(self.driver.matched().values())
                 and len(self.listener.matched()) == 4 and all(self.listener.matched().values()),
                 "DDS discovery")
        # Diagnostics published at start (a warning), before the listener existed: not received.
        self.unheard = self.dut.diagnostics_published
        self.q = np.linspace(-0.5, 0.5, N)

    def joint(self, t, names=NAMES, q=None):
        q = self.q if q is None else q
        by_name = dict(zip(NAMES, q, strict=True))
        self.joints.write(JointState(
            header=header(t, "base_link"), name=list(names),
            position=[float(by_name.get(n, 0.0)) for n in names],
            velocity=[0.0] * len(names), effort=[]))

    def wrench(self, t, w):
        self.ft.write(wrench_stamped(header(t, "ft_sensor"), np.full(6, w)))

    def step(self, t, w=1.0, names=NAMES, joint=True, wall=None):
        """At wall time `wall` (default t): a joint message stamped t (if `joint`), an F/T
        message stamped t, spun through."""
        self.now = t if wall is None else wall
        received = sum(self.dut.monitor.received.values()) + 1 + joint
        if joint:
            self.joint(t, names)
        self.wrench(t, w)
        wait_for(lambda: (self.dut.spin_once(0), sum(self.dut.monitor.received.values()))[1]
                 >= received, "the station to receive")
        self.collect()

    def spin(self):
        self.dut.spin_once(0)
        self.collect()

    def collect(self):
        """Waits until the listener has everything the station published."""
        def caught_up():
            self.listener.spin(0)
            return (len(self.got["wrench"]) == self.dut.published
                    and len(self.got["contact"]) == self.dut.contact_published
                    and len(self.got["diagnostics"]) + self.unheard
                    == self.dut.diagnostics_published)
        wait_for(caught_up, "the listener to catch up")

    def close(self):
        for node in (self.listener, self.driver, self.dut):
            node.close()

    def expected(self, w):
        return np.full(6, w) - self.model.predict(np.r_[self.q, np.zeros(2 * N)][None])[0]

    def last_status(self):
        (status,) = self.got["diagnostics"][-1].status
        return status, {kv.key: kv.value for kv in status.values}


def published_times(rig):
    return [round(from_stamp(w.header.stamp) * 1e3) for w in rig.got["wrench"]]


@pytest.fixture
def rig():
    rig = Rig()
    for k in range(5):
        rig.step(0.001 * k)
    assert len(rig.got["wrench"]) == 5 and not rig.dut.monitor.fault
    assert [e.kind for e in rig.events] == ["recovered"]  # from "no data yet"
    rig.events.clear()
    yield rig
    rig.close()


def test_publishes_the_compensated_wrench_with_the_inputs_header(rig):
    last = rig.got["wrench"][-1]
    assert last.header.frame_id == "ft_sensor" and from_stamp(last.header.stamp) == \
        pytest.approx(0.004, abs=1e-12)
    np.testing.assert_allclose(wrench_of(last), rig.expected(1.0), rtol=0, atol=1e-12)
    assert len(rig.got["contact"]) == len(rig.got["contact_force"]) == 5
    assert rig.got["contact"][-1].data is False and rig.got["contact_force"][-1].data == 0.0
    status, values = rig.last_status()  # published at the recovery from "no data"
    assert status.level == OK and values["fault"] == "false"


def test_joints_in_another_order_are_reordered(rig):
    shuffled = [NAMES[k] for k in (3, 0, 6, 2, 5, 1, 4)]
    rig.step(0.005, w=2.0, names=shuffled)
    assert not rig.dut.monitor.fault
    np.testing.assert_array_equal(rig.dut.monitor.joint_state[:N], rig.q)
    np.testing.assert_allclose(wrench_of(rig.got["wrench"][-1]), rig.expected(2.0), atol=1e-12)


@pytest.mark.parametrize(("names", "says"), [
    ([*NAMES[:6], "gripper_finger_joint"],
     "unknown ['gripper_finger_joint'], missing ['arm_joint_7']"),
    (NAMES[:6], "missing ['arm_joint_7']"),
    ([*NAMES, NAMES[2]], "['arm_joint_3'] twice"),
])
def test_unknown_or_missing_joint_names_fault(rig, names, says):
    rig.step(0.005, names=names)  # the F/T message is good; the joint state it would use is not
    assert rig.dut.monitor.fault and rig.dut.monitor.reason == "joint_names"
    assert says in rig.events[0].detail and "ros2.joint_names is" in rig.events[0].detail
    status, values = rig.last_status()
    assert status.level == ERROR and values["reason"] == "joint_names" and says in status.message
    rig.step(0.006, joint=False)  # still no good joint state: nothing published
    assert published_times(rig) == [0, 1, 2, 3, 4] and len(rig.got["contact"]) == 5
    rig.step(0.007, w=4.0)
    assert not rig.dut.monitor.fault and rig.events[-1].kind == "recovered"
    assert rig.last_status()[0].level == OK
    np.testing.assert_allclose(wrench_of(rig.got["wrench"][-1]), rig.expected(4.0), atol=1e-12)
    assert rig.dut.monitor.rejected == {"joint_names": 1}


def test_joints_beyond_joint_names_are_ignored_and_said_once(rig):
    """A robot's /joint_states with a gripper's (or another arm's) joints among the arm's:
    the arm's are taken by name, the others ignored; a warning names them once, on
    /diagnostics too."""
    names = ["gripper_finger_joint", *reversed(NAMES), "torso_joint"]
    rig.step(0.005, w=2.0, names=names)
    rig.step(0.006, w=3.0, names=names)
    assert not rig.dut.monitor.fault and not rig.dut.monitor.rejected
    np.testing.assert_array_equal(rig.dut.monitor.joint_state[:N], rig.q)
    np.testing.assert_allclose(wrench_of(rig.got["wrench"][-1]), rig.expected(3.0), atol=1e-12)
    said = [w for w in rig.dut.warnings if "ignored" in w]
    assert said == [("joint states also carry ['gripper_finger_joint', 'torso_joint'], not in "
                     "ros2.joint_names: ignored (the model's joints are taken from them by "
                     "name)")]
    assert any("torso_joint" in status.message for message in rig.got["diagnostics"]
               for status in message.status)


def test_another_devices_joint_states_on_the_topic_are_ignored(rig):
    """A gripper driver publishing its own JointState on /joint_states beside the arm's:
    its messages name none of joint_names and are ignored (counted, said once), not a
    fault between two of the arm's."""
    for k in (5, 6, 7):
        rig.joint(0.001 * k - 0.0005, names=["gripper_finger_joint"])
        rig.step(0.001 * k, w=2.0)
    assert not rig.dut.monitor.fault and not rig.dut.monitor.rejected
    assert published_times(rig) == [0, 1, 2, 3, 4, 5, 6, 7]
    assert rig.dut.summary()["joint_states_ignored"] == 3
    said = [w for w in rig.dut.warnings if "name none of ros2.joint_names" in w]
    assert len(said) == 1 and "gripper_finger_joint" in said[0]


def test_time_going_back_and_nan(rig):
    rig.step(0.002, w=9.0, joint=False)  # F/T back in time: 2 ms < 4 ms
    assert rig.dut.monitor.reason == "out_of_order"
    assert "went back from 0.004000 s to 0.002000 s" in rig.last_status()[0].message
    rig.step(0.005, w=np.nan)
    assert rig.dut.monitor.reason == "not_finite" and "NaN" in rig.last_status()[0].message
    assert published_times(rig) == [0, 1, 2, 3, 4] and len(rig.got["contact"]) == 5
    rig.step(0.006, w=3.0)
    assert not rig.dut.monitor.fault and rig.events[-1].kind == "recovered"
    np.testing.assert_allclose(wrench_of(rig.got["wrench"][-1]), rig.expected(3.0), atol=1e-12)
    assert rig.dut.monitor.rejected == {"out_of_order": 1, "not_finite": 1}
    assert rig.dut.summary()["processed"] == 6


def test_a_driver_whose_clock_restarts_is_said_on_diagnostics_and_taken_up_again(rig):
    """A looped bag: the stamps go back from 1 s to 1 ms while the station's clock runs on.
    Both streams are taken up again at once (nothing refused, nothing read as overload) and
    a warning says so on /diagnostics."""
    rig.step(1.0)
    processed = rig.dut.processed
    for k in (1, 2, 3):
        rig.step(0.001 * k, wall=1.0 + 0.001 * k)
    assert rig.dut.processed == processed + 3 and not rig.dut.monitor.rejected
    assert rig.dut.summary()["clock_restarts"] == {"joint": 1, "ft": 1}
    said = [status for message in rig.got["diagnostics"] for status in message.status
            if "clock restarted" in status.message]
    assert said and all(status.level == WARN for status in said)
    assert "went back 0.999 s, from 1.000000 s to 0.001000 s" in said[-1].message
    assert not any(event.reason == "overload" for event in rig.events)


def test_wrenches_stamped_on_another_clock_name_the_ros2_key_on_diagnostics(rig):
    rig.now = 0.005
    rig.joint(0.005)
    rig.wrench(1.005, 1.0)  # the sensor's clock, 1 s off the robot's
    wait_for(lambda: (rig.dut.spin_once(0), rig.dut.monitor.received["ft"])[1] >= 6,
             "the station to receive")
    rig.collect()
    status, values = rig.last_status()
    assert values["reason"] == "stamp_gap" and "on different clocks" in status.message
    assert "set ros2.pair_tolerance_s: 0" in status.message


def test_silence_is_published_at_once(rig):
    rig.now = 0.004 + 0.0061  # 6.1 ms of silence
    rig.spin()
    assert rig.dut.monitor.reason == "sensor_timeout"
    status, values = rig.last_status()
    assert status.level == ERROR and values["reason"] == "sensor_timeout"
    assert "no F/T message for 6.1 ms (timeout 5 ms)" in status.message
    assert from_stamp(rig.got["diagnostics"][-1].header.stamp) == pytest.approx(0.0101, abs=1e-9)
    n = len(rig.got["diagnostics"])
    rig.spin()  # still silent: published once, not on every spin
    assert len(rig.got["diagnostics"]) == n and len(rig.got["wrench"]) == 5
    rig.step(0.011, w=2.0)
    assert not rig.dut.monitor.fault and published_times(rig) == [0, 1, 2, 3, 4, 11]


def test_periodic_diagnostics_carry_rates(rig):
    n = len(rig.got["diagnostics"])
    # The stamps' first second closes: 6 F/T messages in 1 s, far from chain.sensor.rate_hz
    # (1 kHz): a warning (published at once), then the periodic diagnostics are due.
    rig.step(1.0)
    assert len(rig.got["diagnostics"]) == n + 2
    assert rig.last_status()[1]["rate_ft_hz"] == "6.0"  # 6 F/T messages in 1 s
    rig.step(1.5)
    assert len(rig.got["diagnostics"]) == n + 2
    rig.step(2.0)
    assert len(rig.got["diagnostics"]) == n + 3
    status, values = rig.last_status()
    assert status.level == WARN and "chain.sensor.rate_hz is 1000 Hz" in status.message
    assert values["rate_ft_hz"] == values["rate_joint_hz"] == "2.0"
    assert values["processed"] == values["published"] == values["received_ft"] == "8"


def test_periodic_diagnostics_carry_serves_cpu_since_the_last(rig):
    """cpu_core_percent and cpu_us_per_message: the process's CPU time between two periodic
    diagnostics over their wall time and per F/T message processed in between."""
    cpu = [5.0]  # the process's CPU clock (s), advanced by hand
    rig.dut.cpu_meter = CpuMeter(rig.now, rig.dut.processed, cpu_clock=lambda: cpu[0])
    rig.step(1.0)  # the stamps' first second: a warning, then the periodic diagnostics
    processed, n = rig.dut.processed, len(rig.got["diagnostics"])
    cpu[0] += 0.002  # 2 ms of CPU until the next periodic diagnostics
    rig.step(2.0)
    assert len(rig.got["diagnostics"]) == n + 1
    _, values = rig.last_status()
    messages = rig.dut.processed - processed
    assert messages > 0
    assert float(values["cpu_us_per_message"]) == pytest.approx(2000 / messages, abs=0.05)
    assert float(values["cpu_core_percent"]) == pytest.approx(0.2, abs=0.05)  # 2 ms in 1 s


def test_config_errors():
    with pytest.raises(ConfigError, match=r"ros2\.joint_names: list the model's joints"):
        Ros2Config().validate()
    with pytest.raises(ConfigError, match=r"ros2\.wrench_qos"):
        Ros2Config(joint_names=NAMES, wrench_qos="fast").validate()
    with pytest.raises(ConfigError, match=r"ros2\.wrench_topic: topic '/joint_states' is also"):
        Ros2Config(joint_names=NAMES, wrench_topic="/joint_states").validate()
    with pytest.raises(ConfigError, match=r"ros2\.tare_topic"):
        scenario = ScenarioConfig()
        scenario.chain.bias_tracker.enabled = False
        Rig(scenario, tare_topic="/ft_tare")


@pytest.mark.parametrize("window", [0.0, 0.05])
def test_messages_go_in_publication_order_within_the_reorder_window(window):
    """A joint state published before a wrench but delivered after it (as after a lost
    datagram): with a reorder window it is still handed over first; without, as it arrives."""
    with Ros2Node(DOMAIN, reorder_window_s=window) as node, Ros2Node(DOMAIN) as driver:
        got = []
        topics = {"joint": f"/order_{os.getpid()}/joint", "wrench": f"/order_{os.getpid()}/ft"}
        for kind, topic in topics.items():
            node.subscribe(topic, "std_msgs/msg/Float64", lambda _m, _a, k=kind: got.append(k))
        writers = {kind: driver.publisher(topic, "std_msgs/msg/Float64")
                   for kind, topic in topics.items()}
        wait_for(lambda: all(driver.matched().values()) and all(node.matched().values()),
                 "DDS discovery")
        Float64 = ros2_type("std_msgs/msg/Float64")
        now_ns = time.time_ns()
        writers["wrench"].write(Float64(data=1.0), timestamp=now_ns)
        time.sleep(0.01)
        node.spin(0)
        writers["joint"].write(Float64(data=0.0), timestamp=now_ns - 1_000_000)  # earlier
        wait_for(lambda: (node.spin(10), len(got))[1] == 2, "both messages")
        assert got == (["joint", "wrench"] if window else ["wrench", "joint"])


def test_cli_errors_name_the_ros2_setting(tmp_path, capsys):
    from ftdrake.cli.main import main

    (tmp_path / "m.ftd").write_bytes(b"")  # the settings are checked before the model is read
    assert main(["serve", "--ros2", "--model", str(tmp_path / "m.ftd")]) == 2
    assert "ros2.joint_names: list the model's joints" in capsys.readouterr().err
    (tmp_path / "ros2.yaml").write_text("joint_names: [a, b]\nwrench_qos: fast\n")
    assert main(["record", "--ros2", "--ros2-config", str(tmp_path / "ros2.yaml"), "--out",
                 str(tmp_path / "r.parquet")]) == 2
    err = capsys.readouterr().err
    assert "ros2.wrench_qos: 'fast' is not one of reliable, sensor_data" in err
    assert "ros2.yaml" in err


def test_tare_and_payload_topics_reach_the_tracker_and_its_estimates_are_published():
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.track_payload = True
    scenario.chain.robot.file = "ftdrake"  # a forest carries no robot: the simulated arm
    rig = Rig(scenario, tare_topic=f"/tare_{os.getpid()}", payload_topic=f"/grasp_{os.getpid()}")
    try:
        outputs = {"bias": [], "payload": []}
        for name, msgtype in (("bias", "geometry_msgs/msg/WrenchStamped"),
                              ("payload", "geometry_msgs/msg/InertiaStamped")):
            rig.listener.subscribe(rig.config.output_topic(name), msgtype,
                                   lambda m, _a, n=name: outputs[n].append(m))
        events = {name: rig.driver.publisher(topic, "std_msgs/msg/Empty") for name, topic in
                  (("tared", rig.config.tare_topic), ("payload_changed", rig.config.payload_topic))}
        wait_for(lambda: all(rig.driver.matched().values())
                 and all(rig.listener.matched().values()), "DDS discovery")
        Empty = ros2_type("std_msgs/msg/Empty")
        rig.step(0.0)
        for writer in events.values():
            writer.write(Empty(structure_needs_at_least_one_member=0))
        wait_for(lambda: (rig.dut.spin_once(0), rig.dut.summary()["signals"])[1]["tared"]
                 ["received"] == 1, "the tare")
        rig.step(0.001)
        assert rig.dut.summary()["signals"] == {"tared": {"received": 1, "rejected": 0},
                                                "payload_changed": {"received": 1, "rejected": 0}}
        wait_for(lambda: (rig.listener.spin(0), len(outputs["payload"]))[1] == 2, "estimates")
        assert len(outputs["bias"]) == 2
        np.testing.assert_allclose(wrench_of(outputs["bias"][-1]), rig.dut.output("bias"),
                                   rtol=0, atol=0)
        payload = outputs["payload"][-1]
        assert payload.header.frame_id == "ft_sensor"
        assert payload.inertia.m == rig.dut.output("payload")[0]
    finally:
        rig.close()


def test_an_imu_that_stops_is_an_error_on_diagnostics_until_it_resumes():
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    rig = Rig(scenario, model=ImuPayloadCompensator().fit(*imu_rows()), imu_topic="/ft_imu")
    try:
        imu = rig.driver.publisher("/ft_imu", "sensor_msgs/msg/Imu")
        wait_for(lambda: all(rig.driver.matched().values()), "the IMU topic to match")

        def step(t, with_imu=True):
            if with_imu:  # received before the wrench of its stamp
                accepted = rig.dut.imu.accepted
                imu.write(imu_message(t))
                wait_for(lambda: (rig.dut.spin_once(0), rig.dut.imu.accepted)[1] > accepted,
                         "the station to receive the IMU sample")
            rig.step(t)

        for k in range(5):
            step(0.001 * k)
        assert len(rig.got["wrench"]) == 5 and not rig.dut.monitor.fault
        for k in range(5, 10):  # silent: from 7 ms on no IMU sample is within 2 ms
            step(0.001 * k, with_imu=False)
        status, values = rig.last_status()
        assert status.level == ERROR and values["reason"] == "imu_stamp_gap"
        assert status.message.startswith("fault imu_stamp_gap: no IMU sample stamped within")
        assert "Fix: the IMU's driver on ros2.imu_topic '/ft_imu'" in status.message
        assert values["unpaired_imu"] == "1" and values["received_imu"] == "5"  # at the rise
        assert [(e.kind, e.reason) for e in rig.events] == [("recovered", ""),
                                                             ("fault", "imu_stamp_gap")]
        assert len(rig.got["wrench"]) == 7
        step(0.010)
        status, values = rig.last_status()
        # No fault; WARN for the start-up warning (these joint names are not the model's
        # robot's).
        assert status.level == WARN and "joint_names" in status.message
        assert values["fault"] == "false" and len(rig.got["wrench"]) == 8
        assert rig.events[-1].kind == "recovered"
    finally:
        rig.close()
