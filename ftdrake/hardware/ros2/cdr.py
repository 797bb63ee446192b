"""The ROS 2 station's inputs read straight from their CDR bytes: ``JointState`` and
``WrenchStamped`` unpacked with ``struct`` into light views, instead of cyclonedds'
Python deserialiser building an IDL object field by field for every message (for the
joint state, its list of names too: a name list equal to the previous message's bytes is
reused).

Plain CDR (XCDR1) in either byte order, as ROS 2's Cyclone and Fast DDS write it; the
alignment of each field counts from the end of the 4-byte encapsulation header. Any other
encapsulation (XCDR2) returns None: the caller then uses cyclonedds' deserialiser. The views
have the attributes the station reads (``header.stamp.sec``/``nanosec``,
``header.frame_id``, ``name``, ``position``, ``velocity``, ``effort``,
``wrench.force.x`` ...); ``tests/hardware/ros2/test_ros2_cdr.py`` compares them with
cyclonedds' objects.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np

#: Encapsulation identifiers of plain CDR: big- and little-endian.
_CDR_BE, _CDR_LE = b"\x00\x00", b"\x00\x01"


class Stamp(NamedTuple):
    sec: int
    nanosec: int


class Header(NamedTuple):
    stamp: Stamp
    frame_id: str


class Vector3(NamedTuple):
    x: float
    y: float
    z: float


class Wrench(NamedTuple):
    force: Vector3
    torque: Vector3


class WrenchStampedView(NamedTuple):
    """A ``geometry_msgs/msg/WrenchStamped`` as read from its bytes."""

    header: Header
    wrench: Wrench


class JointStateView(NamedTuple):
    """A ``sensor_msgs/msg/JointState`` as read from its bytes (arrays of float)."""

    header: Header
    name: list
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


class _Reader:
    """Reads fields of one message; `order` "<" or ">"."""

    __slots__ = ("data", "order", "pos")

    def __init__(self, data: bytes, order: str):
        self.data, self.order, self.pos = data, order, 4

    def align(self, size: int) -> None:
        self.pos += -(self.pos - 4) % size

    def uint32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from(self.order + "I", self.data, self.pos)
        self.pos += 4
        return value

    def string(self) -> str:
        length = self.uint32()
        if length == 0 or self.pos + length > len(self.data) or \
                self.data[self.pos + length - 1] != 0:
            raise struct.error("CDR string without its terminating NUL")
        text = self.data[self.pos:self.pos + length - 1].decode()
        self.pos += length
        return text

    def header(self) -> Header:
        self.align(4)
        sec, nanosec = struct.unpack_from(self.order + "iI", self.data, self.pos)
        self.pos += 8
        return Header(Stamp(sec, nanosec), self.string())

    def doubles(self, count: int) -> np.ndarray:
        if count:
            self.align(8)
        end = self.pos + 8 * count
        if end > len(self.data):
            raise struct.error("CDR sequence longer than the message")
        values = np.frombuffer(self.data, self.order + "f8", count, self.pos).astype(float)
        self.pos = end
        return values


def _reader(data: bytes) -> _Reader | None:
    kind = bytes(data[:2])
    if kind == _CDR_LE:
        return _Reader(data, "<")
    if kind == _CDR_BE:
        return _Reader(data, ">")
    return None


def wrench_stamped(data: bytes) -> WrenchStampedView | None:
    """The WrenchStamped in `data` (None: not plain CDR); struct.error when truncated."""
    r = _reader(data)
    if r is None:
        return None
    head = r.header()
    r.align(8)
    f = struct.unpack_from(r.order + "6d", data, r.pos)
    return WrenchStampedView(head, Wrench(Vector3(*f[:3]), Vector3(*f[3:])))


class JointStateReader:
    """Reads JointState bytes (:meth:`read`), keeping the last message's names."""

    def __init__(self):
        self._names: tuple[bytes, list] = (b"", [])

    def read(self, data: bytes) -> JointStateView | None:
        """The JointState in `data` (None: not plain CDR); struct.error when malformed."""
        r = _reader(data)
        if r is None:
            return None
        head = r.header()
        count = r.uint32()
        start = r.pos
        for _ in range(count):  # skip the names: the same bytes as last time, the same names
            length = r.uint32()
            r.pos += length
        raw = bytes(data[start:r.pos])
        if raw != self._names[0]:
            r.pos = start
            self._names = (raw, [r.string() for _ in range(count)])
        names = list(self._names[1])
        position = r.doubles(r.uint32())
        velocity = r.doubles(r.uint32())
        effort = r.doubles(r.uint32())
        return JointStateView(head, names, position, velocity, effort)
