"""The ROS 2 message types ftdrake puts on DDS: the bytes Cyclone DDS writes for each equal
rosbags' CDR serialisation of the same ROS 2 message (an independent implementation of ROS 2's
types and encoding), and rosbags' bytes read back as the same message. Also ROS 2's DDS names
of topics and types."""

import math

import numpy as np
import pytest

pytest.importorskip("cyclonedds")
from rosbags.interfaces import Nodetype

from ftdrake.errors import ConfigError
from ftdrake.hardware.ros2 import dds
from ftdrake.hardware.ros2.messages import (
    TYPES,
    dds_type_name,
    from_stamp,
    ros2_type,
    to_stamp,
    typestore,
)

NUMPY = {"float64": np.float64, "float32": np.float32, "uint8": np.uint8, "int8": np.int8,
         "byte": np.uint8, "char": np.uint8, "int32": np.int32, "uint32": np.uint32,
         "int64": np.int64, "uint64": np.uint64, "int16": np.int16, "uint16": np.uint16}


def build(msgtype, value, side):
    """`value` (nested dicts and lists) as a rosbags message (side "rosbags") or a Cyclone
    IdlStruct (side "dds")."""
    _, fields = typestore().fielddefs[msgtype]
    kwargs = {}
    for name, (kind, detail) in fields:
        v = value[name]
        if kind == Nodetype.NAME:
            kwargs[name] = build(detail, v, side)
        elif kind == Nodetype.BASE:
            kwargs[name] = v
        else:
            (ekind, edetail), _ = detail
            if ekind == Nodetype.NAME:
                kwargs[name] = [build(edetail, e, side) for e in v]
            elif edetail[0] == "string" or side == "dds":
                kwargs[name] = list(v)
            else:
                kwargs[name] = np.array(v, dtype=NUMPY[edetail[0]])
    cls = typestore().types[msgtype] if side == "rosbags" else ros2_type(msgtype)
    return cls(**kwargs)


def header(sec, nanosec, frame):
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame}


def vec(x, y, z):
    return {"x": x, "y": y, "z": z}


def status(level, name, message, values):
    return {"level": level, "name": name, "message": message, "hardware_id": "ft-1",
            "values": [{"key": k, "value": v} for k, v in values]}


SAMPLES = {
    "sensor_msgs/msg/JointState": [
        {"header": header(0, 0, ""), "name": [], "position": [], "velocity": [], "effort": []},
        {"header": header(1_700_000_000, 123_456_789, "base_link"),
         "name": ["shoulder_pan_joint", "Gelenk_ä", "関節_3"], "position": [0.1, -2.5, 3.0],
         "velocity": [1e-9, -0.0, 7.25], "effort": []},
        {"header": header(-3, 999_999_999, "wrist_3_link"), "name": ["a"],
         "position": [math.pi], "velocity": [], "effort": [-1e300]},
    ],
    "geometry_msgs/msg/WrenchStamped": [
        {"header": header(12, 500, "tool0"),
         "wrench": {"force": vec(1.5, -2.0, 9.81), "torque": vec(0.0, 1e-6, -0.25)}},
        {"header": header(0, 0, "Kraftsensor_ü"),
         "wrench": {"force": vec(math.inf, -math.inf, 0.0), "torque": vec(-0.0, 3.0, 4.0)}},
    ],
    "sensor_msgs/msg/Temperature": [
        {"header": header(5, 6, "ft_sensor"), "temperature": 31.25, "variance": 0.0}],
    "sensor_msgs/msg/Imu": [
        {"header": header(9, 10, "ft_sensor"),
         "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
         "orientation_covariance": [-1.0] + [0.0] * 8,
         "angular_velocity": vec(0.1, -0.2, 0.3), "angular_velocity_covariance": [0.0] * 9,
         "linear_acceleration": vec(0.5, -1.0, 9.81),
         "linear_acceleration_covariance": [1e-4] * 9}],
    "std_msgs/msg/Bool": [{"data": True}, {"data": False}],
    "std_msgs/msg/Empty": [{"structure_needs_at_least_one_member": 0}],
    "std_msgs/msg/Float64": [{"data": 17.5}, {"data": -0.0}],
    "geometry_msgs/msg/InertiaStamped": [
        {"header": header(3, 4, "tool0"),
         "inertia": {"m": 0.35, "com": vec(0.0, 0.01, 0.08), "ixx": 0.0, "ixy": 0.0,
                     "ixz": 0.0, "iyy": 0.0, "iyz": 0.0, "izz": 0.0}}],
    "diagnostic_msgs/msg/DiagnosticArray": [
        {"header": header(7, 8, ""), "status": []},
        {"header": header(7, 9, ""), "status": [
            status(0, "ftdrake: compensation", "ok", [("fault", "false"), ("rate_ft_hz", "500")]),
            status(2, "ftdrake: Eingänge", "fault not_finite: NaN ✗", []),
            status(1, "x", "", [("out_of_domain", "true")])]},
    ],
}


def test_every_type_has_samples():
    assert set(SAMPLES) == set(TYPES)


@pytest.mark.parametrize("msgtype", TYPES)
def test_wire_bytes_equal_rosbags_cdr(msgtype):
    node = dds.Ros2Node(domain_id=dds_domain())
    writer = node.publisher("/ftdrake_test/" + msgtype.split("/")[-1].lower(), msgtype)
    # What DataWriter.write puts on the wire: sample.serialize(use_version_2=<its QoS>).
    assert writer._use_version_2 is False  # XCDR1: plain CDR, as ROS 2 writes
    for value in SAMPLES[msgtype]:
        ours = build(msgtype, value, "dds").serialize(use_version_2=writer._use_version_2)
        theirs = bytes(typestore().serialize_cdr(build(msgtype, value, "rosbags"), msgtype))
        assert ours == theirs, (msgtype, value)
        assert ours[:2] == b"\x00\x01"  # CDR_LE encapsulation
        assert ros2_type(msgtype).deserialize(theirs) == build(msgtype, value, "dds")


def dds_domain():
    import os

    return 100 + os.getpid() % 100


def test_a_wrong_field_type_would_change_the_bytes():
    """The comparison above can fail: Time with nanosec as int64 instead of uint32."""
    from cyclonedds.idl import make_idl_struct, types

    bad = make_idl_struct("Time_", "builtin_interfaces::msg::dds_::Time_",
                          {"sec": types.int32, "nanosec": types.int64})
    theirs = bytes(typestore().serialize_cdr(
        build("builtin_interfaces/msg/Time", {"sec": 1, "nanosec": 2}, "rosbags"),
        "builtin_interfaces/msg/Time"))
    assert bad(sec=1, nanosec=2).serialize(use_version_2=False) != theirs


def test_names_follow_the_ros2_dds_mapping():
    assert dds_type_name("sensor_msgs/msg/JointState") == "sensor_msgs::msg::dds_::JointState_"
    assert ros2_type("geometry_msgs/msg/WrenchStamped").__idl_typename__ == \
        "geometry_msgs::msg::dds_::WrenchStamped_"
    assert dds.dds_topic("/joint_states") == "rt/joint_states"
    assert dds.dds_topic("/force_torque_sensor_broadcaster/wrench") == \
        "rt/force_torque_sensor_broadcaster/wrench"
    for bad in ("", "/a b", "/9x", "a//b"):
        with pytest.raises(ConfigError, match="not a ROS 2 topic name"):
            dds.dds_topic(bad)


@pytest.mark.parametrize("t", [0.0, 1.5, 1_700_000_000.123456789, 2.999999999])
def test_stamps(t):
    stamp = to_stamp(t)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert from_stamp(stamp) == pytest.approx(t, abs=1e-9 * max(1.0, abs(t)) * 4)
