"""Live mistakes named with their fix, on the LCM station (memq://) and the ROS 2 station
(Cyclone DDS on loopback), with clocks the tests move: joint positions in degrees, a message
of another type on an input channel or topic, a joint list that does not match the model, a
wrench in another frame than the configured one, a driver's rate far from
chain.sensor.rate_hz. Each gives a fault (or, for the rate, a warning) whose words name the
mistake, the config key and the fix — never "ok" with a result computed from it."""

import json
import os

import numpy as np
import pytest

from ftdrake import ChainConfig, ConfigError, RandomForestCompensator
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.live_checks import joint_bounds, joint_names_problem
from ftdrake.hardware.messages import (
    decode_contact_state,
    decode_wrench,
    encode_joint_state,
    encode_wrench,
)
from ftdrake.physics.robot import RobotDescription
from tests.helpers import DATA, wait_for

N = 7


def forest():
    """A 7-joint forest trained on q in [-1, 1] rad."""
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(200, 3 * N))
    return RandomForestCompensator(features="q", n_estimators=3).fit(X, np.sin(X[:, :6]))


def chain(rate_hz=1000.0):
    config = ChainConfig()
    config.bias_tracker.enabled = False
    config.sensor.rate_hz = rate_hz
    return config


class LcmRig:
    """An LCM station on memq:// with a test clock; records the wrenches and contact states
    it publishes and the warnings it gives."""

    def __init__(self, rate_hz=1000.0, **config):
        self.config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=0.5,
                                     joint_state_timeout_s=0.5, **config)
        self.now = 0.0
        self.events, self.warnings = [], []
        self.dut = HardwareStation(self.config, forest(), chain(rate_hz), "memq://",
                                   clock=lambda: self.now, on_event=self.events.append,
                                   on_warning=self.warnings.append)
        self.wrenches, self.contacts = [], []
        self.dut.lcm.subscribe(self.config.output_channel("wrench_compensated"),
                               lambda d: self.wrenches.append(decode_wrench(d)))
        self.dut.lcm.subscribe(self.config.output_channel("contact"),
                               lambda d: self.contacts.append(decode_contact_state(d)))

    def step(self, t, q, joint_data=None, ft_data=None):
        self.now = t
        self.dut.lcm.publish(self.config.joint_state_channel, joint_data or encode_joint_state(
            "iiwa_status", t, q, np.zeros(N)))
        self.dut.lcm.publish(self.config.ft_channel, ft_data or encode_wrench(t, np.ones(6)))
        self.dut.spin_once(0)
        self.dut.lcm.handle(0)


Q = np.linspace(-0.5, 0.5, N)  # rad, inside the training range


# -- degrees ---------------------------------------------------------------------------------
def test_joint_positions_in_degrees_fault_and_say_degrees():
    rig = LcmRig()
    for k in range(5):
        rig.step(0.001 * (k + 1), np.degrees(Q))
    m = rig.dut.monitor
    assert m.fault and m.reason == "degrees"
    assert "joint state in degrees?" in m.detail and "send radians" in m.detail
    assert "|q| ≤ 6.28 rad: 2π; the model's training range is [-0.99, 0.99] rad" in m.detail
    assert rig.wrenches == [] and rig.dut.processed == 0  # nothing judged from it
    assert rig.contacts and all(c.fault and not c.contact for c in rig.contacts)
    assert "degrees" in str(rig.events[-1])
    # The same joints in radians: accepted, published.
    rig.step(0.01, Q)
    assert not m.fault and len(rig.wrenches) == 1


def test_radians_beyond_the_training_range_are_no_fault():
    """q = 3 rad on a model trained on ±1 rad: outside its range (out of domain), but a
    radian value; only values radians cannot be are faulted."""
    bounds = joint_bounds(forest(), N)
    assert bounds.check(np.full(N, 3.0)) is None
    assert bounds.check(np.full(N, 2 * np.pi - 0.01)) is None
    reason, detail = bounds.check(np.r_[np.zeros(N - 1), 40.0])  # 40° = 0.70 rad
    assert reason == "degrees" and "joint 7 reads 40.00" in detail and "0.698 rad" in detail
    reason, detail = bounds.check(np.r_[np.zeros(N - 1), 4000.0])  # neither rad nor degrees
    assert reason == "joint_range" and "joint 7 reads 4000.00 rad" in detail


def test_the_robots_joint_limits_bound_a_joint():
    """With a robot whose joints have limits (the 7-joint arm's ±…), a value beyond them by
    more than the margin is faulted even under 2π; the limit is named."""
    model = forest()
    robot = RobotDescription(model=str(DATA / "seven_joint_arm.urdf"),
                             sensor_frame="tool", base_frame="base")
    model.robot_description = lambda: robot
    bounds = joint_bounds(model, N)
    from ftdrake.hardware.live_checks import robot_limits

    lower, upper, label = robot_limits(model, N)
    assert np.isfinite(lower).all() and np.isfinite(upper).all()
    limit = np.maximum(np.abs(lower), np.abs(upper))
    np.testing.assert_allclose(bounds.limit, limit + 0.1)
    q = np.zeros(N)
    q[2] = limit[2] + 0.2
    reason, detail = bounds.check(q)
    assert reason == "degrees" and "limits" in detail and label in detail


# -- wrong message type (LCM) ------------------------------------------------------------
def test_an_lcm_message_of_another_type_names_the_channel_and_both_types():
    rig = LcmRig()
    status = encode_joint_state("iiwa_status", 0.001, Q, np.zeros(N))
    rig.step(0.001, Q, ft_data=status)  # a joint state on the F/T channel
    m = rig.dut.monitor
    assert m.reason == "wrong_type"
    assert ("F/T message on LCM channel FT_SENSOR is a drake.lcmt_iiwa_status, expected "
            "drake.lcmt_force_torque" in m.detail)
    assert "lcm.ft_channel" in m.detail
    rig.step(0.002, Q, joint_data=encode_joint_state("panda_status", 0.002, Q, np.zeros(N)))
    assert m.reason == "wrong_type"
    assert ("joint-state message on LCM channel IIWA_STATUS is a drake.lcmt_panda_status, "
            "expected drake.lcmt_iiwa_status" in m.detail)
    assert "lcm.joint_state_type: panda_status" in m.detail
    assert rig.wrenches == []


def test_a_truncated_lcm_message_is_malformed_not_another_type():
    rig = LcmRig()
    rig.step(0.001, Q, ft_data=encode_wrench(0.001, np.ones(6))[:20])
    assert rig.dut.monitor.reason == "malformed"
    assert "truncated or corrupt drake.lcmt_force_torque" in rig.dut.monitor.detail


# -- joints against the model ------------------------------------------------------------
def test_lcm_joint_count_other_than_the_models_names_the_key():
    with pytest.raises(ConfigError, match=r"lcm\.n_joints: 6 joints, but the model "
                       r"\(RandomForestCompensator\) was trained for 7"):
        HardwareStation(HardwareConfig(lcm_url="memq://", n_joints=6), forest(), chain(),
                        "memq://")


def test_joint_names_against_the_models_robot():
    model = forest()
    names = tuple(f"joint_{k}" for k in range(N))
    robot = RobotDescription(model="unused.urdf", sensor_frame="S", joints=names)
    model.robot_description = lambda: robot
    assert joint_names_problem(model, list(names)) is None
    assert joint_names_problem(model, [f"left_{n}" for n in names]) is None  # a prefix
    words, certain = joint_names_problem(model, list(reversed(names)))
    assert certain and "another order" in words and "ros2.joint_names" in words
    words, certain = joint_names_problem(model, [f"a{k}" for k in range(N)])
    assert not certain and "are not the joints of the model's robot" in words


# -- rate ---------------------------------------------------------------------------------
def test_a_driver_rate_far_from_the_configured_one_is_warned_once():
    rig = LcmRig(rate_hz=1000.0)
    for k in range(600):  # 500 Hz stamps for 1.2 s
        rig.step(0.002 * (k + 1), Q)
    assert len(rig.warnings) == 1
    (warning,) = rig.warnings
    assert "F/T messages arrive at 500 Hz" in warning
    assert "chain.sensor.rate_hz is 1000 Hz" in warning and "chain.sensor.rate_hz: 500" in warning
    summary = rig.dut.summary()
    assert summary["warnings"] == [warning]
    assert summary["rate_hz"]["measured"] == pytest.approx(500.0)
    assert not rig.dut.monitor.fault  # a warning: the chain still runs


def test_a_driver_at_the_configured_rate_gives_no_warning():
    rig = LcmRig(rate_hz=500.0)
    for k in range(600):
        rig.step(0.002 * (k + 1), Q)
    assert rig.warnings == [] and rig.dut.rate_check.measured_hz == pytest.approx(500.0)


# -- ROS 2 --------------------------------------------------------------------------------
@pytest.fixture
def ros2():
    pytest.importorskip("cyclonedds")
    from ftdrake.hardware.ros2.config import Ros2Config
    from ftdrake.hardware.ros2.dds import Ros2Node
    from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_stamped
    from ftdrake.hardware.ros2.station import ERROR, Ros2Station

    domain = 100 + (os.getpid() + 37) % 100
    names = [f"arm_joint_{k + 1}" for k in range(N)]
    made = []

    class Rig:
        def __init__(self, wrench_type="geometry_msgs/msg/WrenchStamped", **config):
            self.config = Ros2Config(joint_names=list(names), domain_id=domain,
                                     output_namespace=f"/ftdrake_m{os.getpid()}", **config)
            self.now = 0.0
            self.warnings = []
            self.dut = Ros2Station(self.config, forest(), chain(), clock=lambda: self.now,
                                   on_warning=self.warnings.append)
            self.driver = Ros2Node(domain)
            made.extend([self.dut, self.driver])
            self.joints = self.driver.publisher(self.config.joint_state_topic,
                                                "sensor_msgs/msg/JointState")
            self.ft = self.driver.publisher(self.config.wrench_topic, wrench_type)
            self.JointState = ros2_type("sensor_msgs/msg/JointState")
            self.header, self.wrench_stamped, self.ERROR = header, wrench_stamped, ERROR

        def step(self, t, q=Q, frame="ft_sensor"):
            self.now = t
            received = sum(self.dut.monitor.received.values()) + 2
            self.joints.write(self.JointState(
                header=self.header(t, "base_link"), name=list(names),
                position=[float(x) for x in q], velocity=[0.0] * N, effort=[]))
            self.ft.write(self.wrench_stamped(self.header(t, frame), np.ones(6)))
            wait_for(lambda: (self.dut.spin_once(0),
                              sum(self.dut.monitor.received.values()))[1] >= received,
                     "the station to receive")

    yield Rig
    for node in made:
        node.close()


def test_ros2_degrees_are_a_fault_on_the_diagnostics(ros2):
    rig = ros2()
    wait_for(lambda: all(rig.driver.matched().values()), "DDS discovery")
    for k in range(3):
        rig.step(0.001 * (k + 1), np.degrees(Q))
    status = rig.dut.diagnostic_status()
    assert status.level == rig.ERROR and "joint state in degrees?" in status.message
    assert rig.dut.published == 0


def test_ros2_wrench_in_another_frame_is_a_fault_naming_the_key(ros2):
    rig = ros2(wrench_frame_id="ft_sensor_link")
    wait_for(lambda: all(rig.driver.matched().values()), "DDS discovery")
    rig.step(0.001, frame="tool0")
    m = rig.dut.monitor
    assert m.reason == "frame_id"
    assert ("wrench frame_id 'tool0' is not ros2.wrench_frame_id 'ft_sensor_link'"
            in m.detail)
    rig.step(0.002, frame="ft_sensor_link")
    assert not m.fault and rig.dut.published == 1


def test_ros2_another_type_on_the_wrench_topic_names_both_types(ros2):
    rig = ros2(wrench_type="geometry_msgs/msg/Wrench")

    def named():
        rig.dut.spin_once(0)
        return rig.dut.monitor.reason == "wrong_type"

    wait_for(named, "the station to name the type")
    detail = rig.dut.monitor.detail
    assert ("/force_torque_sensor_broadcaster/wrench carries geometry_msgs/msg/Wrench"
            in detail)
    assert "ftdrake reads geometry_msgs/msg/WrenchStamped there" in detail
    assert "ros2.wrench_topic" in detail
    status = rig.dut.diagnostic_status()
    assert status.level == rig.ERROR and "geometry_msgs/msg/Wrench " in status.message


def test_ros2_joint_names_of_another_length_name_the_key(ros2, tmp_path, capsys):
    from ftdrake.compensation.files.persistence import save_model
    from ftdrake.hardware.ros2.config import Ros2Config
    from ftdrake.hardware.ros2.station import Ros2Station

    with pytest.raises(ConfigError, match=r"ros2\.joint_names: 6 joints, but the model "
                       r"\(RandomForestCompensator\) was trained for 7"):
        Ros2Station(Ros2Config(joint_names=[f"j{k}" for k in range(6)]), forest(), chain())
    # The command line says the same.
    from ftdrake.cli import main

    save_model(forest(), tmp_path / "m.ftd")
    (tmp_path / "live.yaml").write_text(json.dumps(
        {"ros2": {"joint_names": [f"j{k}" for k in range(6)]}}))
    code = main(["serve", "--ros2", "--model", str(tmp_path / "m.ftd"), "--config",
                 str(tmp_path / "live.yaml"), "--duration", "0.1", "--quiet"])
    assert code != 0
    assert "ros2.joint_names: 6 joints" in capsys.readouterr().err


def test_ros2_a_best_effort_driver_on_a_reliable_subscription_names_the_qos_key(ros2):
    """A driver publishing with SensorDataQoS (best effort) never matches ftdrake's default
    reliable subscription: the station says so and names ros2.wrench_qos and its fix."""
    del ros2  # for cyclonedds and the closing of what it made
    from ftdrake.hardware.ros2.config import Ros2Config
    from ftdrake.hardware.ros2.dds import Ros2Node
    from ftdrake.hardware.ros2.station import Ros2Station

    domain = 100 + (os.getpid() + 61) % 100
    config = Ros2Config(joint_names=[f"j{k}" for k in range(N)], domain_id=domain,
                        wrench_topic="/ft_best_effort/wrench")
    dut, driver = Ros2Station(config, forest(), chain()), Ros2Node(domain)
    try:
        driver.publisher(config.wrench_topic, "geometry_msgs/msg/WrenchStamped",
                         profile="sensor_data")

        def named():
            dut.spin_once(0)
            return dut.monitor.reason == "qos"

        wait_for(named, "the station to name the QoS")
        assert ("a publisher on /ft_best_effort/wrench offers a QoS that ros2.wrench_qos "
                "'reliable' cannot match" in dut.monitor.detail)
        assert "Fix: set ros2.wrench_qos: sensor_data" in dut.monitor.detail
    finally:
        dut.close()
        driver.close()


def test_a_sensor_data_reader_keeps_the_queue_depth():
    """A best-effort reader keeps queue_depth samples (its history is its own), not the
    writers' keep-last-5 that would lose samples between two spins at 1 kHz."""
    pytest.importorskip("cyclonedds")
    from cyclonedds.qos import Policy

    from ftdrake.hardware.ros2.dds import qos

    assert qos("sensor_data", 1000)[Policy.History] == Policy.History.KeepLast(1000)
    assert qos("sensor_data", 1000, writer=True)[Policy.History] == Policy.History.KeepLast(5)
    assert qos("sensor_data", 1000)[Policy.Reliability] == Policy.Reliability.BestEffort
