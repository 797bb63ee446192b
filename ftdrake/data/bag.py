"""Reading ROS bags (ROS 1 ``.bag`` files, ROS 2 bag folders) into a :class:`~.logs.RobotLog`.

Rows are a ``sensor_msgs/JointState`` topic's messages; an optional
``geometry_msgs/WrenchStamped`` topic is put on their times. The rows then pass the checks
every reader shares (:mod:`.logs`): NaN rows dropped, out-of-order messages sorted with a
warning, gaps, units, missing derivatives.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..conventions import MEASURED, TORQUE, joint_columns, wrench_columns
from ..errors import LogError
from ..signals import DEFAULT_ACCELERATION_CUTOFF_HZ
from .robot_log import RobotLog, assemble_log, option_hint, warn_log

# --- Bags --------------------------------------------------------------------------------------

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"


def _header_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _topic(reader, topic: str, msgtype: str, path, option: str) -> list:
    connections = [c for c in reader.connections if c.topic == topic]
    if not connections:
        have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        raise LogError(f"{path}: no topic {topic!r}; the bag has {have}; choose one with "
                       f"{option_hint(option, 'TOPIC')}")
    wrong = {c.msgtype for c in connections} - {msgtype}
    if wrong:
        raise LogError(f"{path}: topic {topic!r} is {sorted(wrong)}, expected {msgtype}")
    return connections


def read_bag(
    path: str | Path | Sequence[str | Path],
    joint_topic: str = "/joint_states",
    *,
    wrench_topic: str | None = None,
    targets: str | None = None,
    joints: Sequence[str] | None = None,
    stamps: str = "header",
    align: str = "linear",
    use_velocities: bool = True,
    position_unit: str = "rad",
    sg_window: float = 0.1,
    sg_polyorder: int = 4,
    gap_factor: float = 3.0,
    check_units: bool = True,
    qdd_estimate: str = "savgol",
    acceleration_cutoff_hz: float = DEFAULT_ACCELERATION_CUTOFF_HZ,
) -> RobotLog:
    """Reads a ROS 1 bag (``.bag`` file, or several) or a ROS 2 bag (directory) with `rosbags`.

    Rows are the ``sensor_msgs/JointState`` messages on `joint_topic`.

    Args:
      joint_topic: JointState topic (positions rad, velocities rad/s, efforts N·m).
      wrench_topic: optional ``geometry_msgs/WrenchStamped`` topic (N, N·m).
      targets: ``"effort"`` (the JointState efforts, named ``tau_0..``) or ``"wrench"`` (the
        wrench, named ``meas_Fx..meas_Tz``, in the message's frame_id, see `source`); default
        ``"wrench"`` when `wrench_topic` is given, else ``"effort"``.
      joints: joint names to keep, in this order; default: the first message's names.
        Messages that lack one of them (e.g. a gripper's own JointState) are skipped, counted.
      stamps: ``"header"`` uses each message's header stamp, the time the driver sampled the
        joints (a zero stamp falls back to the receive time, with a warning); ``"receive"``
        uses the time the recorder received the message, which adds transport jitter.
      align: how the wrench is put on joint-state times. ``"linear"`` (default) interpolates
        between the two wrench samples around each joint-state stamp: an error of order dt²
        instead of the half-period timing error of ``"nearest"``, which picks the closest
        sample and suits a wrench logged much slower than the joints. Joint-state rows outside
        the wrench's time span are dropped (never extrapolated), counted.
      use_velocities: use the messages' velocities when every message has them; otherwise
        they are computed from positions.
      Other arguments as in :func:`~.logs.read_table`.
    """
    targets = _check_options(stamps, align, targets, wrench_topic)
    paths = [Path(p) for p in ([path] if isinstance(path, (str, Path)) else path)]
    label = ", ".join(p.name for p in paths)
    m = _read_messages(paths, label, joint_topic, wrench_topic, joints, stamps)
    joints = m.joints
    if m.skipped:
        warn_log(f"{label}: skipped {m.skipped} {joint_topic} message(s) lacking some of "
                 f"{joints}")
    if m.zero_stamps:
        warn_log(f"{label}: {m.zero_stamps} {joint_topic} message(s) have a zero header stamp; "
                 f"used their receive time")
    if not m.pos:
        raise LogError(f"{label}: no usable messages on {joint_topic!r}")

    t0_ns = min(m.stamp_ns)
    t = (np.asarray(m.stamp_ns) - t0_ns) * 1e-9
    q = np.array(m.pos)
    qd = np.array(m.vel) if use_velocities and all(v is not None for v in m.vel) else None
    source = f"{label} {joint_topic} ({stamps} stamps)"
    if targets == "effort":
        target, target_names = _efforts(m, label, joint_topic)
    else:
        if len(m.w) < 2:
            raise LogError(f"{label}: {len(m.w)} message(s) on {wrench_topic!r}; need at least 2")
        target = _align(t, (np.asarray(m.w_ns) - t0_ns) * 1e-9, np.array(m.w), align)
        target_names = wrench_columns(MEASURED)
        outside = np.isnan(target[:, 0])
        if outside.any():
            warn_log(f"{label}: dropped {outside.sum()} joint state(s) outside the time span "
                     f"of {wrench_topic}")
            t, q, target = t[~outside], q[~outside], target[~outside]
            qd = None if qd is None else qd[~outside]
        source += f", {wrench_topic} in frame {m.frame_id!r} ({align})"
    return assemble_log(
        t, q, qd, None, target, target_names, joints, source,
        sort=True, t0=t0_ns * 1e-9, position_unit=position_unit, sg_window=sg_window,
        sg_polyorder=sg_polyorder, gap_factor=gap_factor, check_units=check_units,
        qdd_estimate=qdd_estimate, acceleration_cutoff_hz=acceleration_cutoff_hz,
    )


def _check_options(stamps: str, align: str, targets: str | None, wrench_topic) -> str:
    """The reader's choices checked; returns the targets (default: the wrench with a
    wrench topic, else the efforts)."""
    if stamps not in ("header", "receive"):
        raise LogError(f"stamps must be 'header' or 'receive', got {stamps!r}")
    if align not in ("linear", "nearest"):
        raise LogError(f"align must be 'linear' or 'nearest', got {align!r}")
    targets = targets or ("wrench" if wrench_topic else "effort")
    if targets not in ("effort", "wrench") or (targets == "wrench" and not wrench_topic):
        raise LogError(f"targets must be 'effort', or 'wrench' with a wrench_topic; "
                       f"got {targets!r}, wrench_topic={wrench_topic!r}")
    return targets


@dataclass
class _Messages:
    """What a bag's topics held, one entry per used message."""

    joints: list | None  # the joint names kept, in order
    stamp_ns: list = field(default_factory=list)
    pos: list = field(default_factory=list)
    vel: list = field(default_factory=list)  # None where a message has no velocities
    eff: list = field(default_factory=list)  # None where a message has no efforts
    w_ns: list = field(default_factory=list)
    w: list = field(default_factory=list)
    frame_id: str = ""
    skipped: int = 0  # joint messages lacking one of `joints`
    zero_stamps: int = 0  # joint messages whose header stamp is zero


def _read_messages(paths, label, joint_topic, wrench_topic, joints, stamps) -> _Messages:
    from rosbags.highlevel import AnyReader  # noqa: PLC0415 (rosbags only for ROS bags)
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415 (as above)

    m = _Messages(joints=joints)
    default_typestore = get_typestore(Stores.LATEST)  # for ROS 2 bags without definitions
    with AnyReader(paths, default_typestore=default_typestore) as reader:
        joint_conns = _topic(reader, joint_topic, JOINT_STATE, label, "joint_topic")
        for conn, receive_ns, raw in reader.messages(connections=joint_conns):
            _add_joint_state(m, reader.deserialize(raw, conn.msgtype), receive_ns, stamps)
        if wrench_topic:
            for conn, receive_ns, raw in reader.messages(
                connections=_topic(reader, wrench_topic, WRENCH_STAMPED, label, "wrench_topic")
            ):
                msg = reader.deserialize(raw, conn.msgtype)
                f, t = msg.wrench.force, msg.wrench.torque
                m.w_ns.append((_header_ns(msg) if stamps == "header" else 0) or receive_ns)
                m.w.append([f.x, f.y, f.z, t.x, t.y, t.z])
                m.frame_id = msg.header.frame_id
    return m


def _add_joint_state(m: _Messages, msg, receive_ns: int, stamps: str) -> None:
    names = list(msg.name)
    m.joints = list(m.joints or names)  # the first message's names unless given
    if not set(m.joints) <= set(names):
        m.skipped += 1
        return
    idx = [names.index(j) for j in m.joints]
    ns = _header_ns(msg) if stamps == "header" else receive_ns
    m.zero_stamps += ns == 0
    m.stamp_ns.append(ns or receive_ns)
    m.pos.append(np.asarray(msg.position)[idx])
    m.vel.append(np.asarray(msg.velocity)[idx] if len(msg.velocity) == len(names) else None)
    m.eff.append(np.asarray(msg.effort)[idx] if len(msg.effort) == len(names) else None)


def _efforts(m: _Messages, label: str, joint_topic: str):
    if any(e is None for e in m.eff):
        raise LogError(f"{label}: {joint_topic} messages carry no efforts; pass "
                       f"{option_hint('wrench_topic', 'TOPIC')} and "
                       f"{option_hint('targets', 'wrench')}")
    return np.array(m.eff), joint_columns(TORQUE, len(m.joints))


def _align(t, t_w, w, align):
    """Wrench samples `w` at times `t_w`, put on times `t`; NaN outside t_w's span."""
    order = np.argsort(t_w, kind="stable")
    t_w, w = t_w[order], w[order]
    inside = (t >= t_w[0]) & (t <= t_w[-1])
    if align == "linear":
        out = np.column_stack([np.interp(t, t_w, w[:, k]) for k in range(w.shape[1])])
    else:
        i = np.clip(np.searchsorted(t_w, t), 1, len(t_w) - 1)
        i -= (t - t_w[i - 1]) < (t_w[i] - t)
        out = w[i]
    out[~inside] = np.nan
    return out


def is_bag(path: str | Path) -> bool:
    """True for what :func:`read_bag` reads: a ``.bag`` file or a (ROS 2 bag) folder."""
    path = Path(path)
    return path.is_dir() or path.suffix == ".bag"


def message_count(path: str | Path, topic: str) -> int:
    """How many messages the bag at `path` holds on `topic`."""
    from rosbags.highlevel import AnyReader  # noqa: PLC0415 (rosbags only for ROS bags)
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415 (as above)

    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.LATEST)) as reader:
        return sum(c.msgcount for c in reader.connections if c.topic == topic)
