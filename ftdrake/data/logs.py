"""Robot log tables (CSV, Parquet) into one validated record, and the checks every reader shares.

Tables are read here (:func:`read_frame`, :func:`read_table`); ROS bags in :mod:`.bag`. Every
reader returns a :class:`RobotLog`: time, joint positions, velocities, accelerations and
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
import fnmatch
import re
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from ..conventions import MEASURED, QD, QDD, TEMPERATURE, TIME, Q, joint_columns
from ..errors import LogError
from ..signals import causal_acceleration, savgol_derivative

MIN_ROWS = 10
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180}
_GLOB_CHARS = set("*?[")

QDD_ESTIMATES = ("savgol", "causal")
META_SCENARIO = b"ftdrake.scenario"  # Parquet metadata key of a `collect` dataset's scenario

Columns = str | re.Pattern | Sequence[str]


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


def _piecewise_derivative(x, t, breaks, deriv, window_s, polyorder):
    """Savitzky–Golay derivative computed separately on each segment between gaps."""
    dt = float(np.median(np.diff(t)))
    pieces = np.split(np.arange(len(t)), breaks)
    for i in pieces:
        if len(i) <= polyorder:
            raise LogError(
                f"the {len(i)} samples between gaps at t = {t[i[0]]:.6g}..{t[i[-1]]:.6g} s are "
                f"too few for a Savitzky–Golay fit of order {polyorder}; drop them or pass "
                f"{option_hint('sg_polyorder', polyorder - 1)}"
            )
    try:
        return np.concatenate(
            [savgol_derivative(x[i], dt, deriv, window_s, polyorder) for i in pieces]
        )
    except ValueError as e:  # too few samples for the fit
        raise LogError(f"{e}; pass a lower {option_hint('sg_polyorder', polyorder - 1)}") from None


def _piecewise_causal(qd, t, breaks, cutoff_hz):
    """The loop's causal q̈ estimate from `qd`, restarted (q̈ = 0) after every gap."""
    dt = float(np.median(np.diff(t)))
    pieces = np.split(np.arange(len(t)), breaks)
    return np.concatenate([causal_acceleration(qd[i], dt, cutoff_hz) for i in pieces])


# --- Validation shared by all readers ----------------------------------------------------------


def warn_log(message: str) -> None:
    """Issues a :class:`LogWarning` attributed to the reader's caller."""
    warnings.warn(message, LogWarning, stacklevel=3)


def _take(t, blocks, rows):
    """`t` and every array in `blocks` restricted to `rows` (a mask or an index array)."""
    return t[rows], {k: None if v is None else v[rows] for k, v in blocks.items()}


def assemble_log(
    t, q, qd, qdd, targets, target_names, joint_names, source, *,
    sort, t0, position_unit, sg_window, sg_polyorder, gap_factor, check_units,
    qdd_estimate="savgol", acceleration_cutoff_hz=25.0, temperature=None,
) -> RobotLog:
    """Cleans rows, checks units and fills missing derivatives; see the module docstring.

    `temperature` (N,), °C, if given, is cleaned with the rows and kept in the log.
    """
    if position_unit not in _ANGLE_UNITS:
        raise LogError(f"position_unit must be one of {list(_ANGLE_UNITS)}, got {position_unit!r}")
    if qdd_estimate not in QDD_ESTIMATES:
        raise LogError(f"qdd_estimate must be one of {list(QDD_ESTIMATES)}, got {qdd_estimate!r}")
    scale = _ANGLE_UNITS[position_unit]
    blocks = {"q": q, "qd": qd, "qdd": qdd, "targets": targets, "temperature": temperature}
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
        warn_log(f"{source}: dropped {bad.sum()} of {len(t)} rows with NaN/inf ({counts})")
        t, blocks = _take(t, blocks, ~bad)

    # Order and duplicates.
    n_back = int((np.diff(t) < 0).sum())
    if n_back:
        first = int(np.argmax(np.diff(t) < 0))
        where = f"first from {t[first]:.6g} to {t[first + 1]:.6g} s"
        if not sort:
            raise LogError(f"{source}: time goes backwards at {n_back} row(s) ({where}); if "
                           f"this file joins several recordings, add a column numbering them "
                           f"and pass {option_hint('group', 'COLUMN')} to read each apart, "
                           f"or sort the rows by time")
        warn_log(f"{source}: time goes backwards at {n_back} row(s) ({where}); rows sorted by time")
        t, blocks = _take(t, blocks, np.argsort(t, kind="stable"))
    dup = np.r_[False, np.diff(t) == 0]
    if dup.any():
        warn_log(f"{source}: dropped {dup.sum()} row(s) repeating an earlier timestamp "
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
        warn_log(f"{source}: {len(breaks)} gap(s) longer than {gap_factor:g} × the median period "
              f"{median_dt * 1e3:.3g} ms; longest {dt[i]:.4g} s at t = {t[i]:.6g} s; "
              f"derivatives are computed separately between gaps")

    q = blocks["q"]
    derived = [k for k in ("qd", "qdd") if blocks[k] is None]
    deriv = {k: _piecewise_derivative(q, t, breaks, d, sg_window, sg_polyorder)
             for d, k in ((1, "qd"), (2, "qdd"))}
    if check_units:
        _check_units(q, blocks["qd"], deriv["qd"], joint_names, source)
    qd = deriv["qd"] if blocks["qd"] is None else blocks["qd"]
    if blocks["qdd"] is None and qdd_estimate == "causal":
        deriv["qdd"] = _piecewise_causal(qd, t, breaks, acceleration_cutoff_hz)
    return RobotLog(
        t=t, q=q, qd=qd,
        qdd=deriv["qdd"] if blocks["qdd"] is None else blocks["qdd"],
        targets=blocks["targets"], target_names=list(target_names),
        joint_names=list(joint_names), source=source, derived=derived, t0=t0,
        temperature=None if blocks["temperature"] is None else blocks["temperature"][:, 0],
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


TABLE_SUFFIXES = (".csv", ".csv.gz", ".txt", ".parquet", ".pq")


def is_table(path: str | Path) -> bool:
    """True for a file name :func:`read_frame` reads (CSV or Parquet)."""
    return Path(path).name.endswith(TABLE_SUFFIXES)


def read_frame(path: str | Path, kind: str | None = None) -> pd.DataFrame:
    """The table at `path` (CSV or Parquet); the one place ftdrake reads a table file.

    `kind` (``"csv"`` or ``"parquet"``) overrides the format the file name suggests.
    A Parquet file's ``ftdrake.scenario`` metadata (a ``collect`` dataset's scenario YAML)
    is returned in ``frame.attrs["scenario"]`` (None when absent). Raises
    FileNotFoundError for a missing file and LogError for an unknown or unreadable one.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    kind = kind or ("csv" if path.name.endswith((".csv", ".csv.gz", ".txt")) else
                    "parquet" if path.suffix in (".parquet", ".pq") else None)
    if kind == "csv":
        try:
            frame = pd.read_csv(path)
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
            raise LogError(f"{path.name}: not a readable CSV file: {e}") from None
        frame.attrs["scenario"] = None
        return frame
    if kind == "parquet":
        try:
            table = pq.read_table(path)
        except Exception as e:  # noqa: BLE001 - any pyarrow failure: unreadable
            raise LogError(f"{path.name}: not a readable Parquet file: {e}") from None
        frame = table.to_pandas()
        scenario = (table.schema.metadata or {}).get(META_SCENARIO)
        frame.attrs["scenario"] = scenario.decode() if scenario else None
        return frame
    raise LogError(f"{path}: unknown table format; expected .csv or .parquet")


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
    qdd_estimate: str = "savgol",
    acceleration_cutoff_hz: float = 25.0,
    temperature: str | None = None,
    label: str | None = None,
) -> RobotLog:
    """Reads a CSV or Parquet log (or a DataFrame) with named columns.

    Args:
      source: ``.csv`` / ``.csv.gz`` / ``.parquet`` path, or a DataFrame.
      positions, targets, velocities, accelerations: columns, see :func:`expand_columns`
        (``"q_*"``, ``re.compile(r"q_\\d+")``, or a list of names). Velocities or
        accelerations left None are computed from the positions (see `qdd_estimate`).
      time: time column (numbers in `time_unit`, or datetimes); None: rows are sampled at
        `rate_hz`.
      position_unit: ``"rad"`` or ``"deg"``; the angle unit of the position, velocity and
        acceleration columns (converted to rad, rad/s, rad/s²).
      sg_window, sg_polyorder: Savitzky–Golay window (s) and order, see
        :func:`ftdrake.signals.savgol_derivative`.
      gap_factor: a step longer than this × the median period is a gap.
      check_units: raise on degree-like positions and on given velocities that disagree with
        the derivative of the positions (see the module docstring).
      qdd_estimate: how missing accelerations are computed: ``"savgol"`` (Savitzky–Golay of
        q, non-causal) or ``"causal"`` (:func:`ftdrake.signals.causal_acceleration` of q̇ at
        `acceleration_cutoff_hz`, the estimate ``CompensatorSystem`` makes in the loop).
      temperature: the sensor's temperature column (°C), kept as ``RobotLog.temperature``
        (a model then takes it as X's last column); None: not read.
      label: the name errors and warnings give the source (default: the file name, or
        ``"DataFrame"``).
    """
    frame, label, cols, selected = _select_columns(
        source, label, positions, velocities, accelerations, targets, temperature)
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
        try:
            expand_columns([time], cols, f"{label} time")
        except LogError as e:
            raise LogError(f"{e}; choose it with {option_hint('time', 'COLUMN')}") from None
        if time_unit not in _TIME_UNITS:
            raise LogError(f"time_unit must be one of {list(_TIME_UNITS)}, got {time_unit!r}")
        col = frame[time]
        if pd.api.types.is_datetime64_any_dtype(col):
            t0 = col.iloc[0].timestamp()
            t = (col - col.iloc[0]).dt.total_seconds().to_numpy()
        else:
            t = _numeric(frame, [time], label)[:, 0] * _TIME_UNITS[time_unit]
    arrays = {what: _numeric(frame, names, label) for what, names in selected.items()}
    return assemble_log(
        t, arrays["positions"], arrays.get("velocities"), arrays.get("accelerations"),
        arrays["targets"], selected["targets"], selected["positions"], label,
        sort=False, t0=t0, position_unit=position_unit, sg_window=sg_window,
        sg_polyorder=sg_polyorder, gap_factor=gap_factor, check_units=check_units,
        qdd_estimate=qdd_estimate, acceleration_cutoff_hz=acceleration_cutoff_hz,
        temperature=arrays.get("temperature"),
    )


def read_static_table(
    source: str | Path | pd.DataFrame,
    positions: Columns = "q_*",
    targets: Columns = f"{MEASURED}_*",
    *,
    position_unit: str = "rad",
    check_units: bool = True,
    temperature: str | None = None,
    label: str | None = None,
) -> RobotLog:
    """Reads a table of static poses: one pose held still and its reading a row.

    What ``ftdrake calibrate`` takes (a calibration log is often such a table, with no time
    column): joint positions and targets (and the temperature, °C, if named); velocities and
    accelerations are zero (the robot is still; nothing to differentiate), and ``t`` is the
    row number (no time; rows are independent). Rows with NaN/inf are dropped with a
    :class:`LogWarning`; degree-like positions raise unless `check_units` is False.
    """
    frame, label, _, selected = _select_columns(source, label, positions, None, None, targets,
                                                temperature)
    if position_unit not in _ANGLE_UNITS:
        raise LogError(f"position_unit must be one of {list(_ANGLE_UNITS)}, got {position_unit!r}")
    arrays = {what: _numeric(frame, names, label) for what, names in selected.items()}
    q = arrays["positions"] * _ANGLE_UNITS[position_unit]
    bad = ~np.isfinite(np.hstack(list(arrays.values()))).all(axis=1)
    if bad.any():
        warn_log(f"{label}: dropped {bad.sum()} of {len(bad)} rows with NaN/inf")
    keep = ~bad
    if keep.sum() < 1:
        raise LogError(f"{label}: no usable rows")
    q = q[keep]
    if check_units:
        _check_units(q, None, np.zeros_like(q), selected["positions"], label)
    T = arrays.get("temperature")
    return RobotLog(
        t=np.flatnonzero(keep).astype(float), q=q, qd=np.zeros_like(q), qdd=np.zeros_like(q),
        targets=arrays["targets"][keep], target_names=list(selected["targets"]),
        joint_names=list(selected["positions"]), source=f"{label} (static poses)",
        temperature=None if T is None else T[keep, 0],
    )


def _select_columns(source, label, positions, velocities, accelerations, targets, temperature):
    """(frame, label, column names, {what: selected columns}) of a table or DataFrame."""
    if isinstance(source, pd.DataFrame):
        frame, name = source, "DataFrame"
    else:
        frame, name = read_frame(source), Path(source).name
    label = label or name
    cols = [str(c) for c in frame.columns]
    frame = frame.set_axis(cols, axis=1).reset_index(drop=True)
    selected = {}
    for what, spec in [("positions", positions), ("velocities", velocities),
                       ("accelerations", accelerations), ("targets", targets)]:
        if spec is not None:
            try:
                selected[what] = expand_columns(spec, cols, f"{label} {what}")
            except LogError as e:
                raise LogError(f"{e}; choose them with {option_hint(what, 'PATTERN')}") from None
    if temperature is not None:
        if temperature not in cols:
            raise LogError(f"{label}: no temperature column {temperature!r} (the sensor's "
                           f"temperature, °C); available columns: {cols}; choose it with "
                           f"{option_hint('temperature', 'COLUMN')}")
        selected["temperature"] = [temperature]
    return frame, label, cols, selected
