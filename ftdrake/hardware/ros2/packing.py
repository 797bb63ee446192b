"""Packed writes of the ROS 2 station's per-sample outputs: ``WrenchStamped``, ``Bool`` and
``Float64`` in plain CDR (XCDR1, little-endian, as ftdrake's writers send), each packed in
one ``struct`` call from a template and handed to Cyclone's write, instead of an IDL object
built and then serialised field by field by cyclonedds' Python serialiser (per output and
F/T sample; most of the station's CPU per message on a small machine).

The bytes are the ones ``DataWriter.write`` sends for the same message: each packer
compares its bytes with cyclonedds' own serialisation of two probe messages when it is
made and, if they differ (another cyclonedds, another layout), writes through
``DataWriter.write`` instead (``packed`` False). ``tests/hardware/ros2/test_ros2_packing.py``
checks the bytes on random messages.
"""

from __future__ import annotations

import struct

from .messages import header, ros2_type, wrench_stamped

try:  # the C call DataWriter.write makes with the serialised bytes
    from cyclonedds._clayer import ddspy_write
except ImportError:  # pragma: no cover (another cyclonedds: the plain writes)
    ddspy_write = None

_PROBES = ((1.5, (0.0, 1.0, -2.5, 3.25, 1e-300, -7.0)), (1234.000000001, (9.0, -1.0, 2.0,
                                                                         -3.0, 4.5, 6e10)))


def _official(sample, writer) -> bytes:
    """What DataWriter.write sends for `sample` (its serialisation padded to 4 bytes)."""
    ser = sample.serialize(use_version_2=getattr(writer, "_use_version_2", False))
    return ser.ljust((len(ser) + 3) & ~3, b"\0")


def _write(writer, data: bytes) -> None:
    from cyclonedds.core import DDSException  # noqa: PLC0415 (cyclonedds only for ROS 2)

    ret = ddspy_write(writer._ref, data)
    if ret < 0:
        raise DDSException(ret, f"Occurred while writing sample in {writer!r}")


class WrenchWriter:
    """Writes ``geometry_msgs/msg/WrenchStamped`` messages on `writer` (a DataWriter of
    that type): :meth:`write` (sec, nanosec, frame_id, [Fx Fy Fz Tx Ty Tz])."""

    def __init__(self, writer):
        self.writer = writer
        self._structs: dict[str, struct.Struct | None] = {}  # frame_id → its packing

    def _struct(self, frame_id: str):
        """The packing of messages in `frame_id` (None: the plain write), checked on the
        probes."""
        template = _official(wrench_stamped(header(0.0, frame_id), [0.0] * 6), self.writer)
        middle = template[12:-48]  # the frame_id string and the padding before the doubles
        packing = struct.Struct(f"<4siI{len(middle)}s6d")
        for t, wrench in _PROBES:
            h = header(t, frame_id)
            packed = packing.pack(template[:4], h.stamp.sec, h.stamp.nanosec, middle, *wrench)
            if ddspy_write is None or packed != _official(wrench_stamped(h, wrench),
                                                          self.writer):
                return None
        return (packing, template[:4], middle)

    @property
    def packed(self) -> bool:
        """Whether the messages in the frames written so far go out packed."""
        return all(s is not None for s in self._structs.values())

    def write(self, sec: int, nanosec: int, frame_id: str, wrench) -> None:
        if frame_id not in self._structs:
            self._structs[frame_id] = self._struct(frame_id)
        packing = self._structs[frame_id]
        if packing is None:
            h = ros2_type("std_msgs/msg/Header")(
                stamp=ros2_type("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec),
                frame_id=frame_id)
            self.writer.write(wrench_stamped(h, wrench))
            return
        layout, head, middle = packing
        _write(self.writer, layout.pack(head, sec, nanosec, middle, *wrench))


#: ValueWriter's kinds: (ROS 2 type, packing, probe values).
_VALUE_TYPES = {"bool": ("std_msgs/msg/Bool", "<4s?3x", (True, False)),
                "float64": ("std_msgs/msg/Float64", "<4sd", (2.5, -1e-300))}


class ValueWriter:
    """Writes ``std_msgs/msg/Bool`` (`kind` ``"bool"``) or ``std_msgs/msg/Float64``
    (``"float64"``) messages on `writer`: :meth:`write` (value)."""

    def __init__(self, writer, kind: str):
        msgtype, layout, probes = _VALUE_TYPES[kind]
        self.writer, self._type = writer, ros2_type(msgtype)
        self._cast = bool if kind == "bool" else float
        head = _official(self._type(data=probes[0]), writer)[:4]
        self._layout, self._head = struct.Struct(layout), head
        self.packed = ddspy_write is not None and all(
            self._layout.pack(head, v) == _official(self._type(data=v), writer) for v in probes)

    def write(self, value) -> None:
        value = self._cast(value)
        if self.packed:
            _write(self.writer, self._layout.pack(self._head, value))
        else:
            self.writer.write(self._type(data=value))
