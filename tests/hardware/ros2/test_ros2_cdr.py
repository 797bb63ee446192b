"""The ROS 2 station's inputs read from their CDR bytes (ros2/cdr.py) against cyclonedds'
deserialiser: the same stamp, frame, names and numbers for random JointState and
WrenchStamped messages; another encapsulation left to cyclonedds; a
truncated message an error."""

import struct

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from ftdrake.hardware.ros2 import cdr
from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_of, wrench_stamped

JointState = ros2_type("sensor_msgs/msg/JointState")


def joint_states(rng):
    for k in range(60):
        n = int(rng.integers(0, 9))
        names = [("joint_" * int(rng.integers(0, 3))) + str(j) * (k % 5) + "é" * (j % 2)
                 for j in range(n)]
        velocity = rng.normal(size=n).tolist() if k % 3 else []
        effort = rng.normal(size=n).tolist() if k % 4 else []
        yield JointState(header=header(float(rng.uniform(0, 2e9)), "base" * (k % 3)),
                         name=names, position=rng.normal(size=n).tolist(), velocity=velocity,
                         effort=effort)


def test_joint_state_as_cyclonedds_reads_it():
    rng = np.random.default_rng(7)
    reader = cdr.JointStateReader()
    for msg in [*joint_states(rng), *joint_states(np.random.default_rng(7))]:  # names again
        data = msg.serialize(use_version_2=False)
        ref, got = JointState.deserialize(data), reader.read(data)
        assert got.header.stamp == (ref.header.stamp.sec, ref.header.stamp.nanosec)
        assert got.header.frame_id == ref.header.frame_id
        assert got.name == list(ref.name)
        for field in ("position", "velocity", "effort"):
            assert np.array_equal(getattr(got, field), np.asarray(getattr(ref, field), float))


def test_wrench_stamped_as_cyclonedds_reads_it():
    rng = np.random.default_rng(8)
    for k in range(60):
        msg = wrench_stamped(header(float(rng.uniform(0, 2e9)), "ft" * (k % 4)),
                             rng.normal(size=6) * 10.0 ** rng.integers(-8, 8))
        data = msg.serialize(use_version_2=False)
        got = cdr.wrench_stamped(data)
        assert got.header.stamp == (msg.header.stamp.sec, msg.header.stamp.nanosec)
        assert got.header.frame_id == msg.header.frame_id
        assert wrench_of(got) == wrench_of(msg)


def test_another_encapsulation_is_left_to_cyclonedds_and_truncation_is_an_error():
    msg = wrench_stamped(header(1.0, "ft"), np.ones(6))
    assert cdr.wrench_stamped(msg.serialize(use_version_2=True)) is None  # XCDR2
    assert cdr.JointStateReader().read(b"\x00\x07\x00\x00" + bytes(40)) is None
    with pytest.raises(struct.error):
        cdr.wrench_stamped(msg.serialize(use_version_2=False)[:-9])
    data = JointState(header=header(1.0, "b"), name=["a", "b"], position=[1.0, 2.0],
                      velocity=[], effort=[]).serialize(use_version_2=False)
    with pytest.raises(struct.error):
        cdr.JointStateReader().read(data[:-9])
