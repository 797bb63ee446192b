"""The ROS 2 station's compiled per-message path against its Python path, over Cyclone DDS on
loopback in one process: two stations read the same driver's messages, one with
``compiled_path`` on, one off, and must publish the same messages (stamps, frames and values
bit for bit) and count the same, through ordinary messages and unusual ones (NaN, a stamp
going back, lost samples, a new joint order, another frame, a joint state beyond its
bounds, a contact). The compiled path's
parts: its CDR against cyclonedds', and the check of Cyclone's C declarations (its chain
update: tests/hardware/test_fast_chain.py)."""

import os

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from ftdrake import ChainConfig, ConfigError
from ftdrake.hardware.ros2 import packing
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.dds import Ros2Node
from ftdrake.hardware.ros2.fast import cyclone
from ftdrake.hardware.ros2.fast.cdr import names_cdr, read_joint_state, read_wrench, wrench_bytes
from ftdrake.hardware.ros2.messages import from_stamp, header, ros2_type, wrench_stamped
from ftdrake.hardware.ros2.station import Ros2Station
from tests.helpers import assert_twins_count_alike, fused_forest, twin_stream, wait_for

N = 7
NAMES = [f"arm_joint_{k + 1}" for k in range(N)]
DOMAIN = 150 + os.getpid() % 80
JointState = ros2_type("sensor_msgs/msg/JointState")
OUTPUTS = {"wrench_contact": "geometry_msgs/msg/WrenchStamped",
           "wrench_compensated": "geometry_msgs/msg/WrenchStamped",
           "bias": "geometry_msgs/msg/WrenchStamped", "contact": "std_msgs/msg/Bool",
           "contact_force": "std_msgs/msg/Float64"}

def station(model, compiled: bool, chain=None, **config):
    """A station on the real clock (the compiled path's), its own output namespace."""
    config = Ros2Config(joint_names=list(NAMES), domain_id=DOMAIN, compiled_path=compiled,
                        output_namespace=f"/ft_{os.getpid()}_{int(compiled)}",
                        sensor_timeout_s=5.0, joint_state_timeout_s=5.0, max_backlog_s=100.0,
                        **config)
    dut = Ros2Station(config, model, chain or ChainConfig())
    dut.compiled.wait()
    return dut


class Twin:
    """Two stations (compiled path on / off) on one driver's topics, a listener on both."""

    def __init__(self, model, chain):
        self.on, self.off = station(model, True, chain), station(model, False, chain)
        self.driver = Ros2Node(DOMAIN)
        self.joints = self.driver.publisher("/joint_states", "sensor_msgs/msg/JointState",
                                            depth=5000)
        self.ft = self.driver.publisher("/force_torque_sensor_broadcaster/wrench",
                                        "geometry_msgs/msg/WrenchStamped", depth=5000)
        self.listener = Ros2Node(DOMAIN)
        self.got = {}
        for dut in (self.on, self.off):
            for name, msgtype in OUTPUTS.items():
                if not dut.has_output(name):
                    continue
                got = self.got[(dut.config.compiled_path, name)] = []
                self.listener.subscribe(dut.config.output_topic(name), msgtype,
                                        lambda m, _a, got=got: got.append(m), depth=5000)
        wait_for(lambda: all(self.driver.matched().values())
                 and all(self.listener.matched().values()), "DDS discovery")
        self.sent = 0

    def write(self, t, q, v, w, names=NAMES, frame="ft_sensor", joint=True, ft=True):
        """A joint state stamped 0.2 ms before the wrench (brought forward to it) and the
        wrench stamped `t`."""
        if joint:
            by_name = dict(zip(NAMES, range(N), strict=True))
            self.joints.write(JointState(
                header=header(t - 0.0002, "base_link"), name=list(names),
                position=[float(q[by_name[n]]) for n in names],
                velocity=[float(v[by_name[n]]) for n in names], effort=[]))
        if ft:
            self.ft.write(wrench_stamped(header(t, frame), list(map(float, w))))
        self.sent += joint + ft

    def spin_all(self):
        for dut in (self.on, self.off):
            wait_for(lambda dut=dut: (dut.spin_once(1), sum(dut.monitor.received.values()))[1]
                     >= self.sent, "the stations to receive")

    def caught_up(self):
        def done():
            self.listener.spin(0)
            return all(len(self.got[(dut.config.compiled_path, "wrench_contact")])
                       == dut.published for dut in (self.on, self.off))
        wait_for(done, "the listener")

    def close(self):
        for node in (self.listener, self.driver, self.on, self.off):
            node.close()


def _values(message):
    if hasattr(message, "wrench"):
        f, m = message.wrench.force, message.wrench.torque
        return (from_stamp(message.header.stamp), message.header.frame_id,
                (f.x, f.y, f.z, m.x, m.y, m.z))
    return message.data


def drive(twin):
    """The twin stream (helpers.twin_stream), joint states in reversed order until k 1250;
    with a wrench in another frame, a joint state in degrees and one going back."""
    for k, t, q, v, w in twin_stream():
        names = NAMES if k >= 1250 else NAMES[::-1]  # the driver's joint order changes
        twin.write(t, q, v, w, names=names, frame="ft_other" if k == 1300 else "ft_sensor")
        if k == 1350:  # a joint state in degrees, between two good ones
            twin.write(t + 0.0005, np.degrees(q) + 400.0, v, w, names=names, ft=False)
        if k == 1150:
            twin.write(t - 0.0015, q, v, w, names=names, ft=False)  # a stamp going back
        if k % 50 == 49:
            twin.spin_all()
    twin.spin_all()


@pytest.mark.parametrize("tracker", [True, False], ids=["tracker on", "tracker off"])
def test_the_compiled_path_publishes_and_counts_as_the_python_path(tracker):
    chain = ChainConfig()
    chain.bias_tracker.enabled = tracker
    twin = Twin(fused_forest(), chain)
    try:
        assert twin.on.compiled.why_not is None, twin.on.compiled.why_not
        assert twin.off.compiled.why_not == "ros2.compiled_path is false"
        drive(twin)
        twin.spin_all()
        twin.caught_up()
        on, off = twin.on.summary(), twin.off.summary()
        assert_twins_count_alike(on, off)
        assert on["load"]["lost_ft"] == off["load"]["lost_ft"] == 5
        assert on["rejected"] == {"not_finite": 1, "out_of_order": 1, "joint_range": 1}
        assert on["processed"] > 1650
        for name in OUTPUTS:
            if not twin.on.has_output(name):
                continue
            got_on = [_values(m) for m in twin.got[(True, name)]]
            got_off = [_values(m) for m in twin.got[(False, name)]]
            assert got_on == got_off, name
        contact = [m.data for m in twin.got[(True, "contact")]]
        assert any(contact) and not all(contact)
        frames = {m.header.frame_id for m in twin.got[(True, "wrench_contact")]}
        assert frames == {"ft_sensor", "ft_other"}
        compiled = on["compiled_path"]
        # Most messages went through the compiled loop; the unusual ones went back.
        assert compiled["used"] and compiled["calls"] > 10 and compiled["handed_back"] >= 5
        assert off["compiled_path"]["calls"] == 0
        # The first second, and the settle windows after the lost samples, are Python's.
        assert twin.on.compiled.loop_messages > 500
    finally:
        twin.close()


def test_cdr_reads_and_writes_the_bytes_cyclonedds_does():
    rng = np.random.default_rng(4)
    scratch = np.zeros(8, dtype=np.uint8)
    order = np.array([NAMES[::-1].index(n) for n in NAMES])
    for frame in ("", "ft", "ft_sensor_link"):
        q, v = rng.normal(size=N), rng.normal(size=N)
        message = JointState(header=header(12.25, frame), name=NAMES[::-1],
                             position=q[::-1].tolist(), velocity=v[::-1].tolist(),
                             effort=[1.0] * N)
        data = np.frombuffer(message.serialize(), dtype=np.uint8).copy()
        x = np.zeros(2 * N)
        assert read_joint_state(data, len(data), names_cdr(NAMES[::-1]), order, x,
                                np.zeros(N), scratch)
        np.testing.assert_array_equal(x, np.r_[q, v])
        # Another name list, or a message cut short: not read here (Python's).
        assert not read_joint_state(data, len(data), names_cdr(NAMES), order, x, np.zeros(N),
                                    scratch)
        assert not read_joint_state(data, len(data) // 2, names_cdr(NAMES[::-1]), order, x,
                                    np.zeros(N), scratch)
        w = rng.normal(size=6)
        sample = wrench_stamped(header(3.5, frame), w.tolist())
        data = np.frombuffer(sample.serialize(), dtype=np.uint8).copy()
        got = np.zeros(6)
        end = read_wrench(data, len(data), got, scratch)
        np.testing.assert_array_equal(got, w)
        out = np.zeros(256, dtype=np.uint8)
        size = wrench_bytes(out, np.array([0, 1, 0, 0], dtype=np.uint8), data, end, w, scratch)
        writer = type("Writer", (), {"_use_version_2": False})()
        assert bytes(out[:size]) == packing._official(sample, writer)


def test_wrong_declarations_keep_the_python_path(monkeypatch):
    """The self-test catches a sample-info layout other than the one declared (the stride
    of the infos: a real mistake of a first prototype) and the station says why."""
    participant = Ros2Node(DOMAIN)
    try:
        c = cyclone.load()
        assert cyclone.self_test(participant.participant, c) is None
        monkeypatch.setattr(cyclone, "INFO_BYTES", 56)
        problem = cyclone.self_test(participant.participant, c)
        assert problem is not None and "not laid out as declared" in problem
    finally:
        participant.close()
    dut = station(fused_forest(), True)
    try:
        assert dut.compiled.why_not.startswith("Cyclone DDS's C declarations do not hold")
        assert dut.summary()["compiled_path"]["used"] is False
    finally:
        dut.close()


def test_where_the_compiled_path_does_not_apply_it_says_why():
    chain = ChainConfig()
    chain.sensor.wrench_delay_s = 0.002
    config = Ros2Config(joint_names=list(NAMES), domain_id=DOMAIN)
    dut = Ros2Station(config, fused_forest(), chain)
    try:
        assert dut.compiled.why_not == ("the wrench is delayed against the joint state "
                                        "(chain.sensor.wrench_delay_s)")
    finally:
        dut.close()
    with pytest.raises(ConfigError, match=r"ros2\.compiled_path: true or false"):
        Ros2Config(joint_names=list(NAMES), compiled_path="yes").validate()


def test_the_loop_is_compiled_in_a_process_of_its_own_and_a_failure_there_is_said(
        monkeypatch):
    """Found in numba's cache, the loop is loaded before the station serves; else it
    compiles in its own process while the station serves in Python, and is loaded here once
    that is done. A compile that fails keeps the Python path and says why, as a
    warning."""
    dut = station(fused_forest(), True)
    try:
        assert dut.compiled._loaded and dut.compiled.compile_s > 0
        assert dut.summary()["compiled_path"]["ready_after_s"] == dut.compiled.compile_s
    finally:
        dut.close()
    monkeypatch.setattr("ftdrake.hardware.fast.path._in_cache", lambda *_: False)
    monkeypatch.setattr("ftdrake.hardware.fast.path.sys.executable", "/bin/false")
    config = Ros2Config(joint_names=list(NAMES), domain_id=DOMAIN)
    dut = Ros2Station(config, fused_forest(), ChainConfig())
    try:
        assert not dut.compiled.ready()  # compiling meanwhile: the Python path serves
        assert not dut.compiled.wait()
        assert dut.compiled.why_not == "compiling it failed (exit 1: no message)"
        assert any("compiled per-message path is not used" in w for w in dut.warnings)
        dut.spin_once(0)  # the Python path
    finally:
        dut.close()
