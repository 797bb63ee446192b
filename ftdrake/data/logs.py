"""Robot log tables (CSV, Parquet) into one validated :class:`~.robot_log.RobotLog`.

:func:`read_frame` reads a table file (the one place ftdrake does); :func:`read_table` picks
the time, joint and target columns (globs, regexes or names, :func:`expand_columns`) and
passes them through the checks every reader shares (:mod:`.robot_log`); ROS bags are read
in :mod:`.bag`. The record, its warning and the option hints are re-exported here.

Units: time in s (``time_unit`` converts), joint positions in rad (``position_unit``
converts), velocities in rad/s, accelerations in rad/s²; targets as logged.
"""

from __future__ import annotations

import difflib
import fnmatch
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..conventions import LOG_FORMAT, MEASURED, QD, QDD, TIME, Q, legacy_renames
from ..errors import LogError
from ..io import atomic_path
from ..signals import DEFAULT_ACCELERATION_CUTOFF_HZ
from .robot_log import (
    ANGLE_UNITS,
    MIN_ROWS,
    QDD_ESTIMATES,
    LogWarning,
    RobotLog,
    assemble_log,
    check_joint_units,
    option_hint,
    option_spelling,
    warn_log,
)

__all__ = [
    "MIN_ROWS",
    "QDD_ESTIMATES",
    "LogError",
    "LogWarning",
    "RobotLog",
    "assemble_log",
    "column_spec",
    "expand_columns",
    "is_table",
    "missing_time_message",
    "natural_key",
    "option_hint",
    "option_spelling",
    "read_frame",
    "read_static_table",
    "read_table",
    "time_columns",
    "warn_log",
    "write_log",
]

_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_GLOB_CHARS = set("*?[")
META_SCENARIO = b"ftdrake.scenario"  # Parquet metadata key of a `collect` dataset's scenario
#: Parquet metadata key of the log layout's version (conventions.LOG_FORMAT; absent: unknown).
META_LOG_FORMAT = b"ftdrake.log_format"

Columns = str | re.Pattern | Sequence[str]


# --- Column selection ------------------------------------------------------------------------


def natural_key(name: str) -> list:
    """Sort key that orders ``q_2`` before ``q_10``."""
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", name)]


def column_spec(spec: Columns | None) -> Columns | None:
    """A column option as :func:`expand_columns` matches it: ``"re:PATTERN"`` → a compiled
    regex, ``"a,b"`` → the list of names, anything else as it is (a glob, a name, a list,
    a compiled regex, None)."""
    if not isinstance(spec, str):
        return spec
    if spec.startswith("re:"):
        try:
            return re.compile(spec[3:])
        except re.error as e:
            raise LogError(f"{spec!r}: not a regular expression: {e}") from None
    if "," in spec:
        return [s.strip() for s in spec.split(",") if s.strip()]
    return spec


def expand_columns(spec: Columns, available: Sequence[str], what: str = "columns",
                   option: str | None = None) -> list[str]:
    """Column names selected by `spec`: the one column syntax of every reader and command.

    `spec` is a glob (``"q_*"``, any of ``* ? [``), a regular expression (``"re:q_\\d+"`` or
    ``re.compile(r"q_\\d+")``, full match), a comma-separated list of names (``"a,b"``), an
    exact column name, or a list of exact names (kept in the given order). Pattern matches
    are returned in natural order. Raises LogError, naming `what` and listing the available
    columns, when nothing matches or a listed name is missing. A pattern that matches more
    than one kind of indexed column (``q*`` matching ``q_0..``, ``qd_0..`` and ``qdd_0..``)
    issues a :class:`LogWarning` naming them and a narrower pattern for `option` (the reader
    keyword, e.g. ``"positions"``; see :func:`option_hint`).
    """
    available = list(available)
    spec = column_spec(spec)
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
    if label.startswith(("regex", "pattern")):
        _warn_if_mixed_kinds(found, what, label, option)
    return found


def _warn_if_mixed_kinds(found: list[str], what: str, label: str, option: str | None) -> None:
    """A LogWarning when `found` holds several kinds of indexed columns (q_0.., qd_0..)."""
    kinds: dict[str, list[str]] = {}
    for name in found:
        indexed = re.fullmatch(r"(.*?[^\d])(\d+)", name)
        kinds.setdefault(indexed.group(1) if indexed else name, []).append(name)
    several = {k: v for k, v in kinds.items() if len(v) > 1}
    if len(several) < 2:
        return
    groups = ", ".join(f"{v[0]}..{v[-1]}" for v in several.values())
    first = next(iter(several))
    fix = f"'{first}*'"
    if option is not None:
        regex = "re:" + re.escape(first) + r"\d+"
        fix = f"{option_hint(option, first + '*')} or {option_hint(option, regex)}"
    warn_log(f"{what}: {label} matches {len(several)} kinds of columns ({groups}), "
             f"{len(found)} columns in all; if only one kind is meant, narrow it: {fix}",
             depth=1)


def _span(names: Sequence[str]) -> str:
    """``q_0..q_6`` for a run of indexed names, else the names."""
    return f"{names[0]}..{names[-1]}" if len(names) > 2 else ", ".join(names)


def _indexed_kinds(names: Sequence[str]) -> dict[str, list[str]]:
    """Names grouped by their stem before a trailing index (``qd_`` → qd_0, qd_1 …)."""
    kinds: dict[str, list[str]] = {}
    for name in names:
        indexed = re.fullmatch(r"(.*?[^\d])(\d+)", name)
        kinds.setdefault(indexed.group(1) if indexed else name, []).append(name)
    return kinds


_SINGULAR = {"velocities": "velocity", "accelerations": "acceleration"}


def count_mismatch_message(label: str, what: str, spec, found: Sequence[str],
                           positions: Sequence[str]) -> str:
    """The error for a `what` option (``"velocities"``) that selects a number of columns other
    than the positions': the columns it matched, grouped, and a pattern that matches one per
    position when the log has such a group (``re:qd_\\d+`` among qd_0.. and qdd_0..)."""
    spec_text = spec.pattern if isinstance(spec, re.Pattern) else spec
    kinds = _indexed_kinds(found)
    groups = ", ".join(_span(v) for v in kinds.values())
    message = (f"{label}: {option_hint(what, spec_text)} matched {len(found)} columns "
               f"({groups}) for {len(positions)} positions ({_span(positions)}); "
               f"one {_SINGULAR[what]} column per position is needed")
    fits = [stem for stem, v in kinds.items() if len(v) == len(positions)]
    if not fits:
        return f"{message}: choose them with {option_hint(what, 'PATTERN')}"
    literal = str(spec_text).rstrip("*?[")
    stem = max(fits, key=lambda k: difflib.SequenceMatcher(None, literal, k).ratio())
    regex = "re:" + re.escape(stem) + r"\d+"
    return (f"{message}: {regex} matches {len(positions)} ({_span(kinds[stem])}): "
            f"{option_hint(what, regex)}")


#: The names a log's recorded velocities and accelerations usually have, by the positions'
#: stem: ``q_0..`` → ``qd_0..``, ``qdd_0..`` (ftdrake's own, :mod:`~ftdrake.conventions`).
_DERIVATIVE_STEMS = {"velocities": (QD,), "accelerations": (QDD,)}


def recorded_derivatives(columns: Sequence[str], positions: Sequence[str]) -> dict:
    """{``"velocities"``/``"accelerations"``: (regex option, names)} for the derivatives a table
    records under the usual names of its `positions` (one column per position, same index)."""
    kinds = _indexed_kinds(positions)
    if len(kinds) != 1:
        return {}
    stem, = kinds
    if not stem.startswith(Q):
        return {}
    indices = [p[len(stem):] for p in positions]
    found = {}
    for what, stems in _DERIVATIVE_STEMS.items():
        for other in stems:
            names = [other + stem[len(Q):] + i for i in indices]
            if all(n in columns for n in names):
                found[what] = ("re:" + re.escape(other + stem[len(Q):]) + r"\d+", names)
                break
    return found


_TIME_NAMES = ("t", "time", "times", "timestamp", "timestamps", "stamp", "time_s", "sec",
               "secs", "seconds", "elapsed")


def time_columns(columns: Sequence[str]) -> list[str]:
    """The columns whose name says they hold time (``t``, ``time``, ``timestamp``,
    ``header.stamp``, ``time_ns`` …), in table order."""
    def is_time(name: str) -> bool:
        low = re.sub(r"[^a-z0-9]+", "_", str(name).lower()).strip("_")
        parts = low.split("_")
        return low in _TIME_NAMES or any(p in ("time", "timestamp", "stamp") for p in parts)

    return [str(c) for c in columns if is_time(c)]


def missing_time_message(label: str, time: str, columns: Sequence[str]) -> str:
    """The error for a table without the time column `time`: the time-like columns it has
    and the option (``--time``; ``time=`` in Python) that names one."""
    found = time_columns(columns)
    if found:
        return (f"{label}: no time column {time!r}; the table has {found}: choose it with "
                f"{option_hint('time', found[0])}")
    return (f"{label}: no time column {time!r}; available columns: {list(columns)}; choose "
            f"it with {option_hint('time', 'COLUMN')}")


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
    is returned in ``frame.attrs["scenario"]`` (None when absent). A log written before
    :data:`~ftdrake.conventions.LOG_FORMAT` 2 gets today's column names
    (:func:`~ftdrake.conventions.legacy_renames`: ``pred_*`` → ``wrench_internal_*``,
    ``detected`` → ``contact``, ``contact`` → ``contact_true`` …), by the version its Parquet
    metadata says, else (a CSV file, a Parquet file of another writer) by its columns. Raises
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
        return _current_names(frame, None)
    if kind == "parquet":
        try:
            table = pq.read_table(path)
        except Exception as e:  # noqa: BLE001 - any pyarrow failure: unreadable
            raise LogError(f"{path.name}: not a readable Parquet file: {e}") from None
        frame = table.to_pandas()
        metadata = table.schema.metadata or {}
        scenario = metadata.get(META_SCENARIO)
        frame.attrs["scenario"] = scenario.decode() if scenario else None
        version = metadata.get(META_LOG_FORMAT)
        return _current_names(frame, int(version) if version else None)
    raise LogError(f"{path}: unknown table format; expected .csv or .parquet")


def _current_names(frame: pd.DataFrame, log_format: int | None) -> pd.DataFrame:
    renames = legacy_renames(frame.columns, log_format)
    if renames:
        attrs = dict(frame.attrs)
        frame = frame.rename(columns=renames)
        frame.attrs = {**attrs, "renamed_columns": renames}
    return frame


def write_log(frame: pd.DataFrame, path: str | Path) -> None:
    """Writes a log table atomically: CSV for a ``.csv`` name, else Parquet stamped with the
    layout's version (``ftdrake.log_format``: :data:`~ftdrake.conventions.LOG_FORMAT`) and
    with ``frame.attrs["scenario"]`` as its ``ftdrake.scenario`` when there is one."""
    path = Path(path)
    with atomic_path(path) as tmp:
        if path.name.endswith((".csv", ".csv.gz")):
            frame.to_csv(tmp, index=False)
            return
        table = pa.Table.from_pandas(frame, preserve_index=False)
        metadata = {**(table.schema.metadata or {}), META_LOG_FORMAT: str(LOG_FORMAT).encode()}
        if frame.attrs.get("scenario"):
            metadata[META_SCENARIO] = str(frame.attrs["scenario"]).encode()
        pq.write_table(table.replace_schema_metadata(metadata), tmp)


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
    acceleration_cutoff_hz: float = DEFAULT_ACCELERATION_CUTOFF_HZ,
    temperature: str | None = None,
    label: str | None = None,
    min_rows: int = MIN_ROWS,
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
      min_rows: fewer usable rows raise LogError (one trajectory of a file of several may
        be short: its derivatives adapt, see :func:`~.robot_log.assemble_log`).
    """
    frame, label, cols, selected = _select_columns(
        source, label, positions, velocities, accelerations, targets, temperature)
    for what, spec in (("velocities", velocities), ("accelerations", accelerations)):
        if what in selected and len(selected[what]) != len(selected["positions"]):
            raise LogError(count_mismatch_message(label, what, spec, selected[what],
                                                  selected["positions"]))

    t0 = 0.0
    if time is None:
        if not rate_hz:
            raise LogError(f"{label}: without a time column, pass rate_hz")
        t = np.arange(len(frame)) / rate_hz
    else:
        if time not in cols:
            raise LogError(missing_time_message(label, time, cols))
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
        temperature=arrays.get("temperature"), min_rows=min_rows,
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
    if position_unit not in ANGLE_UNITS:
        raise LogError(f"position_unit must be one of {list(ANGLE_UNITS)}, got {position_unit!r}")
    arrays = {what: _numeric(frame, names, label) for what, names in selected.items()}
    q = arrays["positions"] * ANGLE_UNITS[position_unit]
    bad = ~np.isfinite(np.hstack(list(arrays.values()))).all(axis=1)
    if bad.any():
        warn_log(f"{label}: dropped {bad.sum()} of {len(bad)} rows with NaN/inf")
    keep = ~bad
    if keep.sum() < 1:
        raise LogError(f"{label}: no usable rows")
    q = q[keep]
    if check_units:
        check_joint_units(q, None, np.zeros_like(q), selected["positions"], label)
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
                selected[what] = expand_columns(spec, cols, f"{label} {what}", option=what)
            except LogError as e:
                derive = (f", or compute them from q ({option_hint(what, None)})"
                          if what in ("velocities", "accelerations") else "")
                raise LogError(f"{e}; choose them with {option_hint(what, 'PATTERN')}{derive}"
                               ) from None
    if temperature is not None:
        if temperature not in cols:
            raise LogError(f"{label}: no temperature column {temperature!r} (the sensor's "
                           f"temperature, °C); available columns: {cols}; choose it with "
                           f"{option_hint('temperature', 'COLUMN')}")
        selected["temperature"] = [temperature]
    return frame, label, cols, selected
