"""After an overload drop the chain restarts what differentiates or integrates across the
gap: a station in free motion whose F/T stream falls behind (a stretch of messages dropped
as the oldest) declares no contact once it publishes again. The model's internal wrench
depends on q̈, which the station estimates from q̇ (the chain's causal estimate): across a
dropped stretch q̇ jumps, and that jump must not read as an acceleration, be learned into the
bias tracker's estimate, or leave the detector holding a contact. No timing is asserted: the
test's clock is the station's."""

import numpy as np
import pytest

from ftdrake import ChainConfig, RandomForestCompensator
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.core import SETTLE_AFTER_DROP_S
from ftdrake.hardware.messages import decode_contact_state, encode_joint_state, encode_wrench

N = 7
PERIOD = 0.001
FREQ = 0.7 * (1 + np.arange(N) / N)  # Hz, one per joint
AMP = 0.6  # rad
GAIN = 0.8  # N per rad/s² of each of the first six joints' q̈


def motion(t):
    """q, q̇, q̈ (rad, rad/s, rad/s²) of the free motion at times `t` (s)."""
    w = 2 * np.pi * FREQ
    phase = np.outer(t, w)  # q̈ = 0 at the start, where the station's estimate starts
    return AMP * np.sin(phase), AMP * w * np.cos(phase), -AMP * w**2 * np.sin(phase)


def internal(q, qdd):
    """The sensor's internal wrench (N, N·m): a q̈-dependent load plus a q-dependent one
    (torques a tenth of the forces)."""
    return (GAIN * qdd[..., :6] + 2.0 * np.cos(q[..., :6])) * [1, 1, 1, 0.1, 0.1, 0.1]


@pytest.fixture(scope="module")
def model():
    t = np.arange(0, 30, 0.004)
    q, qd, qdd = motion(t)
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=10, random_state=0).fit(
        np.hstack([q, qd, qdd]), internal(q, qdd))


def run(model, lag_s: float, press: bool = False, lost=range(0)):
    """A station (memq://, the default chain: bias tracker and detector on) fed 2.5 s of
    the free motion at 1 kHz; from 1.2 s its handling falls `lag_s` behind for 60 messages
    (the clock ahead of the stamps), then catches up; with `press`, 10 N along z from 2.0
    to 2.3 s; the wrenches numbered in `lost` are never sent. Returns the station and the contact
    states it published, (t, contact, fault)."""
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=1.0, joint_state_timeout_s=1.0,
                            max_backlog_s=0.05)
    now = [0.0]
    chain = ChainConfig()
    chain.detector.test = "norm"  # force_on 2.5 N, torque_on 0.25 N·m
    dut = HardwareStation(config, model, chain, "memq://", clock=lambda: now[0])
    contacts = []
    dut.lcm.subscribe(config.output_channel("contact"),
                      lambda d: contacts.append(decode_contact_state(d)))
    lc = dut.lcm.lc
    times = np.arange(1, 2501) * PERIOD
    q, qd, qdd = motion(times)
    wrench = internal(q, qdd)
    if press:
        wrench[(times >= 2.0) & (times < 2.3), 2] += 10.0
    for k, t in enumerate(times):
        now[0] = t + (lag_s if 1200 <= k < 1260 else 0.0)
        lc.publish(config.joint_state_channel, encode_joint_state("iiwa_status", t, q[k], qd[k]))
        if k not in lost:
            lc.publish(config.ft_channel, encode_wrench(t, wrench[k]))
        while lc.handle_timeout(0) > 0:  # both, and the station's own outputs
            pass
    return dut, contacts


def test_the_free_motion_alone_is_free_of_contact(model):
    """The check below would pass on a station that never declares contact: without the
    drop it declares none, and a press it declares."""
    dut, contacts = run(model, 0.0)
    assert dut.load.dropped == 0 and dut.published == dut.processed == 2500
    assert not any(c.contact for c in contacts)
    _, contacts = run(model, 0.0, press=True)
    declared = [c.t for c in contacts if c.contact]
    assert declared and 2.0 < min(declared) < 2.01 and max(declared) < 2.4


def test_no_contact_after_a_dropped_stretch(model):
    dut, contacts = run(model, 0.2)
    assert dut.load.dropped > 20  # a stretch of the oldest was dropped
    settle = round(SETTLE_AFTER_DROP_S / PERIOD)
    assert dut.published <= dut.processed - settle  # nothing published while settling
    declared = [(c.t, c.fault) for c in contacts if c.contact]
    assert not declared, declared[:5]


def test_no_contact_after_lost_samples(model):
    """A stretch of F/T messages that never arrived (the joint states did): no settle window
    (nothing was dropped here), yet the q̈ estimate bridges the gap by the mean
    acceleration over it instead of reading q̇'s jump as one period's: no contact."""
    dut, contacts = run(model, 0.0, lost=range(1200, 1260))
    assert dut.load.lost == 60 and dut.load.dropped == 0
    declared = [(c.t, c.fault) for c in contacts if c.contact]
    assert not declared, declared[:5]
