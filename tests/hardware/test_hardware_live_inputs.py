"""StreamMonitor: faults on gaps, time going back, duplicates, NaN, wrong joint count; recovery."""

import numpy as np
import pytest

from ftdrake.hardware import StreamMonitor
from ftdrake.hardware.messages import JointSample, WrenchSample

N = 7


def joint(t, n=N, value=0.1):
    return JointSample(t, np.full(n, value), np.zeros(n), None)


def wrench(t, value=1.0):
    return WrenchSample(t, np.full(6, value))


@pytest.fixture
def dut():
    dut = StreamMonitor(N, sensor_timeout_s=0.005, joint_state_timeout_s=0.02)
    assert dut.on_joint(joint(0.0), arrival=0.0)
    assert dut.on_wrench(wrench(0.0), arrival=0.0) and not dut.fault
    return dut


def test_faults_and_recovers(dut):
    # Gap: no F/T for longer than the timeout.
    assert dut.check_timeouts(now=0.010) and dut.reason == "sensor_timeout"
    assert dut.on_wrench(wrench(0.010, 2.0), arrival=0.010) and not dut.fault
    # Time going back: rejected, the held wrench is the last good one.
    assert not dut.on_wrench(wrench(0.005, 9.0), arrival=0.011)
    assert dut.fault and dut.reason == "out_of_order"
    np.testing.assert_array_equal(dut.wrench, np.full(6, 2.0))
    assert not dut.on_wrench(wrench(0.010, 9.0), arrival=0.011) and dut.reason == "duplicate"
    assert not dut.on_wrench(wrench(0.011, np.nan), arrival=0.011)
    assert dut.reason == "not_finite" and np.isfinite(dut.wrench).all()
    assert not dut.on_joint(joint(0.011, n=6), arrival=0.011) and dut.reason == "joint_count"
    # The joint state held from before the bad message is stale: no fresh wrench from it.
    assert not dut.on_wrench(wrench(0.012, 3.0), arrival=0.012) and dut.reason == "joint_count"
    assert dut.on_joint(joint(0.012), arrival=0.012)
    assert dut.on_wrench(wrench(0.013, 3.0), arrival=0.013) and not dut.fault
    assert dut.received == {"ft": 7, "joint": 3}
    assert dut.accepted == {"ft": 4, "joint": 2}
    assert dut.rejected == {"out_of_order": 1, "duplicate": 1, "not_finite": 1,
                            "joint_count": 1}


def test_stale_joint_state_faults_wrench(dut):
    assert not dut.on_wrench(wrench(0.030), arrival=0.030)
    assert dut.fault and dut.reason == "joint_timeout"
    assert dut.on_joint(joint(0.030), arrival=0.030)
    assert dut.on_wrench(wrench(0.031), arrival=0.031) and not dut.fault


def test_unstamped_messages_are_named_with_the_fix():
    """A driver that leaves the stamp at 0 (a hand-made publisher, a driver that does not
    stamp): the second message is a duplicate, and the fault says the messages carry no
    stamp and how to give them one; a repeated real stamp says only that."""
    dut = StreamMonitor(N, sensor_timeout_s=0.005, joint_state_timeout_s=0.02)
    assert dut.on_joint(joint(0.0), arrival=0.0) and dut.on_wrench(wrench(0.0), arrival=0.0)
    assert not dut.on_wrench(wrench(0.0), arrival=0.001) and dut.reason == "duplicate"
    assert "F/T messages are not stamped" in dut.detail and "Fix: have the driver" in dut.detail
    assert "header.stamp" in dut.detail
    assert not dut.on_joint(joint(0.0), arrival=0.001) and dut.reason == "duplicate"
    assert dut.detail.startswith("joint state messages are not stamped")
    assert dut.on_wrench(wrench(0.002), arrival=0.002) is False  # the joint state is stale
    assert dut.on_joint(joint(0.002), arrival=0.002) and dut.on_wrench(wrench(0.003), 0.003)
    assert not dut.on_wrench(wrench(0.003), arrival=0.004)
    assert dut.detail == "F/T message with the same timestamp 0.003000 s again"
