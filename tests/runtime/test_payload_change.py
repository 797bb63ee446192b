"""A payload change nobody signalled, told from a contact by how its wrench follows gravity.

Generated data: the sensor turns about a tilted axis, so g_S turns in S; a payload's wrench is
Newton's law for a rigid body at rest (F = m·g_S, T = c × F), independent of the monitor's
regressor; a press is a force fixed in the world (a wall) or in S (a tool held against
something)."""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RotationMatrix
from pydrake.systems.analysis import Simulator

from ftdrake.config import ConfigError, PayloadChangeConfig, SensorConfig
from ftdrake.runtime.detector import PAYLOAD_DECIDED
from ftdrake.runtime.payload_change import (
    PAYLOAD_STATES,
    PayloadChangeMonitor,
    is_payload_change,
    payload_change_statistics,
)

G_W = np.array([0.0, 0.0, -9.81])
MASS, COM = 0.5, np.array([0.0, 0.02, 0.12])  # kg, m from So in S
SIGMA = np.array(SensorConfig().spec().noise_std)


def _axis_angle(axis, angle):
    return AngleAxis(angle, axis)


def payload_wrench(g_S, mass=MASS, com=COM):
    force = mass * g_S
    return np.hstack([force, np.cross(com, force)])


def noise(n, seed):
    return np.random.default_rng(seed).normal(0.0, SIGMA, (n, 6))


@pytest.fixture(scope="module")
def motion():
    """2 s of the sensor turning at 20°/s, sampled every 20 ms: g_S and R_SW per sample."""
    t = np.arange(0.0, 2.0, 0.02)
    axis = np.array([1.0, 0.5, 0.2]) / np.linalg.norm([1.0, 0.5, 0.2])
    tilt = RotationMatrix.MakeXRotation(0.4)
    R_SW = np.array([(tilt @ RotationMatrix(_axis_angle(axis, a))).inverse().matrix()
                     for a in np.radians(20.0) * t])
    return t, R_SW, R_SW @ G_W


def press(R_SW, force_W, tip=(0.0, 0.0, 0.15)):
    force = R_SW @ np.asarray(force_W)
    return np.hstack([force, np.cross(np.asarray(tip), force)])


def test_the_payload_is_identified_exactly_and_explains_its_wrench(motion):
    _, _, g = motion
    stats = payload_change_statistics(payload_wrench(g), g, SIGMA)
    np.testing.assert_allclose(stats["theta"], [MASS, *(MASS * COM)], rtol=1e-9, atol=1e-12)
    assert stats["sse_payload"] < 1e-12 * stats["sst"]
    # g_S turns by at most the sensor's own turn (39.6°), less for an axis not ⟂ to gravity.
    assert 30.0 < stats["rotation_deg"] <= 39.6 + 1e-9
    assert is_payload_change(stats, PayloadChangeConfig())


@pytest.mark.parametrize("force_W", [[4.905, 0.0, 0.0], [0.0, -3.5, 3.5]])
def test_a_press_fixed_in_the_world_is_not_a_payload(motion, force_W):
    """A wall's push (horizontal, or 45° up) of a 0.5 kg weight's force while turning."""
    _, R_SW, g = motion
    stats = payload_change_statistics(press(R_SW, force_W) + noise(len(g), 1), g, SIGMA)
    print(f"unexplained {stats['sse_payload'] / stats['sst']:.3f}")
    assert stats["sse_payload"] > 0.2 * stats["sst"]
    assert not is_payload_change(stats, PayloadChangeConfig())


def test_a_press_constant_in_the_sensor_frame_is_not_a_payload(motion):
    _, _, g = motion
    wrench = np.tile([3.0, -2.0, 2.5, 0.1, 0.2, 0.0], (len(g), 1)) + noise(len(g), 2)
    stats = payload_change_statistics(wrench, g, SIGMA)
    assert stats["sse_constant"] < stats["sse_payload"]
    assert not is_payload_change(stats, PayloadChangeConfig())


def test_without_rotation_a_weight_is_not_decided(motion):
    """At rest a weight and a steady press along gravity look alike: no decision."""
    _, _, g = motion
    still = np.tile(g[0], (len(g), 1))
    stats = payload_change_statistics(payload_wrench(still) + noise(len(g), 3), still, SIGMA)
    assert stats["rotation_deg"] == 0.0
    assert not is_payload_change(stats, PayloadChangeConfig())


def run_monitor(wrench, gravity, contact, config=None, with_state=False):
    """The monitor alone, fed one sample per period (its inputs held between samples)."""
    monitor = PayloadChangeMonitor(config or PayloadChangeConfig(), SensorConfig())
    simulator = Simulator(monitor)
    context = simulator.get_mutable_context()
    ports = [monitor.get_input_port_wrench_contact().FixValue(context, wrench[0]),
             monitor.get_input_port_gravity_S().FixValue(context, gravity[0]),
             monitor.get_input_port_contact().FixValue(context, [contact[0]])]
    flag, estimate, state = [], [], []
    for k in range(len(wrench)):
        for port, value in zip(ports, (wrench[k], gravity[k], [contact[k]]), strict=True):
            port.GetMutableData().get_mutable_value().SetFromVector(value)
        simulator.AdvanceTo((k + 0.5) * monitor.period)
        flag.append(monitor.get_output_port_payload_change().Eval(context)[0])
        estimate.append(monitor.get_output_port_payload_change_estimate().Eval(context).copy())
        state.append(monitor.get_output_port_payload_state().Eval(context)[0])
    if with_state:
        return np.array(flag), np.array(estimate), np.array(state)
    return np.array(flag), np.array(estimate)


def test_the_monitor_announces_a_weight_once_it_has_turned(motion):
    """A 0.5 kg weight from the first sample, the detector reporting contact: announced once,
    when the window has turned min_rotation_deg (10° at 20°/s: ½ s), with its mass."""
    t, _, g = motion
    flag, estimate = run_monitor(payload_wrench(g) + noise(len(g), 4), g, np.ones(len(g)))
    first = np.argmax(flag > 0.5)
    print(f"announced at {t[first]:.2f} s; Δm {estimate[first, 0]:.4f} kg")
    assert flag.any() and 0.45 <= t[first] <= 0.6
    assert estimate[first, 0] == pytest.approx(MASS, rel=0.02)
    np.testing.assert_allclose(estimate[first, 1:] / estimate[first, 0], COM, atol=0.005)
    # High for signal_s (0.1 s: 5 periods), then refractory: one announcement.
    rises = np.flatnonzero(np.diff(np.r_[0.0, flag]) > 0.5)
    assert len(rises) == 1 and flag.sum() == 5


def test_the_monitor_ignores_a_press_and_the_free_tool(motion):
    _, R_SW, g = motion
    flag, _ = run_monitor(press(R_SW, [4.905, 0.0, 0.0]) + noise(len(g), 5), g, np.ones(len(g)))
    assert not flag.any()
    # The weight's wrench without a contact flag: the detector did not fire, nothing to judge.
    flag, _ = run_monitor(payload_wrench(g), g, np.zeros(len(g)))
    assert not flag.any()


def test_the_window_restarts_when_the_contact_ends(motion):
    """Contact flags that stop before the rotation suffices leave no evidence behind."""
    t, _, g = motion
    contact = ((t < 0.3) | (t > 1.0)).astype(float)  # 0.3 s, then from 1 s on
    flag, _ = run_monitor(payload_wrench(g), g, contact)
    first = t[np.argmax(flag > 0.5)]
    assert flag.any() and first >= 1.0 + 0.45


def test_config_is_validated():
    with pytest.raises(ConfigError, match=r"payload_change\.max_unexplained"):
        dc.replace(PayloadChangeConfig(), max_unexplained=1.5).validate()
    with pytest.raises(ConfigError, match=r"window_s.*fewer than 5 samples"):
        dc.replace(PayloadChangeConfig(), window_s=0.05).validate()


NONE, UNDECIDED, PAYLOAD, CONTACT = (PAYLOAD_STATES[k] for k in (
    "none", "undecided", "payload", "contact"))


def first(mask) -> int:
    """The first index where `mask` holds (−1: nowhere)."""
    return int(np.argmax(mask)) if np.any(mask) else -1


def test_the_decision_is_undecided_until_the_tool_has_turned_then_payload(motion):
    """A weight: undecided (1) while g_S has turned under min_rotation_deg, then a payload
    change (2), held for the refractory time, then none (0: the contact has ended); never
    a contact (3)."""
    t, _, g = motion
    contact = (t < 0.7).astype(float)  # the detector releases after the tracker took over
    _, _, state = run_monitor(payload_wrench(g) + noise(len(g), 4), g, contact,
                              with_state=True)
    decided = first(state == PAYLOAD)
    turn = np.degrees(np.arccos(np.clip(g @ g[0] / np.linalg.norm(g, axis=1) / 9.81, -1, 1)))
    assert decided > 0 and turn[decided] >= 10.0 > turn[decided - 1]
    assert (state[:decided] == UNDECIDED).all() and not (state == CONTACT).any()
    held = round(PayloadChangeConfig().refractory_s / 0.02)
    assert (state[decided:decided + held + 1] == PAYLOAD).all()
    assert (state[decided + held + 1:] == NONE).all()
    assert PAYLOAD == PAYLOAD_DECIDED  # the value the detector stands down on


@pytest.mark.parametrize("force_W", [[4.905, 0.0, 0.0], [0.0, -3.5, 3.5]])
def test_a_press_is_decided_a_contact_once_the_tool_has_turned(motion, force_W):
    t, R_SW, g = motion
    _, _, state = run_monitor(press(R_SW, force_W) + noise(len(g), 1), g, np.ones(len(g)),
                              with_state=True)
    decided = first(state == CONTACT)
    print(f"contact decided at {t[decided]:.2f} s")
    assert 0.45 <= t[decided] <= 0.6
    assert (state[:decided] == UNDECIDED).all() and (state[decided:] == CONTACT).all()


def test_without_rotation_a_weight_stays_undecided(motion):
    """Held still, a weight is neither a payload change nor a contact; without contact the
    decision is none."""
    _, _, g = motion
    still = np.tile(g[0], (len(g), 1))
    wrench = payload_wrench(still) + noise(len(g), 3)
    _, _, state = run_monitor(wrench, still, np.ones(len(g)), with_state=True)
    assert (state == UNDECIDED).all()
    _, _, state = run_monitor(wrench, still, np.zeros(len(g)), with_state=True)
    assert (state == NONE).all()


def held_poses(hold_s=0.6, period=0.02):
    """A short log of three held poses (static gravity, by hand): the sensor tilted 0°, 25°
    and 50° about an axis ⟂ to gravity, each held `hold_s`; (t, R_SW per sample, g_S)."""
    t = np.arange(0.0, 3 * hold_s, period)
    pose = np.minimum((t / hold_s).astype(int), 2)
    axis = np.array([0.6, 0.8, 0.0])
    R_SW = np.array([RotationMatrix(_axis_angle(axis, np.radians(25.0) * k)).inverse().matrix()
                     for k in pose])
    return t, pose, R_SW, R_SW @ G_W


@pytest.mark.parametrize("what", ["weight", "press"])
def test_three_held_poses_decide_within_a_sample_of_the_second_pose(what):
    """The log of three held poses, the change present from its start and the detector
    reporting contact throughout: undecided in the first pose, decided (payload for the
    weight, contact for a press fixed in the world) at the first sample of the second."""
    t, pose, R_SW, g = held_poses()
    wrench = (payload_wrench(g) if what == "weight" else press(R_SW, [4.905, 0.0, 0.0]))
    _, estimate, state = run_monitor(wrench + noise(len(g), 6), g, np.ones(len(g)),
                                     with_state=True)
    expected = PAYLOAD if what == "weight" else CONTACT
    arrived = first(pose == 1)
    assert (state[:arrived] == UNDECIDED).all()
    assert state[arrived] == expected
    print(f"{what}: decided {t[first(state == expected)] - t[arrived]:.2f} s after the turn")
    if what == "weight":
        assert estimate[arrived, 0] == pytest.approx(MASS, rel=0.02)
        assert not (state == CONTACT).any()
    else:
        assert (state[arrived:] == CONTACT).all()
