"""The ROS 2 station's packed writes: the bytes of each WrenchStamped, Bool and Float64 are
cyclonedds' own serialisation of the same message (what DataWriter.write sends), and what a
reader takes from them is the message written."""

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from ftdrake.hardware.ros2 import packing
from ftdrake.hardware.ros2.dds import Ros2Node
from ftdrake.hardware.ros2.messages import (
    from_stamp,
    header,
    ros2_type,
    wrench_of,
    wrench_stamped,
)


@pytest.fixture
def sent(monkeypatch):
    """The bytes the packers hand to Cyclone, kept (and written)."""
    out = []
    write = packing.ddspy_write

    def keep(ref, data):
        out.append(data)
        return write(ref, data)

    monkeypatch.setattr(packing, "ddspy_write", keep)
    return out


def test_packed_bytes_are_cyclonedds_own(sent):
    rng = np.random.default_rng(5)
    node = Ros2Node(227)
    try:
        wrenches = packing.WrenchWriter(node.publisher("/w", "geometry_msgs/msg/WrenchStamped"))
        flags = packing.ValueWriter(node.publisher("/c", "std_msgs/msg/Bool"), "bool")
        forces = packing.ValueWriter(node.publisher("/f", "std_msgs/msg/Float64"), "float64")
        assert flags.packed and forces.packed
        for k in range(40):
            frame = ("ft_sensor", "", "tool0_controller", "x" * (k % 7))[k % 4]
            h = header(float(rng.uniform(0, 2e9)), frame)
            w = (rng.normal(size=6) * 10.0 ** rng.integers(-5, 5)).tolist()
            wrenches.write(h.stamp.sec, h.stamp.nanosec, frame, w)
            assert sent[-1] == packing._official(wrench_stamped(h, w), wrenches.writer)
            flags.write(k % 3 == 0)
            assert sent[-1] == packing._official(ros2_type("std_msgs/msg/Bool")(data=k % 3 == 0),
                                                 flags.writer)
            forces.write(w[0])
            assert sent[-1] == packing._official(ros2_type("std_msgs/msg/Float64")(data=w[0]),
                                                 forces.writer)
        assert wrenches.packed
    finally:
        node.close()


def test_a_reader_takes_the_message_written():
    node = Ros2Node(226)
    got = []
    try:
        node.subscribe("/w", "geometry_msgs/msg/WrenchStamped", lambda m, _a: got.append(m))
        wrenches = packing.WrenchWriter(node.publisher("/w", "geometry_msgs/msg/WrenchStamped"))
        h = header(12.25, "ft_sensor")
        wrenches.write(h.stamp.sec, h.stamp.nanosec, "ft_sensor", [1.0, 2, 3, 4, 5, 6.5])
        for _ in range(200):
            if node.spin(10):
                break
        assert len(got) == 1 and from_stamp(got[0].header.stamp) == 12.25
        assert got[0].header.frame_id == "ft_sensor"
        assert wrench_of(got[0]) == [1.0, 2, 3, 4, 5, 6.5]
    finally:
        node.close()
