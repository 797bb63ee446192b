"""Training data from any log: the loader ``train``, ``evaluate``, the study and the demo share.

:func:`load_training_data` reads a table (CSV/Parquet, :mod:`.logs`) or a ROS bag
(:mod:`.bag`) into the model layout ``X = [q, q̇, q̈]`` (rad, rad/s, rad/s²) and targets ``Y``
(a wrench in N, N·m, or joint torques in N·m; any number of columns), as a
:class:`TrainingData`. How the log is read is one :class:`ReadOptions` value: its fields are
the keywords of the readers and the ``ftdrake train`` flags (``positions`` ↔ ``--positions``),
and a model file's manifest keeps it (``extra.data.options``), so ``evaluate`` reads new data
the way the model was trained.

A table with a ``trajectory`` column (``ftdrake collect``'s datasets; ``ReadOptions.group``
names another) is read per trajectory: time restarts in each, derivatives never cross from
one into the next, and ``TrainingData.groups`` keeps them apart for grouped cross-validation.
``ReadOptions.dataset("est")`` reads a ``collect`` dataset exactly as
:func:`~.dataset.joint_state_layout` and :func:`~.dataset.wrench_targets` do.

``ReadOptions.temperature`` names the sensor's temperature column (°C): it becomes X's last
column, ``[q, q̇, q̈, T]`` (what every compensator takes as a temperature input). A table of
static poses without a time column (what ``ftdrake calibrate`` takes) is read with
``static_poses`` (q̇ = q̈ = 0; :func:`~.logs.read_static_table`).
"""

from __future__ import annotations

import dataclasses as dc
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ..config import CompensatorConfig, parse_config
from ..conventions import MEASURED, QD, QD_EST, QDD, QDD_EST, TIME, TRAJECTORY, Q
from ..errors import ConfigError, LogError
from .bag import is_bag, message_count, read_bag
from .logs import (
    MIN_ROWS,
    QDD_ESTIMATES,
    LogWarning,
    RobotLog,
    column_spec,
    expand_columns,
    is_table,
    option_hint,
    read_frame,
    read_static_table,
    read_table,
    recorded_derivatives,
    warn_log,
)

TABLE_DEFAULTS = {"positions": f"{Q}_*", "targets": f"{MEASURED}_*", "time": TIME}
BAG_JOINT_TOPIC = "/joint_states"


@dc.dataclass(frozen=True)
class ReadOptions:
    """Everything about how a log is read, with its defaults; kept in a model's manifest.

    Column options (`positions`, `targets`, `velocities`, `accelerations`) are a glob
    (``"q_*"``), a comma-separated list of names, or a regular expression after ``re:``
    (``"re:qd_\\d+"``); None is the default. For bags, `positions` selects JointState joint
    names (default: all); `targets` is ``effort`` (default) or ``wrench`` (default with
    `wrench_topic`) or selects among the names read (``tau_0..``, ``meas_Fx..``); velocities
    are the messages' own.

    Attributes:
      positions: joint position columns (rad); default ``q_*``.
      targets: target columns; default ``meas_*``.
      velocities: velocity columns (rad/s); None or ``"derive"``: Savitzky–Golay derivative
        of q (``"derive"`` also overrides columns a model's manifest names).
      accelerations: acceleration columns (rad/s²); None or ``"derive"``: computed, see
        `qdd_estimate`.
      time: time column (s); default ``t``.
      group: trajectory id column; default ``trajectory`` when the table has one.
      joint_topic: a bag's JointState topic; default ``/joint_states``.
      wrench_topic: a bag's WrenchStamped topic; default none.
      position_unit: ``"rad"`` or ``"deg"`` (positions, velocities, accelerations).
      check_units: refuse degree-like positions and velocities that disagree with q.
      qdd_estimate: how missing accelerations are computed. ``"savgol"`` (default): the
        Savitzky–Golay second derivative of q, non-causal, best for offline fits.
        ``"causal"``: :func:`ftdrake.signals.causal_acceleration` of q̇, the estimate
        ``CompensatorSystem`` makes in the loop (which has no q̈ sensor and cannot look
        ahead). Use it for a ``q,qd,qdd`` model that will run in the loop: trained on a
        Savitzky–Golay q̈, it sees at run time a causal, noisier q̈, i.e. inputs unlike
        those it was fitted on.
      acceleration_cutoff_hz: the causal estimate's cut-off (Hz); None: the
        scenario's ``compensator.acceleration_cutoff_hz`` when the file carries one (a
        ``collect`` dataset), else that field's default (12 Hz). Set it to the cut-off of the
        loop the model will run in.
      sg_window, sg_polyorder: Savitzky–Golay window (s) and order, see
        :func:`ftdrake.signals.savgol_derivative`.
      gap_factor: a time step longer than this × the median period is a gap.
      temperature: the sensor's temperature column (°C, tables only); read as X's last
        column, so that a model learns (and at run time applies) its zero drift. None: no
        temperature input.
    """

    positions: str | None = None
    targets: str | None = None
    velocities: str | None = None
    accelerations: str | None = None
    time: str | None = None
    group: str | None = None
    joint_topic: str | None = None
    wrench_topic: str | None = None
    position_unit: str = "rad"
    check_units: bool = True
    qdd_estimate: str = "savgol"
    acceleration_cutoff_hz: float | None = None
    sg_window: float = 0.1
    sg_polyorder: int = 4
    gap_factor: float = 3.0
    temperature: str | None = None

    def __post_init__(self):
        if self.qdd_estimate not in QDD_ESTIMATES:
            raise ConfigError(f"qdd_estimate must be one of {list(QDD_ESTIMATES)}, "
                              f"got {self.qdd_estimate!r}")
        if self.position_unit not in ("rad", "deg"):
            raise ConfigError(f"position_unit must be 'rad' or 'deg', got {self.position_unit!r}")
        for name in ("sg_window", "gap_factor"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be positive, got {getattr(self, name)!r}")
        cutoff = self.acceleration_cutoff_hz
        if cutoff is not None and not cutoff > 0:
            raise ConfigError(f"acceleration_cutoff_hz must be positive, got {cutoff!r}")

    @classmethod
    def dataset(cls, source: str = "est", **overrides) -> ReadOptions:
        """Options that read a ``collect`` dataset as :func:`~.dataset.joint_state_layout`
        (`source` ``"est"``: the loop's q̇ and causal q̈; ``"plant"``: the simulator's values) and
        :func:`~.dataset.wrench_targets` do."""
        if source not in ("est", "plant"):
            raise ConfigError(f"source must be 'est' or 'plant', got {source!r}")
        qd, qdd = (QD_EST, QDD_EST) if source == "est" else (QD, QDD)
        return cls(positions=rf"re:{Q}_\d+", velocities=rf"re:{qd}_\d+",
                   accelerations=rf"re:{qdd}_\d+", targets=f"{MEASURED}_*", **overrides)

    def to_dict(self) -> dict:
        """The options as plain JSON values (as stored in a manifest)."""
        return dc.asdict(self)

    @classmethod
    def from_dict(cls, values: Mapping | None) -> ReadOptions:
        """Options from :meth:`to_dict` output (or an older manifest's subset of it)."""
        values = dict(values or {})
        known = {f.name for f in dc.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ConfigError(f"unknown read options {unknown}; known: {sorted(known)}")
        return cls(**{k: v for k, v in values.items() if v is not None})

    def updated(self, **given) -> ReadOptions:
        """These options with every value in `given` that is not None replacing its own."""
        return dc.replace(self, **{k: v for k, v in given.items() if v is not None})


@dc.dataclass
class TrainingData:
    """The rows of a log (or of several trajectories in one table) in the model layout.

    X: (N, 3n) ``[q, q̇, q̈]`` in rad, rad/s, rad/s², with the temperature (°C) as one more,
    last column when ``options.temperature`` names one. Y: (N, m) targets as logged.
    t: (N,) time in s (a static table's: the row number). groups: (N,) trajectory id per row
    (0 for a single log).
    rows: counts in the file, after the reader, outside the time window, used.
    options: the options read with (`acceleration_cutoff_hz` resolved).
    derivation: how each computed column (``"qd"``, ``"qdd"``) was computed.
    """

    X: np.ndarray
    Y: np.ndarray
    t: np.ndarray
    groups: np.ndarray
    joint_names: list[str]
    target_names: list[str]
    derived: list[str]
    source: str
    rows: dict
    kind: str = "table"  # or "bag"
    options: ReadOptions = dc.field(default_factory=ReadOptions)
    warnings: list[str] = dc.field(default_factory=list)
    scenario_yaml: str | None = None  # a `collect` dataset's scenario
    static: bool = False  # a table of static poses (q̇ = q̈ = 0, no time column)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def has_temperature(self) -> bool:
        """Whether X carries the sensor temperature (°C) as its last column."""
        return self.X.shape[1] == 3 * self.n_joints + 1

    @property
    def derivation(self) -> dict:
        o = self.options
        savgol = {"method": "savitzky_golay", "window_s": o.sg_window,
                  "polyorder": o.sg_polyorder}
        causal = {"method": "causal", "cutoff_hz": o.acceleration_cutoff_hz,
                  "signal": "causal_acceleration of qd"}
        return {k: causal if k == "qdd" and o.qdd_estimate == "causal" else savgol
                for k in self.derived}


def load_training_data(
    path: str | Path | pd.DataFrame,
    options: ReadOptions | None = None,
    *,
    t_start: float | None = None,
    t_end: float | None = None,
    report: Callable[[str], None] | None = None,
    static_poses: bool | None = False,
) -> TrainingData:
    """Reads `path` (CSV/Parquet table, ROS 1 ``.bag`` file or ROS 2 bag folder), or a
    table already in memory (a ``pandas.DataFrame``, read as a table file is; messages call
    it ``DataFrame``; a ``collect`` dataset's scenario is its ``attrs["scenario"]``).

    `static_poses`: True reads a table as static poses (:func:`~.logs.read_static_table`:
    q̇ = q̈ = 0, no time column needed, nothing differentiated); None does so when the table
    has no time column (``options.time``, default ``t``); False never (a missing time
    column is an error).

    Derivatives are computed on the whole log (per trajectory) first; then only the rows with
    `t_start` ≤ t ≤ `t_end` (s, on the log's own time axis: a table's time column, a bag's
    time since its first joint state) are kept. Each :class:`~.logs.LogWarning` is passed to
    `report` (one line, if given) and kept in ``TrainingData.warnings``.

    Raises LogError (an :class:`~ftdrake.errors.FtdrakeError`) for a missing or unreadable
    file and for every check the log fails; the message names the option that fixes it.
    """
    options = options or ReadOptions()
    in_memory = isinstance(path, pd.DataFrame)
    if not in_memory:
        path = Path(path)
        if not path.exists():
            raise LogError(f"{path}: no such file or folder")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LogWarning)
        if in_memory:
            data = _table_data(path, IN_MEMORY, options, static_poses)
        elif is_bag(path):
            data = _read_bag(path, options)
        else:
            data = _read_table(path, options, static_poses)
    for w in caught:
        if issubclass(w.category, LogWarning):
            data.warnings.append(str(w.message))
            if report is not None:
                report(f"warning: {w.message}")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if data.static and (t_start is not None or t_end is not None):
        name = IN_MEMORY if in_memory else path.name
        raise LogError(f"{name}: a table of static poses has no time axis; "
                       f"{option_hint('t_start', None)} and {option_hint('t_end', None)}")
    return _time_window(data, t_start, t_end)


#: What messages call a table given in memory (a DataFrame) instead of a file.
IN_MEMORY = "DataFrame"

#: A velocities/accelerations option that computes them from q (``--accelerations derive``),
#: e.g. for `evaluate` on a log without the columns the model was trained with.
DERIVED = "derive"


def _columns_or_derived(value: str | None) -> str | None:
    return None if value == DERIVED else value


def _cutoff(options: ReadOptions, scenario_yaml: str | None, label: str) -> float:
    """The causal estimate's cut-off: given, else the scenario's, else the config default."""
    if options.acceleration_cutoff_hz is not None:
        return float(options.acceleration_cutoff_hz)
    if scenario_yaml:
        return float(parse_config(scenario_yaml, source=f"{label} metadata")
                     .chain.compensator.acceleration_cutoff_hz)
    return float(CompensatorConfig().acceleration_cutoff_hz)


def _reader_keywords(options: ReadOptions, cutoff: float) -> dict:
    return {"position_unit": options.position_unit, "check_units": options.check_units,
            "sg_window": options.sg_window, "sg_polyorder": options.sg_polyorder,
            "gap_factor": options.gap_factor, "qdd_estimate": options.qdd_estimate,
            "acceleration_cutoff_hz": cutoff}


def _read_table(path: Path, options: ReadOptions, static_poses: bool | None = False
                ) -> TrainingData:
    if not is_table(path):
        raise LogError(f"{path}: unknown format; expected .csv, .parquet, a .bag file or a "
                       f"ROS 2 bag folder")
    return _table_data(read_frame(path), path.name, options, static_poses)


def _table_data(frame: pd.DataFrame, name: str, options: ReadOptions,
                static_poses: bool | None = False) -> TrainingData:
    """The rows of table `frame` (`name`: the file's name, for messages)."""
    scenario = frame.attrs.get("scenario") or None
    cutoff = _cutoff(options, scenario, name)
    time = options.time or TABLE_DEFAULTS["time"]
    if static_poses or (static_poses is None and time not in frame.columns):
        return _read_static(frame, name, options, cutoff)
    kwargs = {
        "positions": column_spec(options.positions or TABLE_DEFAULTS["positions"]),
        "targets": column_spec(options.targets or TABLE_DEFAULTS["targets"]),
        "velocities": column_spec(_columns_or_derived(options.velocities)),
        "accelerations": column_spec(_columns_or_derived(options.accelerations)),
        "time": time,
        "temperature": options.temperature,
        **_reader_keywords(options, cutoff),
    }
    group = options.group
    if group is None and TRAJECTORY in frame.columns:
        group = TRAJECTORY
    if group is None:
        logs, ids = [read_table(frame, label=name, **kwargs)], [0]
    else:
        if group not in frame.columns:
            raise LogError(f"{name}: no group column {group!r}; available columns: "
                           f"{list(frame.columns)}; choose it with "
                           f"{option_hint('group', 'COLUMN')}")
        ids = list(pd.unique(frame[group]))
        # One short trajectory does not stop the others: its derivatives adapt to its length
        # (a warning counts them); only the whole file must have MIN_ROWS.
        logs = [read_table(frame[frame[group] == i].reset_index(drop=True),
                           label=f"{name} [{group}={i}]", min_rows=2, **kwargs)
                for i in ids]
        rows = sum(len(log) for log in logs)
        if rows < MIN_ROWS:
            raise LogError(f"{name}: only {rows} usable rows in {len(ids)} trajectories; "
                           f"need at least {MIN_ROWS}")
    data = _stack(logs, ids, name)
    _note_recorded_derivatives(data.joint_names, frame.columns, options, name)
    data.rows["in_file"] = len(frame)
    data.scenario_yaml = scenario
    data.options = dc.replace(options, acceleration_cutoff_hz=cutoff)
    return data


def _note_recorded_derivatives(positions, columns, options: ReadOptions, label: str) -> None:
    """A LogWarning when the table records velocities or accelerations under the usual names
    (qd_0.., qdd_0..) that are computed from q instead because no option chose them (the
    option ``derive`` chooses computing them, and silences this)."""
    recorded = recorded_derivatives([str(c) for c in columns], positions)
    unused = {w: v for w, v in recorded.items() if getattr(options, w) is None}
    if not unused:
        return
    how = {"velocities": "Savitzky–Golay derivative of q",
           "accelerations": ("causal estimate from q̇" if options.qdd_estimate == "causal"
                             else "Savitzky–Golay second derivative of q")}
    said = "; ".join(f"{w} {v[1][0]}..{v[1][-1]} (computed instead: {how[w]})"
                     for w, v in unused.items())
    use = " ".join(option_hint(w, v[0]) for w, v in unused.items())
    keep = " ".join(option_hint(w, DERIVED) for w in unused)
    warn_log(f"{label}: the log records {said}; to use the recorded ones: {use} (to compute "
             f"them and not see this: {keep})")


def _read_static(frame, name: str, options: ReadOptions, cutoff: float) -> TrainingData:
    """A table of static poses (one pose and its reading a row; q̇ = q̈ = 0)."""
    log = read_static_table(
        frame, column_spec(options.positions or TABLE_DEFAULTS["positions"]),
        column_spec(options.targets or TABLE_DEFAULTS["targets"]),
        position_unit=options.position_unit, check_units=options.check_units,
        temperature=options.temperature, label=name)
    data = _stack([log], [0], name)
    data.rows["in_file"] = len(frame)
    data.static = True
    data.options = dc.replace(options, acceleration_cutoff_hz=cutoff)
    return data


def _read_bag(path: Path, options: ReadOptions) -> TrainingData:
    """A bag's JointState rows; `positions`/`targets` select joints and targets by name."""
    if options.temperature is not None:
        raise LogError(f"{path.name}: a bag has no temperature column; "
                       f"{option_hint('temperature', None)} (the temperature input reads a "
                       f"table column, °C)")
    positions, targets = column_spec(options.positions), options.targets
    kind = targets if targets in ("effort", "wrench") else None
    topic = options.joint_topic or BAG_JOINT_TOPIC
    listed = positions if isinstance(positions, list) else None  # names: skip other messages
    cutoff = _cutoff(options, None, path.name)
    try:
        log = read_bag(path, topic, wrench_topic=options.wrench_topic, targets=kind,
                       joints=listed, **_reader_keywords(options, cutoff))
    except LogError:
        raise
    except Exception as e:  # noqa: BLE001 - rosbags' errors have various types
        raise LogError(f"{path.name}: not a readable ROS 1 or ROS 2 bag: {e}") from None
    if positions is not None and listed is None:
        keep = expand_columns(positions, log.joint_names, f"{path.name} joints on {topic}")
        i = [log.joint_names.index(n) for n in keep]
        log.q, log.qd, log.qdd, log.joint_names = log.q[:, i], log.qd[:, i], log.qdd[:, i], keep
    if kind is None and targets is not None:
        keep = expand_columns(column_spec(targets), log.target_names, f"{path.name} targets")
        i = [log.target_names.index(n) for n in keep]
        log.targets, log.target_names = log.targets[:, i], keep
    data = _stack([log], [0], path.name)
    data.rows["in_file"] = message_count(path, topic)
    data.kind = "bag"
    data.options = dc.replace(options, acceleration_cutoff_hz=cutoff)
    return data


def _stack(logs: list[RobotLog], ids, source: str) -> TrainingData:
    first = logs[0]
    for log in logs[1:]:
        if log.joint_names != first.joint_names or log.target_names != first.target_names:
            raise LogError(f"{source}: trajectories differ in their columns")
    data = TrainingData(
        X=np.vstack([log.X() for log in logs]),
        Y=np.vstack([log.targets for log in logs]),
        t=np.concatenate([log.t for log in logs]),
        groups=np.concatenate([np.full(len(log), i) for log, i in zip(logs, ids, strict=True)]),
        joint_names=list(first.joint_names),
        target_names=list(first.target_names),
        derived=sorted({d for log in logs for d in log.derived}),
        source=first.source if len(logs) == 1 else f"{source} ({len(logs)} trajectories)",
        rows={"read": int(sum(len(log) for log in logs))},
    )
    if len(logs) == 1:
        data.groups = np.zeros(len(first), dtype=np.int64)
    return data


def _time_window(data: TrainingData, t_start, t_end) -> TrainingData:
    keep = np.ones(len(data.t), bool)
    if t_start is not None:
        keep &= data.t >= t_start
    if t_end is not None:
        keep &= data.t <= t_end
    if not keep.any():
        raise LogError(f"{data.source}: no rows in the time window {t_start}..{t_end} s; the "
                       f"log spans t = {data.t.min():.6g}..{data.t.max():.6g} s; choose "
                       f"{option_hint('t_start', 'S')} and {option_hint('t_end', 'S')} in it")
    data.rows["outside_time_window"] = int((~keep).sum())
    data.rows["used"] = int(keep.sum())
    data.rows["dropped_by_reader"] = data.rows["in_file"] - data.rows["read"]
    data.X, data.Y, data.t, data.groups = (a[keep] for a in (data.X, data.Y, data.t, data.groups))
    return data
