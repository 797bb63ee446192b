"""The runtime chain run offline over a log: :func:`replay`.

Every row of a log is one sample of the loop: the :class:`~ftdrake.runtime.chain.
CompensationChain` that the stations add is advanced once per row, exactly as the live
station advances it once per F/T message (diagram time k·period for the k-th row), with the
row's wrench and joint state on its inputs. The numbers are therefore the loop's own — the
acceleration estimate, the bias tracker and the detector's debouncing included — and not a
batch ``model.predict``.

Which inputs an update reads (`pairing`):

* ``"row"`` (default): the k-th update reads row k's wrench and joint state. What a table
  recorded from a robot holds (rows paired by timestamp, ``ftdrake record``) and what the
  live station sees when both messages of a sample arrive before it runs.
* ``"simulated"``: the k-th update reads row k's joint state with row k−1's wrench (a zero
  wrench for the first row). What the compensator of a simulated station reads: Drake's
  plant steps before the chain's update, so in :func:`ftdrake.sim.simulate.simulate`'s log
  the wrench reaches the chain one sample after the joint state of its row (the simulated
  robot on LCM publishes the same way, :mod:`ftdrake.sim.lcm_publisher`). Replaying such a
  log with this pairing reproduces its ``wrench_internal_*``, ``wrench_compensated_*``,
  ``wrench_contact_*``, ``contact`` ... columns.

Which row an output belongs to (`view`):

* ``"aligned"`` (default): row k holds the chain's outputs after the update that read row
  k's inputs — e.g. ``wrench_compensated`` = wrench − model(joint state) of that same update.
  This is what the live station publishes for the k-th F/T message, and what
  :func:`~ftdrake.sim.simulate.simulate` logs in row k.
* ``"held"``: row k holds what the chain's (state) output ports held when row k's inputs
  arrived, i.e. the outputs of update k−1 (NaN in the first row). The chain's outputs lag
  its inputs by one sample; this view shows that lag.

Within the chain the bias tracker reads the compensator's previous output and the detector
the tracker's, as in the loop; replay runs the same diagram, so those lags are the loop's.

Result columns (one row per log row, ``t`` copied from the log): the columns of every output
port the chain has, named as :data:`ftdrake.conventions.CHAIN_OUTPUTS` says and recorded by
:class:`~ftdrake.offline.recorder.UpdateRecorder` — the names of
:mod:`ftdrake.sim.simulate`'s compensation columns, so a replay can stand in for them:
``wrench_internal_*``, ``wrench_compensated_*``, ``wrench_contact_*``, ``wrench_std_*``,
``out_of_domain``, ``fault``, ``contact`` (the detector's flag), ``contact_force``, and with the
bias tracker ``bias_*``, ``tracker_std_*``, ``payload_dm``, ``payload_mcx..mcz`` (with
``track_payload``) and ``payload_change`` (with ``bias_tracker.payload_change.enabled``).

Gaps: a time step longer than `gap_factor` × the median step (default
:data:`GAP_FACTOR`, the readers' rule) is a gap in the log. The loop's state does not carry
across one: the chain is restarted after each gap (a new chain on the rows up to the next, as
if each stretch were a log of its own), so the bias tracker, the payload-change monitor, the
q̇/q̈ estimates, the delay line and the detector's debouncing and arming start afresh instead
of integrating or differentiating across the gap (a 15 s gap read as one 10 ms step made a
q̈ spike, and a wrench of −95.8 N the row after it). The gaps are kept in the result's
``attrs["gaps"]`` (:func:`find_gaps`) and :func:`summary` reports them.

Log columns read (the layout ``collect``, ``simulate`` and :func:`ftdrake.add_recorder`
write): ``t`` (s), ``q_i`` (rad), ``qd_i`` (rad/s), the wrench ``meas_Fx..meas_Tz`` (N, N·m),
``temperature`` (°C; only for a model trained with it), and optionally ``tared`` and
``payload_changed`` (> 0.5 for the sample of a re-tare / grasp; to the bias tracker).
"""

from __future__ import annotations

import dataclasses as dc
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.systems.analysis import Simulator

from .. import conventions as col
from ..config import ChainConfig, DetectorConfig, ScenarioConfig, parse_config
from ..data.bag import is_bag, read_bag
from ..data.logs import (
    expand_columns,
    is_table,
    missing_time_message,
    option_hint,
    read_frame,
    warn_log,
)
from ..data.robot_log import velocities_from_positions
from ..data.training import DERIVED
from ..errors import LogError, spelled
from ..runtime.chain import CompensationChain
from .recorder import UpdateRecorder, output_columns
from .thresholds import Outlier, armed, calibrate_thresholds

PAIRINGS = ("row", "simulated")
VIEWS = ("aligned", "held")
TARED, PAYLOAD_CHANGED = "tared", "payload_changed"
#: A time step longer than this many median steps is a gap (the readers' ``gap_factor``).
GAP_FACTOR = 3.0

@dc.dataclass
class ReplayInputs:
    """The chain's inputs per update, (N, ...) arrays in the units of the chain's ports."""

    t: np.ndarray  # (N,) s, the log's time of each row
    wrench: np.ndarray  # (N, 6) N, N·m
    joint_state: np.ndarray  # (N, 2n) rad, rad/s
    temperature: np.ndarray | None = None  # (N,) °C
    tared: np.ndarray | None = None  # (N,) > 0.5 for a re-tare's sample
    payload_changed: np.ndarray | None = None  # (N,) > 0.5 for a grasp's sample
    imu: np.ndarray | None = None  # (N, 6) [imu_acc (m/s²); imu_gyro (rad/s)] in S


def replay(model, log, config: ChainConfig | None = None, *, pairing: str = "row",
           view: str = "aligned", period: float | None = None, wrench: str = col.MEASURED,
           robot=None, gap_factor: float = GAP_FACTOR) -> pd.DataFrame:
    """Runs the runtime chain over `log`, one update per row; returns its outputs per row.

    `model`: a fitted compensator (``load_model``). `log`: a DataFrame in the layout of the
    module docstring, or the path of a CSV/Parquet table or ROS bag (read with
    :func:`read_replay_log`; an LCM log is read with
    :func:`ftdrake.hardware.recording.read_lcm_log` first). `config`: the chain's
    :class:`~ftdrake.config.ChainConfig` (default: the one of the scenario a ``collect``
    Parquet file carries, ``scenario.chain_config()``, else ``ChainConfig()``). `pairing`,
    `view`: see the module docstring. `period`: the chain's sample period in s (default: the
    config's sensor period when the log's median period is within 1 % of it, else the
    log's median period). `wrench`: the prefix of the wrench columns. `robot`: the
    RobotDescription for the tracker's payload estimate (``track_payload``; default:
    ``config.robot``, else the robot embedded in the model). A delay between the streams is
    ``config.sensor.wrench_delay_s`` (null: the model's own). `gap_factor`: a step longer
    than this × the median step is a gap, after which the chain restarts (module
    docstring); the gaps are in the result's ``attrs["gaps"]``.

    Raises LogError naming a missing column and what produces it.
    """
    if pairing not in PAIRINGS:
        raise LogError(f"replay: pairing must be one of {PAIRINGS}, got {pairing!r}")
    if view not in VIEWS:
        raise LogError(f"replay: view must be one of {VIEWS}, got {view!r}")
    frame = to_replay_layout(log if isinstance(log, pd.DataFrame) else read_replay_log(log))
    config = chain_config_of(frame, config)
    n = int(model.n_joints_)
    inputs = replay_inputs(frame, n, wrench=wrench,
                           temperature=bool(model.temperature_in_),
                           imu=bool(getattr(model, "needs_imu", False)))
    period = period if period is not None else _period(inputs.t, config)
    gaps = find_gaps(inputs.t, gap_factor)
    parts = []
    for rows in np.split(np.arange(len(inputs.t)), [g["row"] for g in gaps["gaps"]]):
        part = _rows_of(inputs, rows)
        if pairing == "simulated":
            part = dc.replace(part, wrench=np.vstack([np.zeros((1, 6)), part.wrench[:-1]]))
        chain = CompensationChain(model, config, period=period, n_joints=n,
                                  gravity="joint_state", robot=robot)
        outputs = run_chain(chain, part)
        if view == "held":
            outputs = {k: np.vstack([np.full((1, v.shape[1]), np.nan), v[:-1]])
                       for k, v in outputs.items()}
        parts.append(outputs)
    outputs = {k: np.vstack([o[k] for o in parts]) for k in parts[0]}
    result = _frame(inputs.t, outputs)
    result.attrs["gaps"] = gaps
    return result


def find_gaps(t, gap_factor: float = GAP_FACTOR) -> dict:
    """The gaps of times `t` (s, increasing): steps longer than `gap_factor` × the median
    step. Returns a JSON-ready dict: ``gap_factor``, ``median_step_s``, ``count`` and
    ``gaps``, each ``{"row": the first row after it, "t_before", "t_after", "length_s"}``."""
    if not gap_factor > 1:
        raise LogError(f"replay: gap_factor must be above 1 (a step that many median steps "
                       f"long is a gap); got {gap_factor!r}")
    t = np.asarray(t, dtype=float)
    dt = np.diff(t)
    median = float(np.median(dt)) if len(dt) else 0.0
    rows = np.flatnonzero(dt > gap_factor * median) + 1 if len(dt) else np.array([], int)
    return {"gap_factor": float(gap_factor), "median_step_s": median, "count": len(rows),
            "gaps": [{"row": int(k), "t_before": float(t[k - 1]), "t_after": float(t[k]),
                      "length_s": float(t[k] - t[k - 1])} for k in rows]}


def gaps_text(gaps: dict, limit: int = 5) -> str | None:
    """One line on the gaps of :func:`find_gaps` (None without any): how many, the rule,
    where and how long (the first `limit`), and that the chain restarted after each."""
    if not gaps["count"]:
        return None
    listed = "; ".join(f"{g['length_s']:.4g} s after t = {g['t_before']:.6g} s"
                       for g in gaps["gaps"][:limit])
    more = f"; … {gaps['count'] - limit} more" if gaps["count"] > limit else ""
    return (f"{gaps['count']} gap(s) in the log (a step longer than {gaps['gap_factor']:g} × "
            f"the median step {gaps['median_step_s'] * 1e3:.4g} ms): {listed}{more}. The chain "
            "restarted after each (bias tracker, payload-change monitor, q̇/q̈ estimates, "
            "delay line, detector): each stretch replays as a log of its own")


def _rows_of(inputs: ReplayInputs, rows: np.ndarray) -> ReplayInputs:
    """`inputs` cut to `rows`."""
    return ReplayInputs(**{f.name: (None if getattr(inputs, f.name) is None
                                    else getattr(inputs, f.name)[rows])
                           for f in dc.fields(ReplayInputs)})


def run_chain(chain: CompensationChain, inputs: ReplayInputs) -> dict[str, np.ndarray]:
    """Advances `chain` once per row of `inputs` (update k at k·period, as the live station
    does); returns {output port name: (N, size) array after each update}."""
    simulator = Simulator(chain)
    context = simulator.get_mutable_context()
    chain.initialize(context)
    simulator.Initialize()
    fixed = {"wrench_measured": inputs.wrench, "joint_state": inputs.joint_state}
    optional = {"temperature": inputs.temperature, TARED: inputs.tared,
                PAYLOAD_CHANGED: inputs.payload_changed}
    for name, values in optional.items():
        if chain.HasInputPort(name):
            if values is None:
                if name == "temperature":
                    raise LogError("replay: the model was trained with the sensor temperature; "
                                   f"the log needs a {col.TEMPERATURE!r} column (°C)")
                values = np.zeros(len(inputs.t))
            fixed[name] = np.asarray(values, dtype=float).reshape(len(inputs.t), 1)
    if chain.HasInputPort("imu"):  # replay_inputs checked the columns (IMU_REPLAY)
        fixed["imu"] = np.asarray(inputs.imu, dtype=float)
    ports = {name: chain.GetInputPort(name).FixValue(context, values[0])
             for name, values in fixed.items()}
    recorder = UpdateRecorder(chain)
    period = chain.period
    values = [(ports[name].GetMutableData().get_mutable_value(), fixed[name]) for name in fixed]
    for k in range(len(inputs.t)):
        for value, rows in values:
            value.SetFromVector(rows[k])
        simulator.AdvanceTo((k + 0.5) * period)
        recorder.record(context)
    return recorder.outputs()


def replay_inputs(frame: pd.DataFrame, n: int, *, wrench: str = col.MEASURED,
                  temperature: bool = False, imu: bool = False) -> ReplayInputs:
    """The chain's inputs from a log DataFrame (see the module docstring for the columns;
    with `imu`, a model that takes an IMU: the :data:`IMU_REPLAY` columns too)."""
    needed = {col.TIME: "the sample time in s",
              **{c: "joint positions (rad): the robot's joint-state stream"
                 for c in col.joint_columns(col.Q, n)},
              **{c: "joint velocities (rad/s): the robot's joint-state stream (replay "
                 "computes them from q when the log has none)"
                 for c in col.joint_columns(col.QD, n)},
              **{c: "the sensor's reading (N, N·m) from the F/T stream"
                 for c in col.wrench_columns(wrench)}}
    if temperature:
        needed[col.TEMPERATURE] = "the sensor's temperature (°C): the model was trained with it"
    if imu:
        needed.update(dict.fromkeys(IMU_REPLAY, "the IMU at the sensor (m/s², rad/s, in S): "
                                    "the model takes it (scenario.imu.enabled)"))
    missing = [c for c in needed if c not in frame.columns]
    if missing:
        why = sorted({needed[c] for c in missing})
        raise LogError(f"replay: the log lacks columns {missing[:8]}"
                       f"{' ...' if len(missing) > 8 else ''} ({'; '.join(why)}); it has "
                       f"{list(frame.columns)[:20]}; logs in this layout come from "
                       "ftdrake.add_recorder, collect, simulate or ftdrake record; choose "
                       "another table's columns with " + spelled(
                           "to_replay_layout(frame, positions=, velocities=, targets=, time=)",
                           "--positions, --velocities, --targets and --time"))
    t = frame[col.TIME].to_numpy(dtype=float)
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise LogError("replay: the log's time column must increase strictly, with at least "
                       "two rows (one log at a time: split a dataset by its trajectory column)")
    state = frame[col.joint_columns(col.Q, n) + col.joint_columns(col.QD, n)]
    return ReplayInputs(
        t=t, wrench=frame[col.wrench_columns(wrench)].to_numpy(dtype=float),
        joint_state=state.to_numpy(dtype=float),
        temperature=frame[col.TEMPERATURE].to_numpy(dtype=float) if temperature else None,
        tared=frame[TARED].to_numpy(dtype=float) if TARED in frame else None,
        payload_changed=(frame[PAYLOAD_CHANGED].to_numpy(dtype=float)
                         if PAYLOAD_CHANGED in frame else None),
        imu=frame[list(IMU_REPLAY)].to_numpy(dtype=float) if imu else None)


#: The IMU columns replay feeds the chain's ``imu`` input (α is derived in the chain).
IMU_REPLAY = (*col.imu_columns(col.IMU_ACC), *col.imu_columns(col.IMU_GYRO))


def to_replay_layout(frame: pd.DataFrame, *, positions=None, velocities=None, targets=None,
                     time: str | None = None) -> pd.DataFrame:
    """`frame` with the columns chosen as every reader chooses them (globs, comma lists,
    ``re:`` patterns; :func:`~ftdrake.data.logs.expand_columns`) renamed into the replay
    layout: ``t``, ``q_i``, ``qd_i``, ``meas_Fx … meas_Tz``; other columns are kept. The
    defaults are that layout's own (``t``, ``q_*``, ``qd_*``, ``meas_*``); with none given
    `frame` is returned as it is. Velocities ``"derive"``, or none given on a log with
    positions and without ``qd_*`` columns, are computed from the positions as ``train`` and
    ``evaluate`` compute them (:func:`~ftdrake.data.robot_log.velocities_from_positions`; a
    LogWarning says so).
    Errors name the option (``--positions`` …) that fixes them."""
    columns = [str(c) for c in frame.columns]
    def has(prefix):
        return any(re.fullmatch(rf"{prefix}_\d+", c) for c in columns)

    # Computed when asked for, or when a log with positions has no velocities (a log in
    # another layout altogether is named by replay_inputs, with every option to choose it).
    derive = velocities == DERIVED or (velocities is None and not has(col.QD)
                                       and (positions is not None or has(col.Q)))
    if not derive and all(v is None for v in (positions, velocities, targets, time)):
        return frame
    time = time or col.TIME
    if time not in columns:
        raise LogError("replay: " + missing_time_message("the log", time, columns))
    chosen = _chosen_columns(columns, positions, velocities, targets, derive)
    n = len(chosen["positions"])
    if derive:
        chosen["velocities"] = [f"{col.QD}_{i}" for i in range(n)]  # computed below
    if len(chosen["velocities"]) != n or len(chosen["targets"]) != 6:
        raise LogError(f"replay: {n} positions {chosen['positions']} need as many velocities "
                       f"(got {chosen['velocities']}) and 6 wrench columns (got "
                       f"{chosen['targets']}); choose them with {option_hint('velocities', 'PAT')}"
                       f" and {option_hint('targets', 'PAT')}")
    renamed = {time: col.TIME,
               **dict(zip(chosen["positions"], col.joint_columns(col.Q, n), strict=True)),
               **dict(zip(chosen["velocities"], col.joint_columns(col.QD, n), strict=True)),
               **dict(zip(chosen["targets"], col.wrench_columns(col.MEASURED), strict=True))}
    out = pd.DataFrame({new: frame[old].to_numpy() for old, new in renamed.items()
                        if not (derive and new.startswith(f"{col.QD}_"))})
    if derive:
        qd = _derived_velocities(frame, time, chosen["positions"],
                                 "the log has no velocity columns" if velocities is None
                                 else option_hint("velocities", DERIVED))
        for name, values in zip(col.joint_columns(col.QD, n), qd.T, strict=True):
            out[name] = values
    for c in columns:
        if c not in renamed and c not in out.columns:
            out[c] = frame[c].to_numpy()
    out.attrs = dict(frame.attrs)
    return out


def _chosen_columns(columns, positions, velocities, targets, derive: bool
                    ) -> dict[str, list[str]]:
    """{what: the columns chosen} for the positions, targets and (unless `derive`: computed
    from q) velocities."""
    chosen = {}
    for what, spec, default in (("positions", positions, f"{col.Q}_*"),
                                ("velocities", velocities, rf"re:{col.QD}_\d+"),
                                ("targets", targets, f"{col.MEASURED}_*")):
        if what == "velocities" and derive:
            continue
        try:
            chosen[what] = expand_columns(spec or default, columns, f"replay {what}",
                                          option=what)
        except LogError as e:
            raise LogError(f"{e}; choose them with {option_hint(what, 'PATTERN')}") from None
    return chosen


def _derived_velocities(frame: pd.DataFrame, time: str, positions: list[str], why: str
                        ) -> np.ndarray:
    """(N, n) q̇ of `positions` computed as the readers compute missing velocities; says so
    (and `why`)."""
    t = frame[time].to_numpy(dtype=float)
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise LogError("replay: the log's time column must increase strictly, with at least "
                       "two rows (one log at a time: split a dataset by its trajectory column)")
    warn_log(f"replay: {why}; q̇ computed from {positions[0]}.."
             f"{positions[-1]} as train and evaluate compute it (Savitzky–Golay, 0.1 s "
             f"window, order 4; {option_hint('velocities', 'PAT')} chooses recorded ones)")
    return velocities_from_positions(t, frame[positions].to_numpy(dtype=float), "replay")


def read_replay_log(path, *, wrench_topic: str | None = None,
                    joint_topic: str = "/joint_states") -> pd.DataFrame:
    """A CSV/Parquet table (as is; a Parquet file's scenario in ``attrs["scenario"]``) or a
    ROS bag (JointState rows with the WrenchStamped topic `wrench_topic` put on their
    times, :func:`ftdrake.data.read_bag`) as a DataFrame in the replay layout."""
    path = Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    if is_table(path):
        return read_frame(path)
    if is_bag(path):
        if not wrench_topic:
            raise LogError(f"{path}: a bag needs the F/T sensor's WrenchStamped topic "
                           "(wrench_topic=...)")
        return read_bag(path, joint_topic, wrench_topic=wrench_topic, targets="wrench").to_frame()
    raise LogError(f"{path}: unknown log format; expected .csv, .parquet, a ROS bag, or an "
                   "LCM log read with ftdrake.hardware.recording.read_lcm_log")


def chain_config_of(frame: pd.DataFrame, config: ChainConfig | None = None) -> ChainConfig:
    """The chain config a replay of `frame` runs: `config`, else that of the scenario a
    ``collect`` Parquet file carries in its metadata, else ``ChainConfig()``; validated."""
    if config is None:
        scenario = scenario_of(frame)
        return scenario.chain_config() if scenario is not None else ChainConfig()
    return config.validate()


def scenario_of(frame: pd.DataFrame) -> ScenarioConfig | None:
    """The scenario a ``collect`` Parquet file carries in its metadata (None: none)."""
    scenario = frame.attrs.get("scenario")
    return parse_config(scenario, source="the log's metadata") if scenario else None


def calibrated_detector(result: pd.DataFrame, model, config: ChainConfig
                        ) -> tuple[DetectorConfig, list[Outlier]]:
    """``config.detector`` with its thresholds set for its false-positive budget from a
    replay `result` (:func:`replay`'s output) of contact-free motion the model was not
    trained on, and the stretches of it the thresholds leave out: the contact wrench the
    detector judges, and with the χ² test the model's std, on the rows it judges
    (``arm_after_s`` from the log's start), at the log's median sample rate, with the robust
    largest-residual term (:func:`~ftdrake.offline.thresholds.calibrate_thresholds`,
    ``tail="robust"``: a start transient or another short burst does not set the threshold;
    it is returned as an :class:`~ftdrake.offline.thresholds.Outlier`, times on the log's
    axis). The test is the one ``detector.test`` gives `model` when calibrating (``auto``:
    χ² for a model with a std of a reading); debounce, hysteresis and arming are kept."""
    t = result[col.TIME].to_numpy(float)
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise LogError("calibrating the detector needs a replay with increasing times")
    judged = armed(t - t[0], config.detector.arm_after_s)
    test = config.detector.for_model(model, calibrating=True).test
    std = (result[col.wrench_columns(col.WRENCH_STD)].to_numpy()[judged]
           if test == "chi2" else None)
    detector = config.detector
    kept = {"release_ratio": detector.release_ratio, "debounce_on": detector.debounce_on,
            "debounce_off": detector.debounce_off, "arm_after_s": detector.arm_after_s}
    return calibrate_thresholds(
        result[col.wrench_columns(col.WRENCH_CONTACT)].to_numpy()[judged],
        sample_rate_hz=1.0 / float(np.median(np.diff(t))),
        false_positives_per_hour=config.detector.false_positives_per_hour, test=test,
        std=std, tail="robust", times=t[judged], **kept)


def summary(result: pd.DataFrame) -> dict:
    """Counts of a replay result: rows, samples in contact and contact episodes, samples out
    of domain and faulted, RMS of the contact wrench (N, N·m) outside contact, and the log's
    gaps (:func:`find_gaps`; the chain restarted after each) when the result has them."""
    detected = result[col.CONTACT].fillna(0).to_numpy() > 0.5
    onsets = int(np.count_nonzero(np.diff(np.r_[0, detected.astype(int)]) == 1))
    free = result.loc[~detected, col.wrench_columns(col.WRENCH_CONTACT)]
    found = {"gaps": result.attrs["gaps"]} if "gaps" in result.attrs else {}
    return {"rows": len(result), "contact_samples": int(detected.sum()),
            "contact_episodes": onsets,
            "out_of_domain_samples": int((result[col.OUT_OF_DOMAIN].fillna(0) > 0.5).sum()),
            "fault_samples": int((result[col.FAULT].fillna(0) > 0.5).sum()),
            "free_rms": dict(zip(col.WRENCH_AXES,
                                 np.sqrt(np.nanmean(free.to_numpy() ** 2, axis=0)).round(6)
                                 .tolist(), strict=True)), **found}


def _period(t: np.ndarray, config: ChainConfig) -> float:
    """The config's sensor period when the log's median period is within 1 % of it (so a
    simulated log replays with the loop's exact period), else the log's median period."""
    logged = float(np.median(np.diff(t)))
    nominal = config.sensor.period
    if not (logged > 0 and math.isfinite(logged)):
        raise LogError(f"replay: the log's median sample period is {logged!r} s")
    return nominal if abs(logged - nominal) <= 0.01 * nominal else logged


def _frame(t: np.ndarray, outputs: dict[str, np.ndarray]) -> pd.DataFrame:
    return pd.DataFrame({col.TIME: t, **output_columns(outputs)})
