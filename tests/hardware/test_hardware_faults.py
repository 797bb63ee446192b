"""Fault injection through the station (memq://, a test clock): the sensor stream stops,
resumes, jumps back in time, carries NaN; the joint stream has the wrong joint count. Each
raises and publishes the fault with a message naming it, publishes no stale wrench, and the
station recovers on the next good messages."""

import numpy as np
import pytest

from ftdrake import ChainConfig, ConfigError, RandomForestCompensator, ScenarioConfig
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.messages import (
    ContactState,
    decode_contact_state,
    decode_wrench,
    encode_joint_state,
    encode_wrench,
)

N = 7


class Rig:
    """A station on memq:// with a clock the test moves; records what it publishes."""

    def __init__(self, joint_state_type="iiwa_status"):
        rng = np.random.default_rng(0)
        X = rng.uniform(-1, 1, size=(200, 3 * N))
        self.model = RandomForestCompensator(features="q", n_estimators=3).fit(
            X, np.sin(X[:, :6]))
        scenario = ScenarioConfig()
        scenario.chain.bias_tracker.enabled = False  # the published wrench is measured − predicted
        self.config = HardwareConfig(
            lcm_url="memq://", sensor_timeout_s=0.005, joint_state_timeout_s=0.02,
            joint_state_type=joint_state_type,
            velocity_channel="ROBOT_VELOCITY" if joint_state_type == "robot_state" else "")
        self.now = 0.0
        self.events = []
        self.dut = HardwareStation(self.config, self.model, scenario.chain_config(), "memq://",
                                   clock=lambda: self.now, on_event=self.events.append)
        self.wrenches, self.contacts = [], []
        lcm = self.dut.lcm
        lcm.subscribe(self.config.output_channel("wrench_compensated"),
                      lambda d: self.wrenches.append(decode_wrench(d)))
        lcm.subscribe(self.config.output_channel("contact"),
                      lambda d: self.contacts.append(decode_contact_state(d)))
        self.q = np.linspace(-0.5, 0.5, N)

    def joint(self, t, n=N):
        c = self.config
        if c.joint_state_type == "robot_state":
            self.dut.lcm.publish(c.joint_state_channel,
                                 encode_joint_state("robot_state", t, self.q[:n]))
            self.dut.lcm.publish(c.velocity_channel,
                                 encode_joint_state("robot_state", t, np.zeros(n)))
        else:
            self.dut.lcm.publish(c.joint_state_channel, encode_joint_state(
                "iiwa_status", t, self.q[:n] if n <= N else np.r_[self.q, 0.0], np.zeros(n)))

    def wrench(self, t, w):
        self.dut.lcm.publish(self.config.ft_channel, encode_wrench(t, w))

    def step(self, t, w=1.0, n=N, joint=True):
        """At wall time = t: a joint message (if `joint`), an F/T message, a spin."""
        self.now = t
        if joint:
            self.joint(t, n)
        self.wrench(t, np.full(6, w))
        self.spin()

    def spin(self):
        self.dut.spin_once(0)
        self.dut.lcm.handle(0)

    def expected(self, w):
        return np.full(6, w) - self.model.predict(np.r_[self.q, np.zeros(2 * N)][None])[0]


@pytest.fixture
def rig():
    rig = Rig()
    for k in range(5):
        rig.step(0.001 * k)
    assert len(rig.wrenches) == 5 and not rig.dut.monitor.fault
    assert [e.kind for e in rig.events] == ["recovered"]  # from "no data yet"
    rig.events.clear()
    return rig


def published_times(rig):
    return [round(w.t * 1e3) for w in rig.wrenches]


def test_sensor_stream_stops_and_resumes(rig):
    rig.now = 0.004 + 0.0061  # 6.1 ms of silence; the joint stream is silent as well
    rig.spin()
    assert rig.dut.monitor.fault and rig.dut.monitor.reason == "sensor_timeout"
    (event,) = rig.events
    assert event.kind == "fault" and event.reason == "sensor_timeout"
    assert event.t == pytest.approx(0.0101, abs=1e-9)  # stream time at detection
    assert "no F/T message for 6.1 ms (timeout 5 ms)" in str(event)
    fault_msg = rig.contacts[-1]
    assert fault_msg.fault and fault_msg.t == pytest.approx(0.0101, abs=1e-6)
    rig.spin()  # still silent: the fault is published once, not on every spin
    assert len(rig.contacts) == 6 and len(rig.wrenches) == 5
    rig.step(0.011, w=2.0)  # resumes
    assert not rig.dut.monitor.fault and rig.events[-1].kind == "recovered"
    assert published_times(rig) == [0, 1, 2, 3, 4, 11]
    np.testing.assert_allclose(rig.wrenches[-1].wrench, rig.expected(2.0), atol=1e-12)
    assert not rig.contacts[-1].fault


def test_sensor_time_goes_back_and_nan(rig):
    rig.step(0.002, w=9.0, joint=False)  # F/T back in time: 2 ms < 4 ms
    assert rig.dut.monitor.reason == "out_of_order" and rig.contacts[-1].fault
    assert "went back from 0.004000 s to 0.002000 s" in str(rig.events[-1])
    rig.step(0.005, w=np.nan)
    assert rig.dut.monitor.reason == "not_finite" and rig.contacts[-1].fault
    assert "NaN" in rig.events[-1].detail
    assert published_times(rig) == [0, 1, 2, 3, 4]  # neither is published
    rig.step(0.006, w=3.0)
    assert not rig.dut.monitor.fault and rig.events[-1].kind == "recovered"
    np.testing.assert_allclose(rig.wrenches[-1].wrench, rig.expected(3.0), atol=1e-12)
    assert rig.dut.monitor.rejected == {"out_of_order": 1, "not_finite": 1}
    assert rig.dut.fault_episodes == {"out_of_order": 1, "not_finite": 1}
    assert rig.dut.summary()["processed"] == 6


def test_wrong_joint_count_faults_until_a_good_joint_state(rig):
    rig.step(0.005, n=6)  # the F/T message is good, the joint state it would use is stale
    assert rig.dut.monitor.fault and rig.dut.monitor.reason == "joint_count"
    assert "joint state has 6 positions and 6 velocities, expected 7" in str(rig.events[0])
    rig.step(0.006, joint=False)  # still no good joint state: still faulted, nothing published
    assert published_times(rig) == [0, 1, 2, 3, 4]
    assert [c.fault for c in rig.contacts[-2:]] == [True, True]
    rig.step(0.007, w=4.0)
    assert not rig.dut.monitor.fault and published_times(rig)[-1] == 7
    np.testing.assert_allclose(rig.wrenches[-1].wrench, rig.expected(4.0), atol=1e-12)
    assert rig.dut.monitor.received == {"joint": 7, "ft": 8}
    assert rig.dut.monitor.rejected == {"joint_count": 1}


def test_robot_state_pairs_positions_with_velocities():
    rig = Rig("robot_state")
    for k in range(3):
        rig.step(0.001 * k)
    assert len(rig.wrenches) == 3 and rig.dut.monitor.accepted["joint"] == 3
    # A position without its velocity, then a complete pair: the lone one is counted.
    rig.dut.lcm.publish(rig.config.joint_state_channel,
                        encode_joint_state("robot_state", 0.003, rig.q))
    rig.step(0.004)
    assert rig.dut.monitor.rejected == {"unpaired": 1} and len(rig.wrenches) == 4
    q32 = rig.q.astype(np.float32).astype(float)
    np.testing.assert_allclose(rig.dut.monitor.joint_state[:N], q32, rtol=0, atol=0)


GRASP_MASS, GRASP_COM = 0.5, np.array([0.0, 0.02, 0.12])  # kg; m from So, in S
GRASP_POSES = np.array([[0, 0, 0, 0, 0, 0, 0], [0.6, 0.3, 0, -0.4, 0.8, 0.5, 0],
                        [-0.5, 0, 0.4, 0.3, -0.9, -0.4, 1.0],
                        [0.2, -0.3, -0.5, 0.2, 1.3, 0.2, -0.7],
                        [0, 0.2, 0.6, -0.2, -0.3, 0.7, 0.4]])


def hold_poses_and_grasp(dut, config, scenario, n_poses, announce: bool):
    """Drives `dut` (memq://) through the first `n_poses` of GRASP_POSES (offsets from home),
    1.2 s each at 1 kHz; from sample 500 (0.5 s) the readings carry a 0.5 kg payload's
    gravity wrench (m·g_S, c × m·g_S; g_S from Drake's own kinematics), announced on the
    payload channel at that sample when `announce`. Returns the contact states published."""
    from ftdrake.hardware.messages import PAYLOAD_COORD, encode_event
    from ftdrake.physics.scenario_robot import robot_description

    contact = []
    dut.lcm.subscribe(config.output_channel("contact"),
                      lambda d: contact.append(decode_contact_state(d)))
    plant, frame_S = robot_description(scenario.models).build_plant()
    context = plant.CreateDefaultContext()
    k = 0
    for pose in np.array(scenario.home_q) + GRASP_POSES[:n_poses]:
        plant.SetPositions(context, pose)
        g_S = frame_S.CalcPoseInWorld(context).rotation().inverse() @ np.array([0, 0, -9.81])
        payload = np.r_[GRASP_MASS * g_S, np.cross(GRASP_COM, GRASP_MASS * g_S)]
        for _ in range(1200):
            t = 0.001 * (k + 1)
            if announce and k == 500:
                dut.lcm.publish(config.payload_channel, encode_event(t, PAYLOAD_COORD))
            dut.lcm.publish(config.joint_state_channel,
                            encode_joint_state("iiwa_status", t, pose, np.zeros(N)))
            dut.lcm.publish(config.ft_channel,
                            encode_wrench(t, payload if k >= 500 else np.zeros(6)))
            dut.spin_once(0)
            dut.lcm.handle(0)
            k += 1
    return contact


def test_a_grasp_on_hardware_is_identified_from_the_joint_state():
    """Payload tracking on hardware: gravity at the sensor comes from the joint state through
    the scenario robot's chain. The arm holds five poses, 1.2 s each; at 0.5 s a 0.5 kg payload
    at c = (0, 20, 120) mm in S is grasped and announced on the payload channel. The readings
    carry its gravity wrench (m·g_S, c × m·g_S) with g_S from Drake's own kinematics. The
    tracker must find m and m·c, and nothing may read as contact after the settle window."""
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.track_payload = True
    scenario.chain.robot.file = "ftdrake"  # a forest carries no robot: the simulated arm
    model = RandomForestCompensator(features="q", n_estimators=2).fit(
        np.random.default_rng(0).uniform(-2, 2, (50, 3 * N)), np.zeros((50, 6)))
    with pytest.raises(ConfigError, match=r"hardware\.payload_channel"):
        HardwareStation(HardwareConfig(lcm_url="memq://", payload_channel="GRASP"), model,
                        ChainConfig(), "memq://")
    config = HardwareConfig(lcm_url="memq://", payload_channel="GRASP", sensor_timeout_s=10.0,
                            joint_state_timeout_s=10.0)
    dut = HardwareStation(config, model, scenario.chain_config(), "memq://")
    contact = hold_poses_and_grasp(dut, config, scenario, 5, announce=True)
    mass, com = GRASP_MASS, GRASP_COM

    estimate = dut.tracker.get_output_port_payload().Eval(
        dut.tracker.GetMyContextFromRoot(dut.chain_context()))
    np.testing.assert_array_equal(estimate, dut.output("payload"))
    assert dut.summary()["signals"]["payload_changed"] == {"received": 1, "rejected": 0}
    assert estimate[0] == pytest.approx(mass, rel=0.01)
    np.testing.assert_allclose(estimate[1:] / estimate[0], com, atol=0.001)
    after_settle = 500 + round(1000 * scenario.chain.bias_tracker.payload_settle_s)
    settled = [c.contact for c in contact[after_settle:]]
    assert len(settled) > 0 and not any(settled)


def test_a_temperature_model_reads_the_temperature_channel_and_faults_when_it_goes_stale():
    """A model trained with the sensor temperature: the station needs the channel, uses the
    last temperature (the published wrench follows it), and publishes no wrench once the
    temperature is older than its timeout."""
    from ftdrake.hardware.messages import encode_temperature

    rng = np.random.default_rng(1)
    X = np.hstack([rng.uniform(-1, 1, (400, 3 * N)), rng.uniform(20, 40, (400, 1))])
    Y = np.zeros((400, 6))
    Y[:, 0] = 0.5 * (X[:, -1] - 20.0)  # Fx drifts 0.5 N/K
    model = RandomForestCompensator(features="q", n_estimators=5).fit(X, Y)
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    with pytest.raises(ConfigError, match=r"hardware\.temperature_channel"):
        HardwareStation(HardwareConfig(lcm_url="memq://"), model, scenario.chain_config(), "memq://")
    config = HardwareConfig(lcm_url="memq://", temperature_channel="FT_TEMPERATURE",
                            temperature_timeout_s=0.5)
    now = [0.0]
    events = []
    dut = HardwareStation(config, model, scenario.chain_config(), "memq://", clock=lambda: now[0],
                          on_event=events.append)
    wrenches = []
    dut.lcm.subscribe(config.output_channel("wrench_compensated"),
                      lambda d: wrenches.append(decode_wrench(d)))
    q = np.linspace(-0.5, 0.5, N)

    def step(t, temperature=None):
        now[0] = t
        if temperature is not None:
            dut.lcm.publish(config.temperature_channel, encode_temperature(t, temperature))
        dut.lcm.publish(config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q, np.zeros(N)))
        dut.lcm.publish(config.ft_channel, encode_wrench(t, np.zeros(6)))
        dut.spin_once(0)
        dut.lcm.handle(0)

    step(0.000)  # no temperature yet: fault, nothing published
    assert not wrenches and dut.monitor.fault and "temperature" in dut.monitor.detail
    step(0.001, 25.0)
    step(0.002, 35.0)
    assert len(wrenches) == 2
    # external = measured (0) − predicted: Fx ≈ −0.5·(T − 20), from the forest's leaves.
    assert wrenches[0].wrench[0] == pytest.approx(-2.5, abs=1.0)
    assert wrenches[1].wrench[0] == pytest.approx(-7.5, abs=1.0)
    for k in range(3, 10):  # the temperature stops; F/T and joints go on
        step(0.001 * k)
    assert len(wrenches) == 9
    step(0.7)  # 0.698 s after the last temperature: stale
    assert len(wrenches) == 9 and dut.monitor.reason == "temperature_timeout"
    assert events[-1].reason == "temperature_timeout"
    step(0.701, 30.0)  # recovers with a fresh temperature
    assert len(wrenches) == 10 and not dut.monitor.fault


def test_a_re_tare_message_resets_the_tracked_bias_and_nothing_reads_as_contact():
    """The driver re-zeroes the sensor in an unknown pose: the reading jumps by 5 N / 0.2 N·m
    and a message on the tare channel says so. The tracker re-initialises its bias and no
    contact is raised; without the message the same jump reads as contact to the end."""
    from ftdrake.hardware.messages import TARE_COORD, encode_event

    rng = np.random.default_rng(2)
    model = RandomForestCompensator(features="q", n_estimators=3).fit(
        rng.uniform(-1, 1, (50, 3 * N)), np.zeros((50, 6)))
    scenario = ScenarioConfig()
    config = HardwareConfig(lcm_url="memq://", tare_channel="FT_TARED", sensor_timeout_s=1.0,
                            joint_state_timeout_s=1.0)
    jump = np.array([5.0, -5.0, 5.0, 0.2, -0.2, 0.2])
    q = np.linspace(-0.5, 0.5, N)

    def run(send_tare: bool):
        dut = HardwareStation(config, model, scenario.chain_config(), "memq://")
        contact = []
        dut.lcm.subscribe(config.output_channel("contact"),
                          lambda d: contact.append(decode_contact_state(d)))
        for k in range(3000):  # 3 s at 1 kHz, the jump at 0.5 s
            t = 0.001 * (k + 1)
            if send_tare and k == 500:
                dut.lcm.publish(config.tare_channel, encode_event(t, TARE_COORD))
            dut.lcm.publish(config.joint_state_channel,
                            encode_joint_state("iiwa_status", t, q, np.zeros(N)))
            dut.lcm.publish(config.ft_channel, encode_wrench(t, jump if k >= 500 else 0 * jump))
            dut.spin_once(0)
            dut.lcm.handle(0)
        return dut, np.array([c.contact for c in contact if not c.fault])

    tared, with_message = run(send_tare=True)
    assert tared.summary()["signals"]["tared"] == {"received": 1, "rejected": 0}
    assert not with_message.any()
    _, without = run(send_tare=False)
    assert without[600:].all()  # read as contact from the jump to the end

    scenario.chain.bias_tracker.enabled = False
    with pytest.raises(ConfigError, match=r"hardware\.tare_channel"):
        HardwareStation(config, model, scenario.chain_config(), "memq://")


def test_an_unsignalled_grasp_on_hardware_is_announced_on_the_contact_channel():
    """The same five poses and 0.5 kg payload as above, but nobody announces the grasp: with
    ``bias_tracker.payload_change`` the chain recognises it from how its wrench follows
    gravity across the poses, says so in the contact state (``payload_change``), and the
    tracker identifies it; a reader of the earlier four-value message still decodes."""
    from ftdrake.hardware.messages import CONTACT_COORDS_V1

    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.track_payload = True
    scenario.chain.robot.file = "ftdrake"  # a forest carries no robot: the simulated arm
    scenario.chain.bias_tracker.payload_change.enabled = True
    model = RandomForestCompensator(features="q", n_estimators=2).fit(
        np.random.default_rng(0).uniform(-2, 2, (50, 3 * N)), np.zeros((50, 6)))
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=10.0,
                            joint_state_timeout_s=10.0)
    dut = HardwareStation(config, model, scenario.chain_config(), "memq://")
    contact = hold_poses_and_grasp(dut, config, scenario, 4, announce=False)
    mass, com = GRASP_MASS, GRASP_COM
    t = np.array([c.t for c in contact])
    announced = t[[c.payload_change for c in contact]]
    print(f"announced from {announced[:1]} s; contact until "
          f"{t[[c.contact for c in contact]].max():.3f} s")
    # The weight reads as contact from 0.5 s; the first pose change (at 1.2 s) turns g_S.
    assert len(announced) and 1.2 < announced[0] < 1.2 + 2.0
    assert not any(c.payload_change for c in contact if c.t < 0.5)
    dm, *mc = dut.output("payload")
    assert dm == pytest.approx(mass, rel=0.02)
    np.testing.assert_allclose(np.array(mc) / dm, com, atol=0.005)
    assert not any(c.contact for c in contact if c.t > announced[0] + 1.0)
    # The earlier message's four values decode too (payload_change then False).
    from drake import lcmt_drake_signal

    old = lcmt_drake_signal()
    old.timestamp, old.dim, old.coord, old.val = 5000, 4, list(CONTACT_COORDS_V1), [1, 2.5, 0, 1]
    assert decode_contact_state(old.encode()) == ContactState(5000 * 1e-6, True, 2.5, False,
                                                              True, False)
