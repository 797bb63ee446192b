"""Reading robot logs (CSV, Parquet, ROS 1 / ROS 2 bags) into one validated record.

Every reader returns a :class:`RobotLog`: time, joint positions, velocities, accelerations and
the targets a model learns (an F/T sensor's wrench, or joint torques), checked the same way:

* rows with NaN/inf are dropped, and a :class:`LogWarning` says how many;
* timestamps must increase: tables with a backwards step raise (they are often several
  recordings glued together), bags are sorted with a warning (messages from one stream can
  arrive out of order);
* rows repeating an earlier timestamp are dropped (the first is kept), with a warning;
* gaps longer than ``gap_factor`` × the median sample period are reported; derivatives are
  computed piecewise between gaps;
* joint positions that look like degrees (most joints beyond ±2π), and given velocities that
  disagree with the derivative of the positions (e.g. deg/s next to rad, or a driver that
  publishes zeros) raise; ``position_unit="deg"`` converts a degree log;
* too few rows, non-numeric columns and missing columns or topics raise :class:`LogError`,
  which names what is missing and lists what is there.

Missing velocities and accelerations are Savitzky–Golay derivatives of the positions
(:func:`savgol_derivative`); ``RobotLog.derived`` says which.

Units: time in s, joint positions in rad, velocities in rad/s, accelerations in rad/s²;
targets as logged (N and N·m for wrenches and joint torques).
"""

from __future__ import annotations

import fnmatch
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.signal import savgol_filter

from ftdrake.compensation.features import stack_layout
from ftdrake.conventions import MEASURED, QD, QDD, TIME, Q, joint_columns, wrench_columns

from ..errors import LogError

MIN_ROWS = 10
TORQUE = "tau"  # target prefix for joint efforts read from a JointState topic
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180}
_GLOB_CHARS = set("*?[")

Columns = str | re.Pattern | Sequence[str]


class LogWarning(UserWarning):
    """A log was read, but rows were dropped or reordered, or it has gaps.

    Escalate with ``warnings.simplefilter("error", LogWarning)`` to refuse such logs.
    """


@dataclass
class RobotLog:
    """One robot log, validated, in SI units.

    Attributes:
      t: (N,) time in s, strictly increasing (for bags: since the first sample, see `t0`).
      q, qd, qdd: (N, n) joint positions (rad), velocities (rad/s), accelerations (rad/s²).
      targets: (N, m) what a model predicts, e.g. ``meas_Fx..meas_Tz`` (N, N·m) or joint
        torques ``tau_0..`` (N·m).
      target_names: m names of the target columns.
      joint_names: n joint names (a bag's JointState names, or a table's position columns).
      source: where the log came from and how it was read.
      derived: which of ``"qd"``, ``"qdd"`` were computed rather than read.
      t0: absolute time of ``t = 0`` in s (UNIX time for bags, 0 for tables).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    targets: np.ndarray
    target_names: list[str]
    joint_names: list[str]
    source: str = ""
    derived: list[str] = field(default_factory=list)
    t0: float = 0.0

    def __post_init__(self):
        n_rows, n = len(self.t), len(self.joint_names)
        for name in ("q", "qd", "qdd"):
            if getattr(self, name).shape != (n_rows, n):
                raise LogError(f"{name} has shape {getattr(self, name).shape}, "
                               f"expected ({n_rows}, {n})")
        if self.targets.shape != (n_rows, len(self.target_names)):
            raise LogError(f"targets have shape {self.targets.shape}, "
                           f"expected ({n_rows}, {len(self.target_names)})")

    def __len__(self) -> int:
        return len(self.t)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def X(self) -> np.ndarray:
        """Model input ``[q, q̇, q̈]``, N × 3n (see :mod:`ftdrake.compensation.features`)."""
        return stack_layout(self.q, self.qd, self.qdd)

    def to_frame(self) -> pd.DataFrame:
        """Columns ``t, q_i, qd_i, qdd_i`` and the target names, as in simulated datasets."""
        n = self.n_joints
        blocks = [self.t[:, None], self.q, self.qd, self.qdd, self.targets]
        names = [TIME, *joint_columns(Q, n), *joint_columns(QD, n), *joint_columns(QDD, n)]
        return pd.DataFrame(np.hstack(blocks), columns=names + list(self.target_names))


# --- Column selection ------------------------------------------------------------------------


def natural_key(name: str) -> list:
    """Sort key that orders ``q_2`` before ``q_10``."""
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", name)]


def expand_columns(spec: Columns, available: Sequence[str], what: str = "columns") -> list[str]:
    """Column names selected by `spec`.

    `spec` is a glob (``"q_*"``, any of ``* ? [``), a compiled regex (``re.compile(r"q_\\d+")``,
    full match), an exact column name, or a list of exact names (kept in the given order).
    Pattern matches are returned in natural order. Raises LogError, naming `what` and listing
    the available columns, when nothing matches or a listed name is missing.
    """
    available = list(available)
    if isinstance(spec, re.Pattern):
        found = sorted((c for c in available if spec.fullmatch(c)), key=natural_key)
        label = f"regex {spec.pattern!r}"
    elif isinstance(spec, str) and _GLOB_CHARS & set(spec):
        found = sorted((c for c in available if fnmatch.fnmatchcase(c, spec)), key=natural_key)
        label = f"pattern {spec!r}"
    else:
        names = [spec] if isinstance(spec, str) else list(spec)
        missing = [c for c in names if c not in available]
        found = [] if missing else names
        label = f"column(s) {missing}"
    if not found:
        raise LogError(f"{what}: {label} not found; available columns: {available}")
    return found


# --- Differentiation -------------------------------------------------------------------------


def savgol_derivative(
    x: np.ndarray, dt: float, deriv: int, window_s: float = 0.1, polyorder: int = 4
) -> np.ndarray:
    """Savitzky–Golay derivative of uniformly sampled rows of `x` (along axis 0).

    Args:
      x: (N, ...) samples, e.g. joint positions in rad.
      dt: sample period in s (a log's median period).
      deriv: 1 for d/dt (rad/s), 2 for d²/dt² (rad/s²).
      window_s: fit window in s, rounded to an odd number of samples (at least
        ``polyorder + 1``, at most N). The default 0.1 s is 13 samples at 125 Hz and 101 at
        1 kHz; with `polyorder` 4 it passes motion up to 5 Hz with < 1.2 % loss in the first
        and < 0.7 % in the second derivative, is -3 dB at 12–14 Hz and passes < 14 % of
        anything above 30 Hz (sensor noise). Shorten it for faster motion.
      polyorder: degree of the local polynomial fit.
    """
    n_rows = len(x)
    window = 2 * round(window_s / dt / 2) + 1
    window = max(window, polyorder + 1 + polyorder % 2)  # odd and > polyorder
    window = min(window, n_rows if n_rows % 2 else n_rows - 1)
    if window <= polyorder:
        raise LogError(
            f"{n_rows} samples are too few for a Savitzky–Golay fit of order {polyorder}"
        )
    return savgol_filter(x, window, polyorder, deriv=deriv, delta=dt, axis=0)


def _piecewise_derivative(x, t, breaks, deriv, window_s, polyorder):
    """Savitzky–Golay derivative computed separately on each segment between gaps."""
    dt = float(np.median(np.diff(t)))
    pieces = np.split(np.arange(len(t)), breaks)
    for i in pieces:
        if len(i) <= polyorder:
            raise LogError(
                f"the {len(i)} samples between gaps at t = {t[i[0]]:.6g}..{t[i[-1]]:.6g} s are "
                f"too few for a Savitzky–Golay fit of order {polyorder}; drop them or lower "
                f"sg_polyorder"
            )
    return np.concatenate(
        [savgol_derivative(x[i], dt, deriv, window_s, polyorder) for i in pieces]
    )


# --- Validation shared by all readers ----------------------------------------------------------


def _warn(message: str) -> None:
    warnings.warn(message, LogWarning, stacklevel=3)


def _take(t, blocks, rows):
    """`t` and every array in `blocks` restricted to `rows` (a mask or an index array)."""
    return t[rows], {k: None if v is None else v[rows] for k, v in blocks.items()}


def _assemble(
    t, q, qd, qdd, targets, target_names, joint_names, source, *,
    sort, t0, position_unit, sg_window, sg_polyorder, gap_factor, check_units,
) -> RobotLog:
    """Cleans rows, checks units and fills missing derivatives; see the module docstring."""
    if position_unit not in _ANGLE_UNITS:
        raise LogError(f"position_unit must be one of {list(_ANGLE_UNITS)}, got {position_unit!r}")
    scale = _ANGLE_UNITS[position_unit]
    blocks = {"q": q, "qd": qd, "qdd": qdd, "targets": targets}
    blocks = {k: None if v is None else np.asarray(v, float).reshape(len(t), -1)
              for k, v in blocks.items()}
    for k in ("q", "qd", "qdd"):
        if blocks[k] is not None:
            blocks[k] = blocks[k] * scale
    t = np.asarray(t, float)

    # NaN / inf rows.
    bad_in = {"t": ~np.isfinite(t)}
    bad_in |= {k: ~np.isfinite(v).all(axis=1) for k, v in blocks.items() if v is not None}
    bad = np.logical_or.reduce(list(bad_in.values()))
    if bad.any():
        counts = ", ".join(f"{k}: {m.sum()}" for k, m in bad_in.items() if m.any())
        _warn(f"{source}: dropped {bad.sum()} of {len(t)} rows with NaN/inf ({counts})")
        t, blocks = _take(t, blocks, ~bad)

    # Order and duplicates.
    n_back = int((np.diff(t) < 0).sum())
    if n_back:
        first = int(np.argmax(np.diff(t) < 0))
        where = f"first from {t[first]:.6g} to {t[first + 1]:.6g} s"
        if not sort:
            raise LogError(f"{source}: time goes backwards at {n_back} row(s) ({where}); if "
                           f"this file joins several recordings, read them separately, or "
                           f"sort the DataFrame by time and pass it in")
        _warn(f"{source}: time goes backwards at {n_back} row(s) ({where}); rows sorted by time")
        t, blocks = _take(t, blocks, np.argsort(t, kind="stable"))
    dup = np.r_[False, np.diff(t) == 0]
    if dup.any():
        _warn(f"{source}: dropped {dup.sum()} row(s) repeating an earlier timestamp "
              f"(kept the first)")
        t, blocks = _take(t, blocks, ~dup)
    if len(t) < MIN_ROWS:
        raise LogError(f"{source}: only {len(t)} usable rows; need at least {MIN_ROWS}")

    # Gaps.
    dt = np.diff(t)
    median_dt = float(np.median(dt))
    breaks = np.flatnonzero(dt > gap_factor * median_dt) + 1
    if len(breaks):
        i = int(np.argmax(dt))
        _warn(f"{source}: {len(breaks)} gap(s) longer than {gap_factor:g} × the median period "
              f"{median_dt * 1e3:.3g} ms; longest {dt[i]:.4g} s at t = {t[i]:.6g} s; "
              f"derivatives are computed separately between gaps")

    q = blocks["q"]
    derived = [k for k in ("qd", "qdd") if blocks[k] is None]
    deriv = {k: _piecewise_derivative(q, t, breaks, d, sg_window, sg_polyorder)
             for d, k in ((1, "qd"), (2, "qdd"))}
    if check_units:
        _check_units(q, blocks["qd"], deriv["qd"], joint_names, source)
    return RobotLog(
        t=t, q=q,
        qd=deriv["qd"] if blocks["qd"] is None else blocks["qd"],
        qdd=deriv["qdd"] if blocks["qdd"] is None else blocks["qdd"],
        targets=blocks["targets"], target_names=list(target_names),
        joint_names=list(joint_names), source=source, derived=derived, t0=t0,
    )


def _check_units(q, qd, qd_from_q, joint_names, source):
    """Raises when positions look like degrees or given velocities disagree with q's.

    Given velocities are compared with the Savitzky–Golay derivative of q by the least-squares
    factor ``qd ≈ ratio × qd_from_q``, which noise in `qd` does not bias; outside 0.5..2 is an
    error. A log that hardly moves (RMS of qd_from_q < 0.01 rad/s) is not checked.
    """
    max_abs = np.abs(q).max(axis=0)
    if np.median(max_abs) > 2 * np.pi:
        big = [f"{n}: {m:.4g}" for n, m in zip(joint_names, max_abs, strict=True) if m > 2 * np.pi]
        raise LogError(
            f"{source}: joint positions look like degrees: {len(big)} of {len(max_abs)} joints "
            f"exceed 2π rad in |q| ({', '.join(big)}); pass position_unit='deg', or "
            f"check_units=False if they really turn that far"
        )
    if qd is None or np.sqrt(np.mean(qd_from_q**2)) < 0.01:
        return
    ratio = float(np.sum(qd * qd_from_q) / np.sum(qd_from_q**2))
    if not 0.5 < ratio < 2:
        raise LogError(
            f"{source}: given qd is {ratio:.3g} × the Savitzky–Golay derivative of q "
            f"(57.3 means deg/s next to rad; ~0 means not a measurement); fix its unit, "
            f"or pass velocities=None to compute them from q, or check_units=False"
        )


# --- Tables ------------------------------------------------------------------------------------


def _numeric(frame: pd.DataFrame, names: list[str], source: str) -> np.ndarray:
    for name in names:
        col = frame[name]
        if pd.api.types.is_bool_dtype(col) or not pd.api.types.is_numeric_dtype(col):
            coerced = pd.to_numeric(col, errors="coerce")
            bad = coerced.isna() & col.notna()
            example = f"row {int(np.argmax(bad))} holds {col[bad].iloc[0]!r}" if bad.any() else ""
            raise LogError(f"{source}: column {name!r} is not numeric (dtype {col.dtype}; "
                           f"{int(bad.sum())} non-numeric values; {example})")
    return frame[names].to_numpy(dtype=float)


def read_table(
    source: str | Path | pd.DataFrame,
    positions: Columns = "q_*",
    targets: Columns = f"{MEASURED}_*",
    velocities: Columns | None = None,
    accelerations: Columns | None = None,
    time: str | None = TIME,
    *,
    time_unit: str = "s",
    rate_hz: float | None = None,
    position_unit: str = "rad",
    sg_window: float = 0.1,
    sg_polyorder: int = 4,
    gap_factor: float = 3.0,
    check_units: bool = True,
) -> RobotLog:
    """Reads a CSV or Parquet log (or a DataFrame) with named columns.

    Args:
      source: ``.csv`` / ``.csv.gz`` / ``.parquet`` path, or a DataFrame.
      positions, targets, velocities, accelerations: columns, see :func:`expand_columns`
        (``"q_*"``, ``re.compile(r"q_\\d+")``, or a list of names). Velocities or
        accelerations left None are Savitzky–Golay derivatives of the positions.
      time: time column (numbers in `time_unit`, or datetimes); None: rows are sampled at
        `rate_hz`.
      position_unit: ``"rad"`` or ``"deg"``; the angle unit of the position, velocity and
        acceleration columns (converted to rad, rad/s, rad/s²).
      sg_window, sg_polyorder: Savitzky–Golay window (s) and order, see
        :func:`savgol_derivative`.
      gap_factor: a step longer than this × the median period is a gap.
      check_units: raise on degree-like positions and on given velocities that disagree with
        the derivative of the positions (see the module docstring).
    """
    if isinstance(source, pd.DataFrame):
        frame, label = source, "DataFrame"
    else:
        path = Path(source)
        label = path.name
        if path.name.endswith((".csv", ".csv.gz", ".txt")):
            frame = pd.read_csv(path)
        elif path.suffix in (".parquet", ".pq"):
            frame = pd.read_parquet(path)
        else:
            raise LogError(f"{path}: unknown table format; expected .csv or .parquet")
    cols = [str(c) for c in frame.columns]
    frame = frame.set_axis(cols, axis=1).reset_index(drop=True)
    selected = {}
    for what, spec in [("positions", positions), ("velocities", velocities),
                       ("accelerations", accelerations), ("targets", targets)]:
        if spec is not None:
            selected[what] = expand_columns(spec, cols, f"{label} {what}")
    n = len(selected["positions"])
    for what in ("velocities", "accelerations"):
        if what in selected and len(selected[what]) != n:
            raise LogError(f"{label}: {len(selected[what])} {what} columns "
                           f"{selected[what]} for {n} positions {selected['positions']}")

    t0 = 0.0
    if time is None:
        if not rate_hz:
            raise LogError(f"{label}: without a time column, pass rate_hz")
        t = np.arange(len(frame)) / rate_hz
    else:
        expand_columns([time], cols, f"{label} time")
        if time_unit not in _TIME_UNITS:
            raise LogError(f"time_unit must be one of {list(_TIME_UNITS)}, got {time_unit!r}")
        col = frame[time]
        if pd.api.types.is_datetime64_any_dtype(col):
            t0 = col.iloc[0].timestamp()
            t = (col - col.iloc[0]).dt.total_seconds().to_numpy()
        else:
            t = _numeric(frame, [time], label)[:, 0] * _TIME_UNITS[time_unit]
    arrays = {what: _numeric(frame, names, label) for what, names in selected.items()}
    return _assemble(
        t, arrays["positions"], arrays.get("velocities"), arrays.get("accelerations"),
        arrays["targets"], selected["targets"], selected["positions"], label,
        sort=False, t0=t0, position_unit=position_unit, sg_window=sg_window,
        sg_polyorder=sg_polyorder, gap_factor=gap_factor, check_units=check_units,
    )


# --- Bags --------------------------------------------------------------------------------------

JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"


def _header_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _topic(reader, topic: str, msgtype: str, path) -> list:
    connections = [c for c in reader.connections if c.topic == topic]
    if not connections:
        have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        raise LogError(f"{path}: no topic {topic!r}; the bag has {have}")
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
      Other arguments as in :func:`read_table`.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if stamps not in ("header", "receive"):
        raise LogError(f"stamps must be 'header' or 'receive', got {stamps!r}")
    if align not in ("linear", "nearest"):
        raise LogError(f"align must be 'linear' or 'nearest', got {align!r}")
    targets = targets or ("wrench" if wrench_topic else "effort")
    if targets not in ("effort", "wrench") or (targets == "wrench" and not wrench_topic):
        raise LogError(f"targets must be 'effort', or 'wrench' with a wrench_topic; "
                       f"got {targets!r}, wrench_topic={wrench_topic!r}")
    paths = [Path(p) for p in ([path] if isinstance(path, (str, Path)) else path)]
    label = ", ".join(p.name for p in paths)

    skipped = zero_stamps = 0
    stamp_ns, pos, vel, eff, w_ns, w, frame_id = [], [], [], [], [], [], ""
    default_typestore = get_typestore(Stores.LATEST)  # for ROS 2 bags without definitions
    with AnyReader(paths, default_typestore=default_typestore) as reader:
        joint_conns = _topic(reader, joint_topic, JOINT_STATE, label)
        for conn, receive_ns, raw in reader.messages(connections=joint_conns):
            msg = reader.deserialize(raw, conn.msgtype)
            names = list(msg.name)
            joints = list(joints or names)  # the first message's names unless given
            if not set(joints) <= set(names):
                skipped += 1
                continue
            idx = [names.index(j) for j in joints]
            ns = _header_ns(msg) if stamps == "header" else receive_ns
            zero_stamps += ns == 0
            stamp_ns.append(ns or receive_ns)
            pos.append(np.asarray(msg.position)[idx])
            vel.append(np.asarray(msg.velocity)[idx] if len(msg.velocity) == len(names) else None)
            eff.append(np.asarray(msg.effort)[idx] if len(msg.effort) == len(names) else None)
        if wrench_topic:
            for conn, receive_ns, raw in reader.messages(
                connections=_topic(reader, wrench_topic, WRENCH_STAMPED, label)
            ):
                msg = reader.deserialize(raw, conn.msgtype)
                f, m = msg.wrench.force, msg.wrench.torque
                w_ns.append((_header_ns(msg) if stamps == "header" else 0) or receive_ns)
                w.append([f.x, f.y, f.z, m.x, m.y, m.z])
                frame_id = msg.header.frame_id
    if skipped:
        _warn(f"{label}: skipped {skipped} {joint_topic} message(s) lacking some of {joints}")
    if zero_stamps:
        _warn(f"{label}: {zero_stamps} {joint_topic} message(s) have a zero header stamp; "
              f"used their receive time")
    if not pos:
        raise LogError(f"{label}: no usable messages on {joint_topic!r}")

    t0_ns = min(stamp_ns)
    t = (np.asarray(stamp_ns) - t0_ns) * 1e-9
    q = np.array(pos)
    qd = np.array(vel) if use_velocities and all(v is not None for v in vel) else None
    source = f"{label} {joint_topic} ({stamps} stamps)"
    if targets == "effort":
        if any(e is None for e in eff):
            raise LogError(f"{label}: {joint_topic} messages carry no efforts; "
                           f"pass a wrench_topic and targets='wrench'")
        target, target_names = np.array(eff), joint_columns(TORQUE, len(joints))
    else:
        if len(w) < 2:
            raise LogError(f"{label}: {len(w)} message(s) on {wrench_topic!r}; need at least 2")
        target = _align(t, (np.asarray(w_ns) - t0_ns) * 1e-9, np.array(w), align)
        target_names = wrench_columns(MEASURED)
        outside = np.isnan(target[:, 0])
        if outside.any():
            _warn(f"{label}: dropped {outside.sum()} joint state(s) outside the time span "
                  f"of {wrench_topic}")
            t, q, target = t[~outside], q[~outside], target[~outside]
            qd = None if qd is None else qd[~outside]
        source += f", {wrench_topic} in frame {frame_id!r} ({align})"
    return _assemble(
        t, q, qd, None, target, target_names, joints, source,
        sort=True, t0=t0_ns * 1e-9, position_unit=position_unit, sg_window=sg_window,
        sg_polyorder=sg_polyorder, gap_factor=gap_factor, check_units=check_units,
    )


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
