"""One robot log, validated: :class:`RobotLog` and the checks every reader shares.

Every reader (tables in :mod:`.logs`, ROS bags in :mod:`.bag`) hands its arrays to
:func:`assemble_log`, which returns a :class:`RobotLog`: time, joint positions, velocities,
accelerations and the targets a model learns (an F/T sensor's wrench, or joint torques),
checked the same way:

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
* too few rows raise :class:`~ftdrake.errors.LogError`.

Missing velocities and accelerations are Savitzky–Golay derivatives of the positions
(:func:`ftdrake.signals.savgol_derivative`); with ``qdd_estimate="causal"`` missing
accelerations are instead the loop's causal estimate from q̇
(:func:`ftdrake.signals.causal_acceleration`). ``RobotLog.derived`` says which were computed.

Errors that an option fixes name it through :func:`option_hint`: as a Python keyword
(``check_units=False``) by default, or as whatever a front end sets with
:func:`option_spelling` (the command line names its flags).

Units: time in s, joint positions in rad, velocities in rad/s, accelerations in rad/s²;
targets as logged (N and N·m for wrenches and joint torques).
"""

from __future__ import annotations

import contextlib
import contextvars
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..conventions import QD, QDD, TEMPERATURE, TIME, Q, joint_columns
from ..errors import LogError
from ..signals import DEFAULT_ACCELERATION_CUTOFF_HZ, causal_acceleration, savgol_derivative

MIN_ROWS = 10
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180}
QDD_ESTIMATES = ("savgol", "causal")


# --- How errors name the option that fixes them ------------------------------------------------


def _python_spelling(name: str, value) -> str:
    return f"{name}={value!r}"


_SPELLING: contextvars.ContextVar[Callable[[str, object], str]] = contextvars.ContextVar(
    "ftdrake_option_spelling", default=_python_spelling)


def option_hint(name: str, value) -> str:
    """How an error message asks the user to set reader option `name` to `value`.

    `name` is a keyword of :func:`read_table` / :func:`~.bag.read_bag` (and a field of
    :class:`~.training.ReadOptions`); by default the hint is ``name=value``.
    """
    return _SPELLING.get()(name, value)


@contextlib.contextmanager
def option_spelling(spell: Callable[[str, object], str]) -> Iterator[None]:
    """Within the block, errors name options as ``spell(name, value)`` returns (e.g. flags)."""
    token = _SPELLING.set(spell)
    try:
        yield
    finally:
        _SPELLING.reset(token)


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
      temperature: (N,) the sensor's temperature in °C, when the log has one and it was
        asked for (``read_table(temperature=...)``); else None.
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
    temperature: np.ndarray | None = None

    def __post_init__(self):
        n_rows, n = len(self.t), len(self.joint_names)
        for name in ("q", "qd", "qdd"):
            if getattr(self, name).shape != (n_rows, n):
                raise LogError(f"{name} has shape {getattr(self, name).shape}, "
                               f"expected ({n_rows}, {n})")
        if self.targets.shape != (n_rows, len(self.target_names)):
            raise LogError(f"targets have shape {self.targets.shape}, "
                           f"expected ({n_rows}, {len(self.target_names)})")
        if self.temperature is not None and np.shape(self.temperature) != (n_rows,):
            raise LogError(f"temperature has shape {np.shape(self.temperature)}, "
                           f"expected ({n_rows},)")

    def __len__(self) -> int:
        return len(self.t)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def X(self) -> np.ndarray:
        """Model input ``[q, q̇, q̈]``, N × 3n (see :mod:`ftdrake.compensation.features`),
        with the temperature (°C) as one more, last column when the log has one."""
        blocks = [self.q, self.qd, self.qdd]
        if self.temperature is not None:
            blocks.append(self.temperature[:, None])
        return np.hstack(blocks)

    def to_frame(self) -> pd.DataFrame:
        """Columns ``t, q_i, qd_i, qdd_i`` and the target names, as in simulated datasets."""
        n = self.n_joints
        blocks = [self.t[:, None], self.q, self.qd, self.qdd, self.targets]
        names = [TIME, *joint_columns(Q, n), *joint_columns(QD, n), *joint_columns(QDD, n),
                 *self.target_names]
        if self.temperature is not None:
            blocks.append(self.temperature[:, None])
            names.append(TEMPERATURE)
        return pd.DataFrame(np.hstack(blocks), columns=names)


# --- Differentiation -------------------------------------------------------------------------


def _piecewise_derivative(x, t, breaks, deriv, window_s, polyorder, short=None):
    """Savitzky–Golay derivative computed separately on each segment between gaps.

    A segment too short for order `polyorder` (an odd window of at most its length must
    exceed the order) is fitted with the highest order its length allows; one shorter than
    the derivative's order needs (fewer than 3 rows for q̈, 1 row for q̇) gets 0 there.
    Each such segment is appended to `short` as (rows, order used, start time).
    """
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    out = np.zeros_like(x, dtype=float)
    for i in np.split(np.arange(len(t)), breaks):
        order = min(polyorder, len(i) - 1 + len(i) % 2 - 1)  # the largest odd window − 1
        if order < polyorder and short is not None:
            short.append((len(i), max(order, 0), float(t[i[0]])))
        if order >= deriv:
            out[i] = savgol_derivative(x[i], dt, deriv, window_s, order)
    return out


def _short_segments_message(source, short, n_segments, polyorder) -> str:
    """One line for every segment fitted with a lower Savitzky–Golay order."""
    rows, _, start = min(short)
    lowest = min(o for _, o, _ in short)
    zero = sum(1 for _, o, _ in short if o < 2)
    return (f"{source}: {len(short)} of {n_segments} segment(s) between gaps are too short "
            f"for a Savitzky–Golay fit of order {polyorder} (shortest: {rows} rows at t = "
            f"{start:.6g} s): fitted there with the order their length allows (down to "
            f"{lowest}" + (f"; q̈ = 0 on {zero} with fewer than 3 rows" if zero else "") +
            f"); {option_hint('sg_polyorder', lowest)} fits every segment with that order")


def velocities_from_positions(t, q, source: str, *, sg_window: float = 0.1,
                              sg_polyorder: int = 4, gap_factor: float = 3.0) -> np.ndarray:
    """q̇ (N, n) rad/s from q (N, n) rad at strictly increasing times `t` (s), as every
    reader computes missing velocities (:func:`assemble_log`): Savitzky–Golay, separately
    between gaps (reported, as are segments too short for the order)."""
    t, q = np.asarray(t, float), np.asarray(q, float).reshape(len(t), -1)
    breaks = _gaps(t, gap_factor, source)
    short = []
    qd = _piecewise_derivative(q, t, breaks, 1, sg_window, sg_polyorder, short)
    if short:
        warn_log(_short_segments_message(source, short, len(breaks) + 1, sg_polyorder))
    return qd


def _piecewise_causal(qd, t, breaks, cutoff_hz):
    """The loop's causal q̈ estimate from `qd`, restarted (q̈ = 0) after every gap."""
    dt = float(np.median(np.diff(t)))
    pieces = np.split(np.arange(len(t)), breaks)
    return np.concatenate([causal_acceleration(qd[i], dt, cutoff_hz) for i in pieces])


# --- Validation shared by all readers ----------------------------------------------------------


def warn_log(message: str, *, depth: int = 0) -> None:
    """Issues a :class:`LogWarning` attributed to the reader's caller; `depth`: the frames
    between the reader and this call beyond one (a helper of the reader's helper: 1)."""
    warnings.warn(message, LogWarning, stacklevel=3 + depth)


def _take(t, blocks, rows):
    """`t` and every array in `blocks` restricted to `rows` (a mask or an index array)."""
    return t[rows], {k: None if v is None else v[rows] for k, v in blocks.items()}


def assemble_log(
    t, q, qd, qdd, targets, target_names, joint_names, source, *,
    sort, t0, position_unit, sg_window, sg_polyorder, gap_factor, check_units,
    qdd_estimate="savgol", acceleration_cutoff_hz=DEFAULT_ACCELERATION_CUTOFF_HZ,
    temperature=None, min_rows=MIN_ROWS,
) -> RobotLog:
    """Cleans rows, checks units and fills missing derivatives; see the module docstring.

    `temperature` (N,), °C, if given, is cleaned with the rows and kept in the log.
    `min_rows`: fewer usable rows raise (one trajectory of several may be shorter).
    """
    if position_unit not in ANGLE_UNITS:
        raise LogError(f"position_unit must be one of {list(ANGLE_UNITS)}, got {position_unit!r}")
    if qdd_estimate not in QDD_ESTIMATES:
        raise LogError(f"qdd_estimate must be one of {list(QDD_ESTIMATES)}, got {qdd_estimate!r}")
    t, blocks = _blocks_in_si(t, q, qd, qdd, targets, temperature, ANGLE_UNITS[position_unit])
    t, blocks = _drop_non_finite_rows(t, blocks, source)
    t, blocks = _order_rows(t, blocks, source, sort)
    if len(t) < max(min_rows, 1):
        raise LogError(f"{source}: only {len(t)} usable rows; need at least {max(min_rows, 1)}")
    derived = [k for k in ("qd", "qdd") if blocks[k] is None]
    breaks = _gaps(t, gap_factor, source, report=bool(derived))

    q = blocks["q"]
    short = []  # segments too short for the Savitzky–Golay order (reported once)
    deriv = {"qd": _piecewise_derivative(q, t, breaks, 1, sg_window, sg_polyorder,
                                         short if "qd" in derived else None)}
    if check_units:
        check_joint_units(q, blocks["qd"], deriv["qd"], joint_names, source)
    qd = deriv["qd"] if blocks["qd"] is None else blocks["qd"]
    if blocks["qdd"] is None and qdd_estimate == "causal":
        deriv["qdd"] = _piecewise_causal(qd, t, breaks, acceleration_cutoff_hz)
    elif blocks["qdd"] is None:
        deriv["qdd"] = _piecewise_derivative(q, t, breaks, 2, sg_window, sg_polyorder,
                                             [] if short else short)
    if short:
        warn_log(_short_segments_message(source, short, len(breaks) + 1, sg_polyorder))
    return RobotLog(
        t=t, q=q, qd=qd,
        qdd=deriv["qdd"] if blocks["qdd"] is None else blocks["qdd"],
        targets=blocks["targets"], target_names=list(target_names),
        joint_names=list(joint_names), source=source, derived=derived, t0=t0,
        temperature=None if blocks["temperature"] is None else blocks["temperature"][:, 0],
    )


def _blocks_in_si(t, q, qd, qdd, targets, temperature, scale):
    """Every block as an (N, k) float array, the joint blocks scaled to rad."""
    blocks = {"q": q, "qd": qd, "qdd": qdd, "targets": targets, "temperature": temperature}
    blocks = {k: None if v is None else np.asarray(v, float).reshape(len(t), -1)
              for k, v in blocks.items()}
    for k in ("q", "qd", "qdd"):
        if blocks[k] is not None:
            blocks[k] = blocks[k] * scale
    return np.asarray(t, float), blocks


def _drop_non_finite_rows(t, blocks, source):
    bad_in = {"t": ~np.isfinite(t)}
    bad_in |= {k: ~np.isfinite(v).all(axis=1) for k, v in blocks.items() if v is not None}
    bad = np.logical_or.reduce(list(bad_in.values()))
    if bad.any():
        counts = ", ".join(f"{k}: {m.sum()}" for k, m in bad_in.items() if m.any())
        warn_log(f"{source}: dropped {bad.sum()} of {len(t)} rows with NaN/inf ({counts})",
                 depth=1)
        t, blocks = _take(t, blocks, ~bad)
    return t, blocks


def _order_rows(t, blocks, source, sort: bool):
    """Rows in time order (a backwards step raises unless `sort`), repeated stamps dropped."""
    n_back = int((np.diff(t) < 0).sum())
    if n_back:
        first = int(np.argmax(np.diff(t) < 0))
        where = f"first from {t[first]:.6g} to {t[first + 1]:.6g} s"
        if not sort:
            raise LogError(f"{source}: time goes backwards at {n_back} row(s) ({where}); if "
                           f"this file joins several recordings, add a column numbering them "
                           f"and pass {option_hint('group', 'COLUMN')} to read each apart, "
                           f"or sort the rows by time")
        warn_log(f"{source}: time goes backwards at {n_back} row(s) ({where}); rows sorted by "
                 f"time", depth=1)
        t, blocks = _take(t, blocks, np.argsort(t, kind="stable"))
    dup = np.r_[False, np.diff(t) == 0]
    if dup.any():
        warn_log(f"{source}: dropped {dup.sum()} row(s) repeating an earlier timestamp "
                 f"(kept the first)", depth=1)
        t, blocks = _take(t, blocks, ~dup)
    return t, blocks


def _gaps(t, gap_factor: float, source, report: bool = True) -> np.ndarray:
    """Indices where a gap longer than `gap_factor` × the median period ends (reported when
    `report`: derivatives are computed from q; a log that gives them has nothing to say)."""
    if len(t) < 2:
        return np.array([], dtype=np.int64)
    dt = np.diff(t)
    median_dt = float(np.median(dt))
    breaks = np.flatnonzero(dt > gap_factor * median_dt) + 1
    if len(breaks) and report:
        i = int(np.argmax(dt))
        warn_log(f"{source}: {len(breaks)} gap(s) longer than {gap_factor:g} × the median period "
                 f"{median_dt * 1e3:.3g} ms; longest {dt[i]:.4g} s at t = {t[i]:.6g} s; "
                 f"derivatives are computed separately between gaps", depth=1)
    return breaks


def check_joint_units(q, qd, qd_from_q, joint_names, source):
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
            f"exceed 2π rad in |q| ({', '.join(big)}); pass "
            f"{option_hint('position_unit', 'deg')}, or {option_hint('check_units', False)} "
            f"if they really turn that far"
        )
    if qd is None or np.sqrt(np.mean(qd_from_q**2)) < 0.01:
        return
    ratio = float(np.sum(qd * qd_from_q) / np.sum(qd_from_q**2))
    if not 0.5 < ratio < 2:
        raise LogError(
            f"{source}: given qd is {ratio:.3g} × the Savitzky–Golay derivative of q "
            f"(57.3 means deg/s next to rad; ~0 means not a measurement); fix its unit, "
            f"or compute them from q ({option_hint('velocities', None)}), or pass "
            f"{option_hint('check_units', False)}"
        )


# --- A uniform time grid ----------------------------------------------------------------------


def resample_uniform(frame: pd.DataFrame, time: str = TIME,
                     period: float | None = None) -> pd.DataFrame:
    """`frame` (a table with a strictly increasing time column `time`, s) on the uniform grid
    t₀ + k·`period` (default: the median time step) that spans it: numeric columns linearly
    interpolated; 0/1 columns (flags, one-row events such as ``tared``) and any others take
    the nearest row's value, and every row flagged 1 flags its nearest grid row, so that no
    event is lost. ``attrs`` are kept. Raises LogError for fewer than two rows or times that
    do not increase."""
    t = frame[time].to_numpy(dtype=float)
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise LogError(f"resampling needs a time column {time!r} that increases strictly, with "
                       "at least two rows")
    period = float(np.median(np.diff(t))) if period is None else float(period)
    grid = t[0] + period * np.arange(int(np.floor((t[-1] - t[0]) / period + 1e-9)) + 1)
    nearest = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    nearest -= (grid - t[nearest - 1]) < (t[nearest] - grid)
    out = {}
    for name in frame.columns:
        values = frame[name].to_numpy()
        flag = pd.api.types.is_numeric_dtype(values) and np.isin(values, (0, 1)).all()
        if name == time:
            out[name] = grid
        elif flag:
            kept = values[nearest].copy()
            onto = np.clip(np.rint((t[values == 1] - t[0]) / period).astype(int), 0,
                           len(grid) - 1)
            kept[onto] = 1
            out[name] = kept
        elif pd.api.types.is_numeric_dtype(values) and not pd.api.types.is_bool_dtype(values):
            out[name] = np.interp(grid, t, values.astype(float))
        else:
            out[name] = values[nearest]
    resampled = pd.DataFrame(out)
    resampled.attrs = dict(frame.attrs)
    return resampled

