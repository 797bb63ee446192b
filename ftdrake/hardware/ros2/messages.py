"""ROS 2 message types for Cyclone DDS, generated from ROS 2's own message definitions.

The definitions come from `rosbags`' type store (``Stores.LATEST``: the ``.msg`` files of the
ROS 2 distributions, parsed by rosbags); nothing here spells a field by hand. Each ROS 2 type
``pkg/msg/Name`` becomes a Cyclone DDS ``IdlStruct`` named as ROS 2 names it on DDS
(``pkg::msg::dds_::Name_``, the mapping of the ros2/design article "Topic and Service name
mapping to DDS"), with the fields in their declared order and types (``byte`` → octet,
``char`` → uint8, ``string<=N>`` → bounded string, ``T[N]`` → array, ``T[]``/``T[<=N]`` →
sequence), so Cyclone serialises it as ROS 2's middleware does: XCDR1 (plain CDR) with the
4-byte encapsulation header. ``tests/hardware/ros2/test_ros2_messages.py`` checks the bytes against
rosbags' own CDR serialiser.

:func:`ros2_type` returns the generated class (cached); :data:`TYPES` names the ones ftdrake
uses. Stamps: :func:`to_stamp` / :func:`from_stamp` convert between seconds and
``builtin_interfaces/msg/Time``.
"""

from __future__ import annotations

import functools
import math

#: The ROS 2 message types ftdrake reads and writes.
TYPES = (
    "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/WrenchStamped",
    "sensor_msgs/msg/Temperature",
    "sensor_msgs/msg/Imu",
    "std_msgs/msg/Bool",
    "std_msgs/msg/Empty",
    "std_msgs/msg/Float64",
    "geometry_msgs/msg/InertiaStamped",
    "diagnostic_msgs/msg/DiagnosticArray",
)


@functools.cache
def typestore():
    """rosbags' type store of the latest ROS 2 distribution it knows."""
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415 (ROS 2 only)

    return get_typestore(Stores.LATEST)


def dds_type_name(msgtype: str) -> str:
    """``pkg/msg/Name`` → ``pkg::msg::dds_::Name_`` (ROS 2's DDS type name)."""
    pkg, kind, name = _split(msgtype)
    return f"{pkg}::{kind}::dds_::{name}_"


def _split(msgtype: str) -> tuple[str, str, str]:
    parts = msgtype.split("/")
    if len(parts) != 3:
        raise ValueError(f"{msgtype!r} is not a ROS 2 type name like 'sensor_msgs/msg/JointState'")
    return parts[0], parts[1], parts[2]


def _base(name: str, bound: int):
    from cyclonedds.idl import types  # noqa: PLC0415 (cyclonedds only for ROS 2)

    if name == "string":
        return types.bounded_str[bound] if bound else str
    if name == "wstring":
        raise TypeError("wstring fields are not supported (no ROS 2 type ftdrake uses has one)")
    table = {"bool": bool, "byte": types.byte, "char": types.uint8, "int8": types.int8,
             "uint8": types.uint8, "int16": types.int16, "uint16": types.uint16,
             "int32": types.int32, "uint32": types.uint32, "int64": types.int64,
             "uint64": types.uint64, "float32": types.float32, "float64": types.float64}
    return table[name]


def _field_type(node):
    from cyclonedds.idl import types  # noqa: PLC0415 (cyclonedds only for ROS 2)
    try:
        from rosbags.interfaces import Nodetype  # noqa: PLC0415 (as above)
    except ImportError:  # rosbags < 0.11 kept it with the type system
        from rosbags.typesys.base import Nodetype  # noqa: PLC0415 (as above)

    kind, detail = node
    if kind == Nodetype.BASE:
        return _base(*detail)
    if kind == Nodetype.NAME:
        return ros2_type(detail)
    element, size = detail
    element = _field_type(element)
    if kind == Nodetype.ARRAY:
        return types.array[element, size]
    if kind == Nodetype.SEQUENCE:
        return types.sequence[element, size] if size else types.sequence[element]
    raise TypeError(f"unknown rosbags node type {kind!r}")


@functools.cache
def ros2_type(msgtype: str):
    """The Cyclone DDS ``IdlStruct`` class of the ROS 2 message type `msgtype`
    (``pkg/msg/Name``), generated from rosbags' definition of it."""
    from cyclonedds.idl import make_idl_struct  # noqa: PLC0415 (cyclonedds only for ROS 2)

    store = typestore()
    if msgtype not in store.fielddefs:
        raise KeyError(f"{msgtype!r}: not a ROS 2 message type rosbags knows")
    _, fields = store.fielddefs[msgtype]
    return make_idl_struct(_split(msgtype)[2] + "_", dds_type_name(msgtype),
                           {name: _field_type(node) for name, node in fields})


def to_stamp(t: float):
    """Seconds → ``builtin_interfaces/msg/Time`` (sec, nanosec ∈ [0, 1e9))."""
    ns = round(t * 1e9)
    sec, nanosec = divmod(ns, 1_000_000_000)
    return ros2_type("builtin_interfaces/msg/Time")(sec=int(sec), nanosec=int(nanosec))


def from_stamp(stamp) -> float:
    """``builtin_interfaces/msg/Time`` → seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def header(t: float, frame_id: str = ""):
    """A ``std_msgs/msg/Header`` at `t` s in `frame_id`."""
    return ros2_type("std_msgs/msg/Header")(stamp=to_stamp(t), frame_id=frame_id)


def wrench_stamped(header_, wrench):
    """A ``geometry_msgs/msg/WrenchStamped`` with `header_` and the wrench [F; τ] (6)."""
    vector = ros2_type("geometry_msgs/msg/Vector3")
    f, m = [float(x) for x in wrench[:3]], [float(x) for x in wrench[3:6]]
    return ros2_type("geometry_msgs/msg/WrenchStamped")(
        header=header_, wrench=ros2_type("geometry_msgs/msg/Wrench")(
            force=vector(*f), torque=vector(*m)))


def wrench_of(msg) -> list[float]:
    """[Fx, Fy, Fz, τx, τy, τz] of a ``geometry_msgs/msg/WrenchStamped``."""
    f, m = msg.wrench.force, msg.wrench.torque
    return [f.x, f.y, f.z, m.x, m.y, m.z]


def is_finite_stamp(stamp) -> bool:
    return math.isfinite(stamp.sec) and math.isfinite(stamp.nanosec)
