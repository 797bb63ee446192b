"""The LCM messages the compiled loop reads and writes, in compiled code: the same bytes as
:mod:`ftdrake.hardware.messages` (lcm-gen's layouts: big-endian, an 8-byte type
fingerprint first; times as int64 µs, decoded as ``utime * 1e-6`` s and encoded as
``round(t * 1e6)``, half to even, as Python's ``round``).

* ``drake.lcmt_force_torque``: fingerprint, ``timestamp``, ``fx fy fz tx ty tz`` (N, N·m).
* ``drake.lcmt_iiwa_status``: fingerprint, ``utime``, int32 ``num_joints``, then seven
  arrays of ``num_joints`` doubles, the first two ``joint_position_measured`` (rad) and
  ``joint_velocity_estimated`` (rad/s).
* The contact state (``drake.lcmt_drake_signal``, :func:`~ftdrake.hardware.messages.
  encode_contact_state`): a template's bytes with its five values and its timestamp
  written in.

A reader returns False for bytes it does not read (another fingerprint, cut short, another
joint count): the loop then hands the message to the station's Python path, which says why.
"""

from __future__ import annotations

import numba
import numpy as np

#: Bytes of an lcmt_force_torque message; of lcmt_iiwa_status's head (before its arrays).
WRENCH_BYTES, IIWA_HEAD = 64, 20
IIWA_ARRAYS = 7
#: Where the contact state's values start in its bytes (after fingerprint and dim).
CONTACT_VALUES = 12


@numba.njit(cache=True)
def _reversed8(data, o, scratch) -> None:
    for i in range(8):
        scratch[i] = data[o + 7 - i]


@numba.njit(cache=True)
def read_f64(data, o, scratch) -> float:
    _reversed8(data, o, scratch)
    return scratch.view(np.float64)[0]


@numba.njit(cache=True)
def read_i64(data, o, scratch) -> int:
    _reversed8(data, o, scratch)
    return scratch.view(np.int64)[0]


@numba.njit(cache=True)
def read_i32(data, o) -> int:
    value = (np.int64(data[o]) << 24) | (np.int64(data[o + 1]) << 16) | (
        np.int64(data[o + 2]) << 8) | np.int64(data[o + 3])
    return value - (np.int64(1) << 32) if value >= (np.int64(1) << 31) else value


@numba.njit(cache=True)
def write_f64(out, o, value, scratch) -> None:
    scratch.view(np.float64)[0] = value
    for i in range(8):
        out[o + i] = scratch[7 - i]


@numba.njit(cache=True)
def write_i64(out, o, value, scratch) -> None:
    scratch.view(np.int64)[0] = value
    for i in range(8):
        out[o + i] = scratch[7 - i]


@numba.njit(cache=True)
def _is(data, fingerprint) -> bool:
    for i in range(8):
        if data[i] != fingerprint[i]:
            return False
    return True


@numba.njit(cache=True)
def read_wrench(data, size, fingerprint, wrench, scratch):
    """(read, t s): an lcmt_force_torque's timestamp and [Fx Fy Fz Tx Ty Tz] into
    `wrench`."""
    if size < WRENCH_BYTES or not _is(data, fingerprint):
        return False, 0.0
    t = np.float64(read_i64(data, 8, scratch)) * 1e-6
    for i in range(6):
        wrench[i] = read_f64(data, 16 + 8 * i, scratch)
    return True, t


@numba.njit(cache=True)
def read_iiwa_status(data, size, fingerprint, x, scratch):
    """(read, t s): an lcmt_iiwa_status of len(x) / 2 joints, ``[q; v]`` into `x`."""
    n = len(x) // 2
    if size < IIWA_HEAD or not _is(data, fingerprint) or read_i32(data, 16) != n:
        return False, 0.0
    if size < IIWA_HEAD + IIWA_ARRAYS * 8 * n:
        return False, 0.0
    t = np.float64(read_i64(data, 8, scratch)) * 1e-6
    for j in range(2 * n):
        x[j] = read_f64(data, IIWA_HEAD + 8 * j, scratch)
    return True, t


@numba.njit(cache=True)
def utime(t) -> int:
    """int64 µs of `t` s: round(t * 1e6), half to even (Python's round)."""
    return np.int64(np.rint(t * 1e6))


@numba.njit(cache=True)
def wrench_bytes(out, fingerprint, t, wrench, scratch) -> int:
    """An lcmt_force_torque of `wrench` at `t` into `out`; its size."""
    out[:8] = fingerprint
    write_i64(out, 8, utime(t), scratch)
    for i in range(6):
        write_f64(out, 16 + 8 * i, wrench[i], scratch)
    return WRENCH_BYTES


@numba.njit(cache=True)
def contact_bytes(out, template, t, values, scratch) -> int:
    """The contact state: `template`'s bytes with `values` (contact, ‖F‖, fault,
    out_of_domain, payload_change) and `t` written in, into `out`; its size."""
    size = len(template)
    out[:size] = template
    for i in range(len(values)):
        write_f64(out, CONTACT_VALUES + 8 * i, values[i], scratch)
    write_i64(out, size - 8, utime(t), scratch)
    return size
