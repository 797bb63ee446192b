"""The compiled path's CDR: ``JointState`` and ``WrenchStamped`` read from their bytes, and
the station's ``WrenchStamped``, ``Bool`` and ``Float64`` outputs written as bytes.

Plain little-endian CDR (XCDR1, encapsulation ``00 01``), as ROS 2's Cyclone and Fast DDS
write it; alignment counts from the end of the 4-byte encapsulation header. Every reader
returns False (or -1) for anything else (another byte order, a field that runs past the
message, counts that do not match): the compiled loop then hands the message to the Python
path (ros2/cdr.py, cyclonedds' deserialiser), which reads or refuses it with a reason. The
written bytes are those of :mod:`ftdrake.hardware.ros2.packing` (its templates' first four
bytes passed in), which checks them against cyclonedds' serialiser.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def u32(buf, at) -> int:
    return (np.int64(buf[at]) | (np.int64(buf[at + 1]) << 8) | (np.int64(buf[at + 2]) << 16)
            | (np.int64(buf[at + 3]) << 24))


@numba.njit(cache=True)
def align(at, size) -> int:
    """`at` rounded up to a multiple of `size` counted from byte 4 (the body's start)."""
    return 4 + ((at - 4 + size - 1) // size) * size


@numba.njit(cache=True)
def doubles(buf, at, out, scratch) -> None:
    """len(out) little-endian doubles from buf[at:] into out (`scratch`: 8 bytes)."""
    for i in range(len(out)):
        scratch[:] = buf[at + 8 * i:at + 8 * i + 8]
        out[i] = scratch.view(np.float64)[0]


@numba.njit(cache=True)
def stamp(buf) -> float:
    """The header's stamp in s (sec int32, nanosec uint32), as messages.from_stamp."""
    sec = u32(buf, 4)
    if sec >= 2 ** 31:
        sec -= 2 ** 32
    return float(sec) + float(u32(buf, 8)) * 1e-9


@numba.njit(cache=True)
def header_end(buf, size) -> int:
    """The offset after the std_msgs/Header (stamp, frame_id); -1 when it is not plain
    little-endian CDR or runs past `size` bytes."""
    if size < 16 or buf[0] != 0 or buf[1] != 1:
        return -1
    end = 16 + u32(buf, 12)
    return end if end <= size else -1


@numba.njit(cache=True)
def frame_is(buf, expected) -> bool:
    """Whether the header's frame_id string (with its NUL) is `expected`'s bytes (a frame's
    name and a NUL)."""
    length = u32(buf, 12)
    if length != len(expected):
        return False
    for i in range(length):
        if buf[16 + i] != expected[i]:
            return False
    return True


@numba.njit(cache=True)
def read_wrench(buf, size, wrench, scratch) -> int:
    """The 6 values of a WrenchStamped into `wrench`; the offset of the header's end (the
    outputs copy the header up to it), -1 when the message cannot be read here."""
    end = header_end(buf, size)
    if end < 0:
        return -1
    at = align(end, 8)
    if at + 48 > size:
        return -1
    doubles(buf, at, wrench, scratch)
    return end


@numba.njit(cache=True)
def read_joint_state(buf, size, names, order, x, values, scratch) -> bool:
    """q and q̇ of a JointState, into x (2n) in the model's order: True when its name list is
    byte for byte `names` (the CDR of the sequence<string> of the last names the station
    accepted, starting 4-aligned) and it carries one position and one velocity per name,
    reordered by `order` (index in the message of each model joint); `values`: scratch of
    the message's joint count."""
    end = header_end(buf, size)
    if end < 0:
        return False
    at = align(end, 4)
    if at + len(names) > size:
        return False
    for i in range(len(names)):
        if buf[at + i] != names[i]:
            return False
    count = u32(buf, at)
    at += len(names)
    n = len(order)
    for part in range(2):  # position, velocity
        at = align(at, 4)
        if at + 4 > size or u32(buf, at) != count:
            return False
        at = align(at + 4, 8)
        if at + 8 * count > size:
            return False
        doubles(buf, at, values, scratch)
        for j in range(n):
            x[part * n + j] = values[order[j]]
        at += 8 * count
    return True


@numba.njit(cache=True)
def wrench_bytes(out, head, data, end, values, scratch) -> int:
    """A WrenchStamped: `head` (the writer's 4 encapsulation bytes), the input's header
    (data[4:end]: stamp and frame_id), zero padding, `values` (6); its size."""
    out[:4] = head
    out[4:end] = data[4:end]
    at = align(end, 8)
    out[end:at] = 0
    for i in range(6):
        scratch.view(np.float64)[0] = values[i]
        out[at + 8 * i:at + 8 * i + 8] = scratch
    return at + 48


@numba.njit(cache=True)
def bool_bytes(out, head, value) -> int:
    """A std_msgs/Bool (padded to 8 bytes, as packing.ValueWriter); its size."""
    out[:4] = head
    out[4:8] = 0
    out[4] = 1 if value > 0.5 else 0
    return 8


@numba.njit(cache=True)
def float64_bytes(out, head, value, scratch) -> int:
    """A std_msgs/Float64; its size."""
    out[:4] = head
    scratch.view(np.float64)[0] = value
    out[4:12] = scratch
    return 12


def names_cdr(names) -> np.ndarray:
    """The CDR bytes of a sequence<string> of `names` starting 4-aligned: its count, then
    each string's length (with the NUL), bytes and NUL, padded to 4 before the next
    length; what :func:`read_joint_state` compares a message's names with."""
    out = bytearray(len(names).to_bytes(4, "little"))
    for name in names:
        while len(out) % 4:
            out.append(0)
        encoded = name.encode("utf-8") + b"\0"
        out += len(encoded).to_bytes(4, "little") + encoded
    return np.frombuffer(bytes(out), dtype=np.uint8).copy()
