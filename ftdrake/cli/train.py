"""`ftdrake train` and `ftdrake evaluate`: fit a compensator on a robot log, score it on another.

Both commands read a log with :mod:`ftdrake.logs` — a CSV/Parquet table (``read_table``) or a
ROS bag (``read_bag``: a ROS 1 ``.bag`` file or a ROS 2 bag folder) — into the model layout
``X = [q, q̇, q̈]`` (rad, rad/s, rad/s²) and targets ``Y`` (a wrench in N, N·m, or joint
torques in N·m; any number of columns)::

    ftdrake train --data id1.csv --targets 'tau_*' --velocities 'qd_*' --model rf --out m.ftd
    ftdrake evaluate --model m.ftd --data id2.csv --json eval.json

Column options are a glob (``'q_*'``), a comma-separated list of names, or a regular
expression after ``re:`` (``'re:qd_\\d+'``). For bags, ``--positions`` selects JointState
joint names (default: all), ``--targets`` is ``effort`` (default) or ``wrench`` (default with
``--wrench-topic``) or selects among the names read (``tau_0..``, ``meas_Fx..``); velocities
are the messages' own. ``--t-start``/``--t-end`` keep the rows in a time window (s, on the
log's own time axis: a table's time column, a bag's time since its first joint state);
derivatives are computed on the whole log first. A table with a ``trajectory`` column
(``ftdrake collect``'s datasets; ``--group`` names another) is read per trajectory, and
cross-validation folds never split a trajectory segment.

`train` tunes the model with the ``quick`` grid and grouped CV (``--preset none`` fits the
defaults), locally or on a Dask cluster (``--dask ADDRESS``), and saves it with
:func:`~ftdrake.compensation.persistence.save_model`. The manifest's ``extra`` records the data
file and options, the columns used and which were Savitzky–Golay derivatives, the training
ranges of time and targets (those of the inputs are the manifest's ``input_range``), the
row counts (in the file, dropped by the reader, outside the time window, used) with the
reader's warnings, and the search result. `evaluate` reads the same columns as training
unless told otherwise (when the data is of the same kind, table or bag) and reports
per-target MSE, NMSE and variance score on all rows, on the rows inside the training range
of every input, and on the rows outside it.

Every problem with the input is a one-line error (exit code 2); rows the reader dropped or
reordered are printed as warnings with counts.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..conventions import WRENCH_AXES, WRENCH_UNITS
from ..data.logs import LogError, LogWarning

MODELS = ("rf", "svr", "gpr", "physics", "hybrid")
FEATURE_SETS = ("q", "q,qd", "q,qd,qdd")
TABLE_DEFAULTS = {"positions": "q_*", "targets": "meas_*", "time": "t"}
GROUP_DEFAULT = "trajectory"
BUILTIN_ROBOT = "ftdrake"  # --robot value naming ftdrake's simulated arm

_COLUMNS_HELP = ("PAT is a glob ('q_*'), a comma-separated list of names, or a regular "
                 "expression after 're:'. Times are in s on the log's own axis (a bag's: since "
                 "its first joint state).")
_DATA_HELP = {
    "positions": ("PAT", "joint position columns (rad), default 'q_*'; bags: joint names"),
    "targets": ("PAT", "target columns, default 'meas_*'; bags: effort, wrench or a pattern"),
    "velocities": ("PAT", "velocity columns (rad/s); default: Savitzky–Golay of q"),
    "accelerations": ("PAT", "acceleration columns (rad/s²); default: Savitzky–Golay of q"),
    "time": ("COL", "time column (s), default 't'"),
    "group": ("COL", f"trajectory id column, default '{GROUP_DEFAULT}' if there is one"),
    "joint_topic": ("T", "bags: JointState topic, default /joint_states"),
    "wrench_topic": ("T", "bags: WrenchStamped topic"),
}
DATA_OPTIONS = tuple(_DATA_HELP)  # how a log is read; kept in the model's manifest


def register(subparsers) -> None:
    """Adds ``train`` and ``evaluate`` to an ``argparse`` subparsers object."""
    p = subparsers.add_parser("train", help="fit a compensator on a robot log; save it",
                              description=_COLUMNS_HELP)
    p.add_argument("--data", type=Path, required=True, metavar="FILE",
                   help="CSV/Parquet table, ROS 1 .bag file or ROS 2 bag folder")
    _add_data_options(p)
    p.add_argument("--model", choices=MODELS, required=True,
                   help="rf, svr, gpr; physics (rigid payload) or hybrid (physics + forest on "
                        "the residual) need 6 wrench targets and --robot")
    p.add_argument("--features", choices=FEATURE_SETS, metavar="q|q,qd|q,qd,qdd",
                   help="inputs the model uses (default q,qd,qdd; physics: q = static, "
                        "q,qd,qdd = dynamic; hybrid: the residual forest's, default q)")
    p.add_argument("--preset", choices=["quick", "none"], default="quick",
                   help="quick: grid search with grouped CV (rf, svr; gpr, physics and hybrid "
                        "fit their parameters from data); none: default parameters")
    p.add_argument("--robot", metavar="FILE",
                   help=f"URDF/SDF holding the sensor frame, or '{BUILTIN_ROBOT}' for the "
                        "simulated arm (physics, hybrid)")
    p.add_argument("--sensor-frame", metavar="NAME", help="frame S of the targets in --robot")
    p.add_argument("--base-frame", metavar="NAME", help="frame of --robot welded to the world")
    p.add_argument("--target-units", metavar="U,U,..",
                   help="unit per target (default: N/N*m for wrench axes, else N*m)")
    p.add_argument("--seed", type=int, default=0, help="random state of rf and gpr")
    p.add_argument("--jobs", type=int, default=-1, help="parallel CV fits (-1: all cores)")
    p.add_argument("--dask", metavar="ADDRESS", help="run the grid search on this Dask scheduler")
    p.add_argument("--out", type=Path, required=True, metavar="MODEL")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(run=run_train)

    p = subparsers.add_parser(
        "evaluate", help="score a saved compensator on a robot log",
        description=_COLUMNS_HELP + " Column and topic options not given are those the model "
        "was trained with (when the file is of the same kind, table or bag), else the defaults.")
    p.add_argument("--model", type=Path, required=True, metavar="MODEL")
    p.add_argument("--data", type=Path, required=True, metavar="FILE")
    _add_data_options(p)
    p.add_argument("--json", type=Path, metavar="OUT", help="also write the results as JSON")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=run_evaluate)


def _add_data_options(p) -> None:
    for name, (metavar, text) in _DATA_HELP.items():
        p.add_argument("--" + name.replace("_", "-"), metavar=metavar, help=text)
    p.add_argument("--t-start", type=float, metavar="S", help="drop rows before this time (s)")
    p.add_argument("--t-end", type=float, metavar="S", help="drop rows after this time (s)")


# -- reading ------------------------------------------------------------------------------------
@dataclass
class LogData:
    """The rows of a log (or of several trajectories in one table) in the model layout.

    X: (N, 3n) ``[q, q̇, q̈]`` in rad, rad/s, rad/s². Y: (N, m) targets as logged.
    t: (N,) time in s. groups: (N,) trajectory id per row (0 for a single log).
    rows: counts in the file, after the reader, outside the time window, used.
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
    warnings: list[str] = field(default_factory=list)
    scenario_yaml: str | None = None  # a `collect` dataset's scenario, for --robot ftdrake

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)


def data_options(args, stored: dict | None = None) -> dict:
    """The column/topic options given on the command line, else those `stored` in a model."""
    stored = stored or {}
    return {k: getattr(args, k) if getattr(args, k) is not None else stored.get(k)
            for k in DATA_OPTIONS}


def read_data(path: Path, options: dict, *, t_start=None, t_end=None, report=print) -> LogData:
    """Reads `path` (table or bag) with `options` (see :data:`DATA_OPTIONS`).

    LogWarnings are passed to `report` (one line each) and kept in ``LogData.warnings``.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file or folder")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LogWarning)
        data = _read_bag(path, options) if _is_bag(path) else _read_table(path, options)
    for w in caught:
        if issubclass(w.category, LogWarning):
            data.warnings.append(str(w.message))
            report(f"warning: {w.message}")
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return _time_window(data, t_start, t_end)


def _is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix == ".bag"


def _column_spec(text: str | None):
    """CLI column option → what :func:`ftdrake.logs.expand_columns` takes."""
    if text is None:
        return None
    if text.startswith("re:"):
        return re.compile(text[3:])
    if "," in text:
        return [s.strip() for s in text.split(",") if s.strip()]
    return text


def _read_table(path: Path, options: dict) -> LogData:
    import pandas as pd

    kwargs = {
        "positions": _column_spec(options["positions"] or TABLE_DEFAULTS["positions"]),
        "targets": _column_spec(options["targets"] or TABLE_DEFAULTS["targets"]),
        "velocities": _column_spec(options["velocities"]),
        "accelerations": _column_spec(options["accelerations"]),
        "time": options["time"] or TABLE_DEFAULTS["time"],
    }
    frame = _read_frame(path)
    group = options["group"]
    if group is None and GROUP_DEFAULT in frame.columns:
        group = GROUP_DEFAULT
    if group is None:
        logs, ids = [_read_group(frame, path.name, kwargs)], [0]
    else:
        if group not in frame.columns:
            raise LogError(f"{path.name}: no group column {group!r}; available columns: "
                           f"{list(frame.columns)}")
        ids = list(pd.unique(frame[group]))
        logs = [_read_group(frame[frame[group] == i], f"{path.name} [{group}={i}]", kwargs)
                for i in ids]
    data = _stack(logs, ids, path.name)
    data.rows["in_file"] = len(frame)
    data.scenario_yaml = frame.attrs.get("scenario") or None
    return data


def _read_frame(path: Path):
    """The table at `path`, with a ``collect`` dataset's scenario in ``attrs["scenario"]``."""
    import pandas as pd

    if path.name.endswith((".csv", ".csv.gz", ".txt")):
        return pd.read_csv(path)
    if path.suffix in (".parquet", ".pq"):
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(path)
        except Exception as e:  # noqa: BLE001 - any pyarrow failure: unreadable
            raise LogError(f"{path.name}: not a readable Parquet file: {e}") from None
        from ..data.dataset import META_SCENARIO

        frame = table.to_pandas()
        scenario = (table.schema.metadata or {}).get(META_SCENARIO)
        frame.attrs["scenario"] = scenario.decode() if scenario else None
        return frame
    raise LogError(f"{path}: unknown format; expected .csv, .parquet, a .bag file or a ROS 2 "
                   f"bag folder")


def _read_group(frame, label: str, kwargs):
    """read_table on a DataFrame, naming it `label` in errors and warnings."""
    from ..data.logs import read_table

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LogWarning)
        try:
            log = read_table(frame.reset_index(drop=True), **kwargs)
        except LogError as e:
            raise LogError(str(e).replace("DataFrame", label, 1)) from None
    for w in caught:
        warnings.warn(str(w.message).replace("DataFrame", label, 1), w.category, stacklevel=2)
    log.source = label
    return log


def _read_bag(path: Path, options: dict) -> LogData:
    """A bag's JointState rows; --positions/--targets select joints and targets by name."""
    from ..data.logs import expand_columns, read_bag

    positions, targets = _column_spec(options["positions"]), options["targets"]
    kind = targets if targets in ("effort", "wrench") else None
    topic = options["joint_topic"] or "/joint_states"
    listed = positions if isinstance(positions, list) else None  # names: skip other messages
    try:
        log = read_bag(path, topic, wrench_topic=options["wrench_topic"], targets=kind,
                       joints=listed)
    except LogError:
        raise
    except Exception as e:  # noqa: BLE001 - rosbags' errors have various types
        raise LogError(f"{path.name}: not a readable ROS 1 or ROS 2 bag: {e}") from None
    if positions is not None and listed is None:
        keep = expand_columns(positions, log.joint_names, f"{path.name} joints on {topic}")
        i = [log.joint_names.index(n) for n in keep]
        log.q, log.qd, log.qdd, log.joint_names = log.q[:, i], log.qd[:, i], log.qdd[:, i], keep
    if kind is None and targets is not None:
        keep = expand_columns(_column_spec(targets), log.target_names, f"{path.name} targets")
        i = [log.target_names.index(n) for n in keep]
        log.targets, log.target_names = log.targets[:, i], keep
    data = _stack([log], [0], path.name)
    data.rows["in_file"] = _bag_message_count(path, topic)
    return data


def _bag_message_count(path: Path, topic: str) -> int:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as reader:
        return sum(c.msgcount for c in reader.connections if c.topic == topic)


def _stack(logs, ids, source: str) -> LogData:
    first = logs[0]
    for log in logs[1:]:
        if log.joint_names != first.joint_names or log.target_names != first.target_names:
            raise LogError(f"{source}: trajectories differ in their columns")
    data = LogData(
        X=np.vstack([log.X() for log in logs]),
        Y=np.vstack([log.targets for log in logs]),
        t=np.concatenate([log.t for log in logs]),
        groups=np.concatenate([np.full(len(log), i) for log, i in zip(logs, ids)]),
        joint_names=list(first.joint_names),
        target_names=list(first.target_names),
        derived=sorted({d for log in logs for d in log.derived}),
        source=first.source if len(logs) == 1 else f"{source} ({len(logs)} trajectories)",
        rows={"read": int(sum(len(log) for log in logs))},
    )
    if len(logs) == 1:
        data.groups = np.zeros(len(first), dtype=np.int64)
    return data


def _time_window(data: LogData, t_start, t_end) -> LogData:
    keep = np.ones(len(data.t), bool)
    if t_start is not None:
        keep &= data.t >= t_start
    if t_end is not None:
        keep &= data.t <= t_end
    if not keep.any():
        raise LogError(f"{data.source}: no rows in the time window {t_start}..{t_end} s; the "
                       f"log spans t = {data.t.min():.6g}..{data.t.max():.6g} s")
    data.rows["outside_time_window"] = int((~keep).sum())
    data.rows["used"] = int(keep.sum())
    data.rows["dropped_by_reader"] = data.rows["in_file"] - data.rows["read"]
    data.X, data.Y, data.t, data.groups = (a[keep] for a in (data.X, data.Y, data.t, data.groups))
    return data


# -- train --------------------------------------------------------------------------------------
def run_train(args) -> int:
    say = _reporter(args.quiet)
    options = data_options(args)
    say(f"reading {args.data} …")
    data = read_data(args.data, options, t_start=args.t_start, t_end=args.t_end, report=_warn)
    say(_describe(data))
    estimator = make_estimator(args, data)
    units = _target_units(args.target_units, data.target_names)
    search = None
    if args.preset == "quick" and _has_grid(estimator):
        from ..compensation.tuning import segment_groups, tune
        from ..sim.collection import dask_backend

        where = f"Dask scheduler {args.dask}" if args.dask else "local processes"
        say(f"tuning {args.model} (quick grid, grouped 5-fold CV) on {where} …")
        with dask_backend(args.dask):
            model, search = tune(estimator, data.X, data.Y, groups=segment_groups(data.groups),
                                 preset="quick", cv="grouped", target_names=data.target_names,
                                 n_jobs=args.jobs, progress=not args.quiet)
        say(f"best {search.best_params[0]}, CV MSE {-search.mean_score[0]:.4g}")
    else:
        why = "" if args.preset == "none" else " (no grid: its parameters are fitted from data)"
        say(f"fitting {args.model}{why} …")
        model = estimator.fit(data.X, data.Y)
    extra = _provenance(args, options, data, model, search)
    from ..compensation.persistence import save_model

    args.out.parent.mkdir(parents=True, exist_ok=True)
    sensor_frame = args.sensor_frame or ("S" if _is_wrench(data.target_names) else "joints")
    save_model(model, args.out, target_names=data.target_names, target_units=units,
               sensor_frame=sensor_frame, extra=extra)
    say(f"saved {args.out}")
    return 0


def make_estimator(args, data: LogData):
    """The unfitted compensator `args` ask for, checked against the data's targets."""
    from ..compensation.forest import RandomForestCompensator

    features = args.features
    if args.model == "rf":
        # One thread per forest: the search runs fits in parallel, and a forest's own threads
        # would add its trees' predictions in a varying order (round-off differences).
        return RandomForestCompensator(features=features or "q,qd,qdd", random_state=args.seed,
                                       n_jobs=1)
    if args.model == "svr":
        from ..compensation.svr import SVRCompensator

        return SVRCompensator(features=features or "q,qd,qdd")
    if args.model == "gpr":
        from ..compensation.gpr import GPRCompensator

        return GPRCompensator(features=features or "q,qd,qdd", random_state=args.seed)
    if args.model == "physics":
        return _physics(args, data, features or "q,qd,qdd")
    from ..compensation.hybrid import HybridCompensator

    residual = RandomForestCompensator(features=features or "q", min_samples_leaf=5,
                                       random_state=args.seed)
    return HybridCompensator(physics=_physics(args, data, "q,qd,qdd"), residual=residual)


def _physics(args, data: LogData, features: str):
    from ..compensation.physics import PhysicsPayloadCompensator

    if not _is_wrench(data.target_names):
        raise ValueError(
            f"--model {args.model} predicts a wrench: 6 targets named *Fx, *Fy, *Fz, *Tx, *Ty, "
            f"*Tz (N, N·m) in the sensor frame; got {data.target_names}. Joint torques need "
            f"rf, svr or gpr"
        )
    if args.robot is None:
        raise ValueError(f"--model {args.model} needs --robot FILE (URDF/SDF) with "
                         f"--sensor-frame NAME, or --robot {BUILTIN_ROBOT} for the simulated arm")
    if features == "q,qd":
        raise ValueError("physics takes --features q (static: gravity only) or q,qd,qdd")
    mode = "static" if features == "q" else "dynamic"
    if args.robot == BUILTIN_ROBOT:
        return PhysicsPayloadCompensator(features=features, mode=mode,
                                         scenario_yaml=data.scenario_yaml)
    robot = Path(args.robot)
    if not robot.is_file():
        raise FileNotFoundError(f"--robot {robot}: no such file")
    if not args.sensor_frame:
        raise ValueError(f"--robot {robot} needs --sensor-frame (the frame of the targets)")
    return PhysicsPayloadCompensator(features=features, mode=mode, robot=str(robot.resolve()),
                                     sensor_frame=args.sensor_frame, base_frame=args.base_frame)


def _is_wrench(names) -> bool:
    """True for 6 names ending in Fx, Fy, Fz, Tx, Ty, Tz (or force_x … torque_z), in order."""
    if len(names) != 6:
        return False
    aliases = [(a.lower(), ("force" if a[0] == "F" else "torque") + a[1]) for a in WRENCH_AXES]
    squashed = [re.sub(r"[^a-z]", "", n.lower()) for n in names]
    return all(s.endswith(alias) for s, alias in zip(squashed, aliases))


def _has_grid(estimator) -> bool:
    from ..compensation.tuning import presets_of

    return "quick" in presets_of(estimator)


def _target_units(text: str | None, names: list[str]) -> list[str]:
    if text:
        units = [u.strip() for u in text.split(",")]
        if len(units) != len(names):
            raise ValueError(f"--target-units gives {len(units)} units for {len(names)} "
                             f"targets {names}")
        return units
    if _is_wrench(names):
        return list(WRENCH_UNITS)
    return ["N*m"] * len(names)


def _provenance(args, options, data: LogData, model, search) -> dict:
    """What the manifest's ``extra`` keeps about the training run."""
    from ..data.logs import read_table

    sg = read_table.__kwdefaults__  # the readers' Savitzky–Golay window (s) and order
    return {
        "data": {
            "file": str(args.data),
            "kind": "bag" if _is_bag(args.data) else "table",
            "source": data.source,
            "options": options,
            "time_window_s": [args.t_start, args.t_end],
        },
        "columns": {
            "joints": data.joint_names,
            "targets": data.target_names,
            "derived": {k: {"method": "savitzky_golay", "window_s": sg["sg_window"],
                            "polyorder": sg["sg_polyorder"]} for k in data.derived},
        },
        "training_range": {
            "t_s": [float(data.t.min()), float(data.t.max())],
            "targets": {n: [float(lo), float(hi)] for n, lo, hi
                        in zip(data.target_names, data.Y.min(axis=0), data.Y.max(axis=0))},
            "inputs": "see the manifest's input_range",
        },
        "rows": data.rows,
        "reader_warnings": data.warnings,
        "model": {"kind": args.model, "params": _plain(model.get_params(deep=False))},
        "tuning": search.to_dict() if search is not None else None,
        "dask": args.dask,
    }


def _plain(params: dict) -> dict:
    """The JSON-friendly parameters (numbers, strings, lists of them); others by type name."""
    out = {}
    for k, v in params.items():
        if k == "scenario_yaml":
            out[k] = None if v is None else "<scenario of the training data>"
        elif v is None or isinstance(v, (bool, int, float, str)):
            out[k] = v
        elif isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
            out[k] = list(v)
        else:
            out[k] = type(v).__name__
    return out


# -- evaluate -----------------------------------------------------------------------------------
def run_evaluate(args) -> int:
    from ..compensation.metrics import report
    from ..compensation.persistence import load_model, read_manifest

    say = _reporter(args.quiet)
    manifest = read_manifest(args.model)
    trained_on = manifest.get("extra", {}).get("data", {})
    same_kind = trained_on.get("kind") == ("bag" if _is_bag(args.data) else "table")
    options = data_options(args, trained_on.get("options") if same_kind else None)
    say(f"reading {args.data} …")
    data = read_data(args.data, options, t_start=args.t_start, t_end=args.t_end, report=_warn)
    say(_describe(data))
    _check_compatible(manifest, data, args)
    model = load_model(args.model, expect_n_joints=data.n_joints)

    prediction = np.asarray(model.predict(data.X)).reshape(data.Y.shape)
    outside = model.out_of_domain(data.X)
    names = data.target_names
    metrics = {"all": report(data.Y, prediction, target_names=names)}
    for key, rows in (("in_domain", ~outside), ("out_of_domain", outside)):
        metrics[key] = (report(data.Y[rows], prediction[rows], target_names=names)
                        if rows.sum() >= 2 else None)
    result = {
        "model": str(args.model),
        "model_class": manifest["model_class"].rsplit(".", 1)[-1],
        "data": str(args.data),
        "source": data.source,
        "rows": data.rows,
        "reader_warnings": data.warnings,
        "in_domain_rows": int((~outside).sum()),
        "out_of_domain_rows": int(outside.sum()),
        "out_of_domain_fraction": float(outside.mean()),
        "out_of_domain_by_input": _outside_by_input(model, data.X),
        "target_units": dict(zip(names, manifest["target_units"])),
        "metrics": metrics,
    }
    print_evaluation(result)
    if args.json is not None:
        from ..io import atomic_write_text

        atomic_write_text(args.json, json.dumps(result, indent=2))
        say(f"wrote {args.json}")
    return 0


def _check_compatible(manifest: dict, data: LogData, args) -> None:
    trained = manifest.get("extra", {}).get("columns", {})
    if manifest["n_joints"] != data.n_joints:
        raise ValueError(
            f"{args.model} was trained on {manifest['n_joints']} joints "
            f"{trained.get('joints', '')}; {args.data.name} gives {data.n_joints} "
            f"{data.joint_names}: another robot, or pass --positions"
        )
    if manifest["n_outputs"] != len(data.target_names):
        raise ValueError(
            f"{args.model} predicts {manifest['n_outputs']} targets {manifest['target_names']}; "
            f"{args.data.name} gives {len(data.target_names)} {data.target_names}: pass --targets"
        )
    if manifest["target_names"] != data.target_names:
        _warn(f"warning: target names differ: model {manifest['target_names']}, "
              f"data {data.target_names}; compared in this order")


def _outside_by_input(model, X) -> dict:
    """Rows outside the training range, per used input column (only columns with any)."""
    from ..compensation.features import feature_names

    used = feature_names(model.features, model.n_joints_)
    Z = X[:, : len(used)]
    counts = ((Z < model.input_min_[: len(used)]) | (Z > model.input_max_[: len(used)])).sum(0)
    return {n: int(c) for n, c in zip(used, counts) if c}


def print_evaluation(result: dict, file=None) -> None:
    """The evaluation as a small table: all rows, then variance score in and out of domain."""
    file = file or sys.stdout
    m = result["metrics"]
    print(f"\n{result['model']} ({result['model_class']}) on {result['data']}: "
          f"{result['rows']['used']} rows, {result['out_of_domain_rows']} "
          f"({100 * result['out_of_domain_fraction']:.1f} %) outside the training range",
          file=file)
    worst = sorted(result["out_of_domain_by_input"].items(), key=lambda kv: -kv[1])[:4]
    if worst:
        print("  rows outside, by input: " + ", ".join(f"{k} {v}" for k, v in worst), file=file)
    print(f"\n  {'target':<10}{'unit':<6}{'mse':>11}{'nmse':>8}{'var.score':>11}"
          f"{'in-domain':>11}{'out-of-dom.':>12}", file=file)
    print(f"  {'rows':<16}{result['rows']['used']:>30}{result['in_domain_rows']:>11}"
          f"{result['out_of_domain_rows']:>12}", file=file)
    for name, row in m["all"].items():
        parts = [m[k][name]["variance_score"] if m[k] else None
                 for k in ("in_domain", "out_of_domain")]
        print(f"  {name:<10}{result['target_units'][name]:<6}{_num(row['mse'], 11, '.4g')}"
              f"{_num(row['nmse'], 8, '.3f')}{_num(row['variance_score'], 11, '.3f')}"
              f"{_num(parts[0], 11, '.3f')}{_num(parts[1], 12, '.3f')}", file=file)
    print("  (in-domain / out-of-domain columns: variance score on those rows)\n", file=file)


def _num(x, width: int, fmt: str) -> str:
    return f"{'–':>{width}}" if x is None else f"{x:>{width}{fmt}}"


# -- output ---------------------------------------------------------------------------------------
def _reporter(quiet: bool):
    def say(message: str) -> None:
        if not quiet:
            print(message, file=sys.stderr, flush=True)

    return say


def _warn(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _describe(data: LogData) -> str:
    r = data.rows
    derived = f"; {', '.join(data.derived)} from Savitzky–Golay" if data.derived else ""
    return (f"{r['used']} rows used of {r['in_file']} in the file ({r['dropped_by_reader']} "
            f"dropped by the reader, {r['outside_time_window']} outside the time window), "
            f"{data.n_joints} joints, {len(data.target_names)} targets{derived}")


def main(argv=None) -> int:
    """Runs train/evaluate alone (``python -m ftdrake.train``), with errors reported as the
    ``ftdrake`` command does; ``ftdrake train|evaluate`` is the usual way."""
    parser = argparse.ArgumentParser(prog="ftdrake")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (ValueError, FileNotFoundError) as e:  # ConfigError, LogError, ModelFileError too
        print(f"ftdrake {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
