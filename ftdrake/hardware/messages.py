"""Decoding robot LCM messages into arrays, and encoding what the station publishes.

Units and conventions (one place):

* Time: LCM ``utime`` / ``timestamp`` fields are int64 microseconds; decoded ``t`` is in s
  (``utime · 1e-6``). Encoding rounds to the nearest µs.
* Joint state: q in rad, v in rad/s, measured joint torque in N·m, in the robot's joint
  order. iiwa/panda status carry float64; ``lcmt_robot_state`` carries float32 positions
  (≈ 1e-7 relative resolution).
* Wrench: ``[Fx, Fy, Fz, Tx, Ty, Tz]`` in N and N·m — ``lcmt_force_torque``'s
  ``fx fy fz tx ty tz`` in that order. As in ftdrake's conventions (README "Conventions"),
  the reading is the load the tool side applies to the sensor, about the sensor origin So,
  expressed in the sensor frame S; the published wrenches (``wrench_contact``,
  ``wrench_compensated``, ``bias``; :data:`ftdrake.conventions.CHAIN_OUTPUTS`) are in the
  same frame, about the same point. No frame change or sign flip happens here.
* Contact state: ``drake.lcmt_drake_signal`` (an existing, documented Drake type: ``dim``,
  ``val[dim]``, ``coord[dim]`` names, ``timestamp`` µs) with ``coord = CONTACT_COORDS``.
* Payload estimate: ``lcmt_drake_signal`` with ``coord = PAYLOAD_COORDS`` (kg, kg·m).
* Events (optional inputs): ``lcmt_drake_signal`` with one value named ``TARE_COORD`` (the
  driver re-zeroed the sensor) or ``PAYLOAD_COORD`` (a payload was grasped or released).
* Sensor temperature (optional input): ``lcmt_drake_signal`` with one value, °C, named
  ``TEMPERATURE_COORD`` (no Drake message carries a temperature; this one names its value).
* IMU at the sensor (optional input, for a model that takes one): ``lcmt_drake_signal``
  with six values named ``IMU_COORDS``: the accelerometer's proper acceleration of So
  (m/s², +9.81 up at rest) and the gyroscope's ω (rad/s), both in S; ``timestamp`` µs is
  the sample's stamp (paired with the F/T stamp, :mod:`~ftdrake.hardware.live_imu`).

The ``drake`` message classes are plain lcm-gen Python (struct packing): decoding and
encoding need no ``lcm`` package; only the transport and log files do.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np
from drake import (
    lcmt_drake_signal,
    lcmt_force_torque,
    lcmt_iiwa_status,
    lcmt_panda_status,
    lcmt_robot_state,
)

from ..conventions import CHAIN_OUTPUTS, OUTPUTS

#: Name of the value in the temperature message (°C).
TEMPERATURE_COORD = "temperature_c"
#: Names of the values in the IMU message (:func:`encode_imu`), in order: f_S, then ω_S.
IMU_COORDS = ("acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z")
#: Names of the value in the event messages (:func:`encode_event`): the sensor was re-zeroed
#: (re-tared), or a payload was grasped or released, at the message's timestamp.
TARE_COORD = "tared"
PAYLOAD_COORD = "payload_changed"

#: Names of the values in the contact-state message, in order: the chain outputs that
#: :data:`ftdrake.conventions.CHAIN_OUTPUTS` puts in ``CONTACT_STATE`` (``contact``,
#: ``contact_force``, ``fault``, ``out_of_domain``, ``payload_change``: 1 while the chain
#: announces a payload change nobody signalled, ``bias_tracker.payload_change``).
CONTACT_COORDS = tuple(o.lcm_field for o in CHAIN_OUTPUTS if o.lcm_channel == "CONTACT_STATE")
#: The message before it carried ``payload_change``; still decoded (the flag then False).
CONTACT_COORDS_V1 = ("contact", "contact_force", "fault", "out_of_domain")
#: Names of the values in the station's status message (:func:`encode_status`, on
#: ``HardwareConfig.status_channel``): the fault flag and its reason (the index in
#: ``live_inputs.REASONS`` + 1; 0 without a fault, -1 for "no_data"), the overload flag, the
#: F/T input rate and the rate the station sustains (Hz), how far behind the stream it is
#: (ms), F/T messages lost (stamp gaps) and dropped (overload), processed and published,
#: and the station's CPU between its two last periodic statuses: % of one core and µs per
#: processed F/T message (the whole process's; NaN before the first or without a message).
STATUS_COORDS = ("fault", "reason", "overload", "input_hz", "sustained_hz", "backlog_ms",
                 "lost_ft", "dropped_ft", "processed", "published", "cpu_core_percent",
                 "cpu_us_per_message")
#: The message before it carried the CPU; still decoded (those two values then NaN).
STATUS_COORDS_V1 = STATUS_COORDS[:-2]
#: Names of the values in the payload message (:func:`encode_payload`): its log columns.
PAYLOAD_COORDS = OUTPUTS["payload"].columns

_JOINT_CLASSES = {
    "iiwa_status": lcmt_iiwa_status,
    "panda_status": lcmt_panda_status,
    "robot_state": lcmt_robot_state,
}


class JointSample(NamedTuple):
    """t (s), q (rad, n), v (rad/s, n, or None for robot_state), tau (N·m, n, or None)."""

    t: float
    q: np.ndarray
    v: np.ndarray | None
    tau: np.ndarray | None


class WrenchSample(NamedTuple):
    """t (s), wrench ``[Fx Fy Fz Tx Ty Tz]`` (N, N·m) in the sensor frame S about So."""

    t: float
    wrench: np.ndarray


class ContactState(NamedTuple):
    """t (s); the detector's flag and ‖F‖ (N); the fault and out-of-domain flags; the flag of
    a payload change nobody signalled (False without the chain's payload-change monitor)."""

    t: float
    contact: bool
    contact_force: float
    fault: bool
    out_of_domain: bool = False
    payload_change: bool = False


def message_class(joint_state_type: str):
    """The ``drake.lcmt_*`` class for a HardwareConfig.joint_state_type."""
    try:
        return _JOINT_CLASSES[joint_state_type]
    except KeyError:
        raise ValueError(f"unknown joint-state type {joint_state_type!r}; one of "
                         f"{', '.join(_JOINT_CLASSES)}") from None


def decode_joint_state(joint_state_type: str, data: bytes) -> JointSample:
    """Decodes one joint-state message. Raises ValueError on a malformed message
    (bad fingerprint or a num_joints that disagrees with the array lengths), struct.error
    on a truncated one."""
    if joint_state_type == "iiwa_status" and isinstance(data, (bytes, bytearray)):
        return _decode_iiwa_status(data)
    cls = message_class(joint_state_type)
    msg = cls.decode(data)
    t = msg.utime * 1e-6
    if joint_state_type == "iiwa_status":
        q, v, tau = (msg.joint_position_measured, msg.joint_velocity_estimated,
                     msg.joint_torque_measured)
    elif joint_state_type == "panda_status":
        q, v, tau = msg.joint_position, msg.joint_velocity, msg.joint_torque
    else:
        q, v, tau = msg.joint_position, None, None
    q = np.asarray(q, dtype=float)
    if len(q) != msg.num_joints:
        raise ValueError(f"{cls.__name__}: num_joints {msg.num_joints} but {len(q)} positions")
    v = None if v is None else np.asarray(v, dtype=float)
    tau = None if tau is None or len(tau) == 0 else np.asarray(tau, dtype=float)
    return JointSample(t, q, v, tau)


# The per-message codecs below pack and unpack the lcm-gen classes' layouts in one struct
# call each (the classes build an object and a buffer per message); the bytes are the
# classes' (tests/hardware/test_hardware_messages.py compares them).
_FT = struct.Struct(">8sqdddddd")
_FT_FINGERPRINT = lcmt_force_torque._get_packed_fingerprint()
_IIWA_HEAD = struct.Struct(">8sqi")
_IIWA_FINGERPRINT = lcmt_iiwa_status._get_packed_fingerprint()
_IIWA_ARRAYS = 7  # lcmt_iiwa_status's arrays of num_joints doubles
_IIWA_TAU = 4  # joint_torque_measured's place among them


def _decode_iiwa_status(data: bytes) -> JointSample:
    """``lcmt_iiwa_status`` bytes → (t, q = joint_position_measured, v =
    joint_velocity_estimated, τ = joint_torque_measured), as decode_joint_state."""
    fingerprint, utime, n = _IIWA_HEAD.unpack_from(data)
    if fingerprint != _IIWA_FINGERPRINT:
        raise ValueError("Decode error")
    head = _IIWA_HEAD.size
    if n < 0 or len(data) < head + _IIWA_ARRAYS * 8 * n:
        raise struct.error(f"lcmt_iiwa_status: {len(data)} bytes for {n} joints")
    values = np.frombuffer(data, ">f8", _IIWA_ARRAYS * n, head).astype(float)
    tau = values[_IIWA_TAU * n:(_IIWA_TAU + 1) * n] if n else None
    return JointSample(utime * 1e-6, values[:n], values[n:2 * n], tau)


def decode_wrench(data: bytes) -> WrenchSample:
    """Decodes ``lcmt_force_torque`` → (t s, [Fx Fy Fz Tx Ty Tz] N, N·m). Raises ValueError
    for another message type, struct.error for a truncated one."""
    fingerprint, timestamp, *wrench = _FT.unpack_from(data)
    if fingerprint != _FT_FINGERPRINT:
        raise ValueError("Decode error")
    return WrenchSample(timestamp * 1e-6, np.array(wrench, dtype=float))


def _utime(t: float) -> int:
    return round(float(t) * 1e6)


def encode_wrench(t: float, wrench) -> bytes:
    """``lcmt_force_torque`` bytes for a wrench ``[Fx Fy Fz Tx Ty Tz]`` (N, N·m) at t (s)."""
    if not (type(wrench) is np.ndarray and wrench.shape == (6,) and wrench.dtype == float):
        wrench = np.asarray(wrench, dtype=float).reshape(6)
    return _FT.pack(_FT_FINGERPRINT, _utime(t), *wrench.tolist())


def encode_contact_state(state: ContactState) -> bytes:
    """``lcmt_drake_signal`` bytes: val = [contact 0/1, ‖F‖ N, fault 0/1, out_of_domain 0/1,
    payload_change 0/1] (``CONTACT_COORDS``)."""
    return _CONTACT.pack(_SIGNAL_FINGERPRINT, len(CONTACT_COORDS), float(bool(state.contact)),
                         float(state.contact_force), float(bool(state.fault)),
                         float(bool(state.out_of_domain)), float(bool(state.payload_change)),
                         _CONTACT_NAMES, _utime(state.t))


def _signal_names(names) -> bytes:
    """An lcmt_drake_signal's ``coord`` strings as lcm-gen encodes them."""
    return b"".join(struct.pack(">I", len(n.encode()) + 1) + n.encode() + b"\0" for n in names)


_SIGNAL_FINGERPRINT = lcmt_drake_signal._get_packed_fingerprint()
_CONTACT_NAMES = _signal_names(CONTACT_COORDS)
_CONTACT = struct.Struct(f">8si{len(CONTACT_COORDS)}d{len(_CONTACT_NAMES)}sq")


def decode_contact_state(data: bytes) -> ContactState:
    """The contact state of ``encode_contact_state`` (or of the earlier 4-value message)."""
    msg = lcmt_drake_signal.decode(data)
    if tuple(msg.coord) not in (CONTACT_COORDS, CONTACT_COORDS_V1):
        raise ValueError(f"not a contact-state signal: coord {list(msg.coord)}")
    c, f, fault, ood, *changed = msg.val
    return ContactState(msg.timestamp * 1e-6, c > 0.5, f, fault > 0.5, ood > 0.5,
                        bool(changed) and changed[0] > 0.5)


def encode_payload(t: float, payload) -> bytes:
    """``lcmt_drake_signal`` bytes: the tracker's payload estimate ``[Δm kg, Δ(m·c) kg·m]``
    (about So, in S) at t (s), its values named ``PAYLOAD_COORDS``."""
    msg = lcmt_drake_signal()
    msg.timestamp = _utime(t)
    msg.dim = len(PAYLOAD_COORDS)
    msg.coord = list(PAYLOAD_COORDS)
    msg.val = [float(x) for x in np.asarray(payload, dtype=float).reshape(len(PAYLOAD_COORDS))]
    return msg.encode()


def decode_payload(data: bytes) -> tuple[float, np.ndarray]:
    """(t s, ``[Δm, Δ(m·c)]`` kg, kg·m) of :func:`encode_payload`; ValueError for another
    signal."""
    msg = lcmt_drake_signal.decode(data)
    if tuple(msg.coord) != PAYLOAD_COORDS:
        raise ValueError(f"not a payload signal: coord {list(msg.coord)}")
    return msg.timestamp * 1e-6, np.array(msg.val, dtype=float)


def encode_status(t: float, values: dict) -> bytes:
    """``lcmt_drake_signal`` bytes of the station's status at t (s): `values` by
    ``STATUS_COORDS`` (a missing or None value is sent as NaN)."""
    msg = lcmt_drake_signal()
    msg.timestamp = _utime(t)
    msg.dim = len(STATUS_COORDS)
    msg.coord = list(STATUS_COORDS)
    msg.val = [float("nan") if values.get(k) is None else float(values[k])
               for k in STATUS_COORDS]
    return msg.encode()


def decode_status(data: bytes) -> tuple[float, dict]:
    """(t s, {name: value}) of :func:`encode_status` (or of the earlier message without the
    CPU: those values NaN); ValueError for another signal."""
    msg = lcmt_drake_signal.decode(data)
    if tuple(msg.coord) not in (STATUS_COORDS, STATUS_COORDS_V1):
        raise ValueError(f"not a status signal: coord {list(msg.coord)}")
    values = dict.fromkeys(STATUS_COORDS, float("nan"))
    values.update(zip(msg.coord, msg.val, strict=True))
    return msg.timestamp * 1e-6, values


def encode_temperature(t: float, celsius: float) -> bytes:
    """``lcmt_drake_signal`` bytes: the sensor's temperature (°C) at t (s)."""
    msg = lcmt_drake_signal()
    msg.timestamp = _utime(t)
    msg.dim = 1
    msg.coord = [TEMPERATURE_COORD]
    msg.val = [float(celsius)]
    return msg.encode()


def decode_temperature(data: bytes) -> tuple[float, float]:
    """(t s, temperature °C); ValueError for a signal that is not a temperature."""
    msg = lcmt_drake_signal.decode(data)
    if msg.dim != 1 or list(msg.coord) != [TEMPERATURE_COORD]:
        raise ValueError(f"not a temperature signal: coord {list(msg.coord)}")
    return msg.timestamp * 1e-6, float(msg.val[0])


def encode_imu(t: float, acceleration, angular_velocity) -> bytes:
    """``lcmt_drake_signal`` bytes: an IMU sample at t (s), `acceleration` f_S (3, m/s²) and
    `angular_velocity` ω_S (3, rad/s), in S."""
    msg = lcmt_drake_signal()
    msg.timestamp = _utime(t)
    msg.dim = len(IMU_COORDS)
    msg.coord = list(IMU_COORDS)
    msg.val = [float(v) for v in (*np.ravel(acceleration), *np.ravel(angular_velocity))]
    if len(msg.val) != msg.dim:
        raise ValueError("encode_imu: acceleration and angular_velocity take 3 values each")
    return msg.encode()


def decode_imu(data: bytes) -> tuple[float, np.ndarray]:
    """(t s, [f_S; ω_S] (6,)); ValueError for a signal that is not an IMU sample."""
    msg = lcmt_drake_signal.decode(data)
    if msg.dim != len(IMU_COORDS) or tuple(msg.coord) != IMU_COORDS:
        raise ValueError(f"not an IMU signal: coord {list(msg.coord)}")
    return msg.timestamp * 1e-6, np.array(msg.val, dtype=float)


def encode_event(t: float, name: str) -> bytes:
    """``lcmt_drake_signal`` bytes announcing the event `name` (``TARE_COORD``: the driver
    re-zeroed the sensor; ``PAYLOAD_COORD``: the gripper took or released a payload) at t."""
    msg = lcmt_drake_signal()
    msg.timestamp = _utime(t)
    msg.dim = 1
    msg.coord = [name]
    msg.val = [1.0]
    return msg.encode()


def decode_event(data: bytes, name: str) -> float:
    """t (s) of the event `name`; ValueError for a signal that is not that event."""
    msg = lcmt_drake_signal.decode(data)
    if msg.dim != 1 or list(msg.coord) != [name]:
        raise ValueError(f"not a {name!r} signal: coord {list(msg.coord)}")
    return msg.timestamp * 1e-6


def encode_joint_state(joint_state_type: str, t: float, q, v=None, tau=None) -> bytes:
    """The message a robot driver would send (for simulated robots and tests). For
    robot_state only q is encoded (send v the same way on the velocity channel)."""
    q = np.asarray(q, dtype=float)
    n = len(q)
    v = np.zeros(n) if v is None else np.asarray(v, dtype=float)
    tau = np.zeros(n) if tau is None else np.asarray(tau, dtype=float)
    zeros = [0.0] * n
    msg = message_class(joint_state_type)()
    msg.utime, msg.num_joints = _utime(t), n
    if joint_state_type == "iiwa_status":
        msg.joint_position_measured, msg.joint_velocity_estimated = list(q), list(v)
        msg.joint_torque_measured = list(tau)
        for name in ("joint_position_commanded", "joint_position_ipo",
                     "joint_torque_commanded", "joint_torque_external"):
            setattr(msg, name, zeros)
    elif joint_state_type == "panda_status":
        msg.joint_position, msg.joint_velocity, msg.joint_torque = list(q), list(v), list(tau)
        for name in ("joint_position_desired", "joint_velocity_desired",
                     "joint_acceleration_desired", "joint_torque_desired",
                     "joint_torque_external"):
            setattr(msg, name, zeros)
        msg.robot_utime = msg.utime
    else:
        msg.joint_name = [f"joint_{i}" for i in range(n)]
        msg.joint_position = list(q)
    return msg.encode()
