"""The wrench paired with the joint state by stamp (LCM station on memq://, a test clock):
a wrench stream that lags the joint states is compensated with the joint state of its own
stamp, not the newest; a wrench with no joint state within the tolerance is a fault and is
never judged; ``pair_tolerance_s: 0`` pairs by arrival (the newest joint state)."""

import numpy as np
import pytest

from ftdrake import ChainConfig, ConfigError, RandomForestCompensator
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.messages import (
    decode_contact_state,
    decode_wrench,
    encode_joint_state,
    encode_wrench,
)

N = 7
PERIOD = 0.001
LAG = 20  # the wrench stream lags the joint states by this many periods


def q_at(k):
    return np.linspace(-0.5, 0.5, N) + 0.02 * k  # rad, moving: each stamp its own pose


class Rig:
    def __init__(self, pair_tolerance_s):
        rng = np.random.default_rng(0)
        X = rng.uniform(-1, 1, size=(300, 3 * N))
        self.model = RandomForestCompensator(features="q", n_estimators=5).fit(
            X, np.sin(3 * X[:, :6]))
        chain = ChainConfig()
        chain.bias_tracker.enabled = False
        self.config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=1.0,
                                     joint_state_timeout_s=1.0,
                                     pair_tolerance_s=pair_tolerance_s)
        self.now = 0.0
        self.dut = HardwareStation(self.config, self.model, chain, "memq://",
                                   clock=lambda: self.now)
        self.wrenches, self.contacts = [], []
        self.dut.lcm.subscribe(self.config.output_channel("wrench_compensated"),
                               lambda d: self.wrenches.append(decode_wrench(d)))
        self.dut.lcm.subscribe(self.config.output_channel("contact"),
                               lambda d: self.contacts.append(decode_contact_state(d)))

    def send(self, k_joint, k_wrench=None):
        """At the test clock k_joint·PERIOD: the joint state of k_joint, and (if given) the
        wrench stamped k_wrench·PERIOD."""
        self.now = k_joint * PERIOD
        lc = self.dut.lcm
        lc.publish(self.config.joint_state_channel, encode_joint_state(
            "iiwa_status", k_joint * PERIOD, q_at(k_joint), np.zeros(N)))
        if k_wrench is not None:
            lc.publish(self.config.ft_channel, encode_wrench(k_wrench * PERIOD, np.ones(6)))
        self.dut.spin_once(0)
        lc.handle(0)

    def predicted(self, k):
        return self.model.predict(np.r_[q_at(k), np.zeros(2 * N)][None])[0]


def lagging_run(rig, n=60):
    for k in range(1, n + 1):
        rig.send(k, k - LAG if k > LAG else None)


def test_a_lagging_wrench_is_paired_with_the_joint_state_of_its_stamp():
    rig = Rig(pair_tolerance_s=0.005)
    lagging_run(rig)
    assert len(rig.wrenches) == 60 - LAG and not rig.dut.monitor.fault
    for w in rig.wrenches:
        k = round(w.t / PERIOD)
        np.testing.assert_allclose(w.wrench, np.ones(6) - rig.predicted(k), atol=1e-12)


def test_pairing_by_arrival_takes_the_newest_joint_state():
    """pair_tolerance_s 0: the behaviour without pairing, each wrench with the newest joint
    state (LAG periods later than its stamp) — what the pairing corrects."""
    rig = Rig(pair_tolerance_s=0.0)
    lagging_run(rig)
    for w in rig.wrenches:
        k = round(w.t / PERIOD)
        np.testing.assert_allclose(w.wrench, np.ones(6) - rig.predicted(k + LAG), atol=1e-12)
    assert not np.allclose(rig.predicted(10), rig.predicted(10 + LAG))


def test_a_wrench_with_no_joint_state_within_the_tolerance_is_a_fault_not_judged():
    rig = Rig(pair_tolerance_s=0.005)
    for k in range(1, 11):
        rig.send(k, k)
    published = len(rig.wrenches)
    rig.send(11, 11 + 100)  # stamped 100 ms after every joint state there is
    m = rig.dut.monitor
    assert m.fault and m.reason == "stamp_gap"
    assert "no joint state stamped within 5 ms of the F/T sample at 0.111000 s" in m.detail
    assert "-100.0 ms away" in m.detail and "lcm.pair_tolerance_s" in m.detail
    assert len(rig.wrenches) == published  # nothing judged from it
    assert rig.contacts[-1].fault and not rig.contacts[-1].contact
    rig.send(112, 112)
    assert not m.fault and len(rig.wrenches) == published + 1


def test_streams_stamped_on_different_clocks_are_named_with_both_fixes():
    """Joint states stamped with one clock and wrenches with another (a sensor's own clock
    against the robot's, sim time against wall time): every wrench is a stamp gap, and the
    fault says the clocks differ, by how much, and both fixes, the key named. Paired by
    arrival (pair_tolerance_s 0) the same stream is compensated."""
    rig = Rig(pair_tolerance_s=0.005)
    offset = 1000  # periods: 1 s
    for k in range(1, 6):
        rig.send(k, k + offset)
    m = rig.dut.monitor
    assert m.fault and m.reason == "stamp_gap" and not rig.wrenches
    assert "on different clocks" in m.detail and "-1.000 s" in m.detail
    assert "set lcm.pair_tolerance_s: 0" in m.detail
    rig = Rig(pair_tolerance_s=0.0)
    for k in range(1, 6):
        rig.send(k, k + offset)
    assert not rig.dut.monitor.fault and len(rig.wrenches) == 5


def test_the_tolerance_is_checked():
    with pytest.raises(ConfigError, match=r"hardware\.pair_tolerance_s"):
        HardwareConfig(pair_tolerance_s=-1.0).validate()


def test_a_joint_state_is_brought_to_the_wrench_stamp_exactly_under_constant_acceleration():
    """joint_state_at: q + q̇δ + ½q̈δ², q̇ + q̈δ, q̈ from the joint state before it by their
    stamps — exact for a motion of constant q̈, ahead of the joint state or behind it; the
    joint state itself when the stamps are equal; q̈ = 0 without one before it."""
    from ftdrake.hardware.live_inputs import joint_state_at

    q0, v0, a = np.linspace(-1, 1, N), np.linspace(0.5, -0.3, N), np.linspace(2, -3, N)

    def x(t):
        return np.r_[q0 + v0 * t + 0.5 * a * t**2, v0 + a * t]

    before = (0.010, x(0.010))
    for t in (0.0132, 0.0101, 0.0087):  # after the joint state at 12 ms, and before it
        np.testing.assert_allclose(joint_state_at(t, 0.012, x(0.012), before), x(t),
                                   rtol=0, atol=1e-13)
    held = x(0.012)
    assert joint_state_at(0.012, 0.012, held, before) is held
    np.testing.assert_allclose(joint_state_at(0.013, 0.012, held),
                               np.r_[held[:N] + 0.001 * held[N:], held[N:]], rtol=0, atol=1e-15)
