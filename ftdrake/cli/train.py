"""`ftdrake train` and `ftdrake evaluate`: fit a compensator on a robot log, score it on another.

Both commands read a log with :func:`ftdrake.data.training.load_training_data` — a CSV/Parquet
table or a ROS bag (a ROS 1 ``.bag`` file or a ROS 2 bag folder) — into the model layout
``X = [q, q̇, q̈]`` (rad, rad/s, rad/s²) and targets ``Y`` (a wrench in N, N·m, or joint
torques in N·m; any number of columns)::

    ftdrake train --data id1.csv --targets 'tau_*' --velocities 'qd_*' --model rf --out m.ftd
    ftdrake evaluate --model m.ftd --data id2.csv --json eval.json

The read flags are the fields of :class:`~ftdrake.data.training.ReadOptions` (``--positions``
↔ ``positions``; see it for their meaning); the model's manifest keeps them, and `evaluate`
reads with the same ones unless told otherwise (column and topic flags only when the data is
of the same kind, table or bag). ``--t-start``/``--t-end`` keep the rows in a time window
(s, on the log's own time axis); derivatives are computed on the whole log first.
``--qdd-estimate causal`` trains on the q̈ estimate the loop makes (see ReadOptions).

`train` tunes the model with the ``quick`` grid and grouped CV (``--preset none`` fits the
defaults), locally or on a Dask cluster (``--dask ADDRESS``), saves it with
:func:`~ftdrake.compensation.persistence.save_model` and prints the file's size. The
manifest's ``extra`` records the data file and its ReadOptions, the columns used and how the
computed ones were derived, the training ranges of time and targets (those of the inputs are
the manifest's ``input_range``), the row counts (in the file, dropped by the reader, outside
the time window, used) with the reader's warnings, and the search result. `evaluate` reports
per-target MSE, NMSE and variance score on all rows, on the rows inside the training range
of every input, and on the rows outside it.

Every problem a user can fix is one line naming the flag that fixes it (exit code 2); rows the
reader dropped or reordered are printed as warnings with counts.
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import functools
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from ..conventions import TEMPERATURE, WRENCH_AXES, WRENCH_UNITS
from ..data.bag import is_bag
from ..data.logs import QDD_ESTIMATES, option_spelling
from ..data.training import ReadOptions, TrainingData, load_training_data
from ..errors import ConfigError, FtdrakeError, LogError, ModelFileError, RobotModelError

FEATURE_SETS = ("q", "q,qd", "q,qd,qdd")
# `evaluate` prints a warning when a cause flags more than this share of some target's rows.
UNTRUSTED_WARN_FRACTION = 0.1
BUILTIN_ROBOT = "ftdrake"  # --robot value naming ftdrake's simulated arm

_COLUMNS_HELP = ("PAT is a glob ('q_*'), a comma-separated list of names, or a regular "
                 "expression after 're:'. Times are in s on the log's own axis (a bag's: since "
                 "its first joint state).")
# ReadOptions field → (metavar, type, help). Every field is a flag of both commands.
_READ_FLAGS = {
    "positions": ("PAT", str, "joint position columns (rad), default 'q_*'; bags: joint names"),
    "targets": ("PAT", str, ("target columns, default 'meas_*'; bags: effort, wrench or a "
                            "pattern")),
    "velocities": ("PAT", str, "velocity columns (rad/s); default: Savitzky–Golay of q"),
    "accelerations": ("PAT", str, "acceleration columns (rad/s²); default: see --qdd-estimate"),
    "time": ("COL", str, "time column (s), default 't'"),
    "group": ("COL", str, ("trajectory id column: reads a file joining several recordings "
                          "as separate trajectories; default 'trajectory' if there is one")),
    "joint_topic": ("T", str, "bags: JointState topic, default /joint_states"),
    "wrench_topic": ("T", str, "bags: WrenchStamped topic"),
    "position_unit": ("rad|deg", str, "angle unit of the joint columns, default rad"),
    "qdd_estimate": ("savgol|causal", str, ("missing accelerations: savgol (Savitzky–Golay "
                     "of q, default) or causal (the estimate the compensator makes in the "
                     "loop, from q̇; use it for q,qd,qdd models that run in the loop)")),
    "acceleration_cutoff_hz": ("HZ", float, ("cut-off of --qdd-estimate causal; default the "
                               "dataset scenario's compensator.acceleration_cutoff_hz, or 25")),
    "sg_window": ("S", float, "Savitzky–Golay window (s), default 0.1"),
    "sg_polyorder": ("N", int, "Savitzky–Golay polynomial order, default 4"),
    "gap_factor": ("X", float, ("a time step longer than X × the median period is a gap, "
                               "default 3")),
    "temperature": ("COL", str, ("the sensor's temperature column (°C, tables): read as the "
                                "models' last input, so the model learns the zero drift "
                                "with temperature; evaluate then needs it too")),
}
_CHOICES = {"position_unit": ("rad", "deg"), "qdd_estimate": QDD_ESTIMATES}
# Options that describe the file (columns, topics): carried to `evaluate` only from the same
# kind of file. The others (units, derivatives) always are.
_FILE_OPTIONS = ("positions", "targets", "velocities", "accelerations", "time", "group",
                 "joint_topic", "wrench_topic", "temperature")


def register(subparsers) -> None:
    """Adds ``train`` and ``evaluate`` to an ``argparse`` subparsers object."""
    from ..compensation import registry

    models = registry.names()
    p = subparsers.add_parser("train", help="fit a compensator on a robot log; save it",
                              description=_COLUMNS_HELP)
    p.add_argument("--data", type=Path, required=True, metavar="FILE",
                   help="CSV/Parquet table, ROS 1 .bag file or ROS 2 bag folder")
    _add_read_flags(p)
    p.add_argument("--model", choices=models,
                   help=", ".join(f"{n}: {registry.entry(n).summary}" for n in models)
                   + "; physics and hybrid need --robot: on a wrench they identify the payload, "
                   "on joint torques the whole arm (as arm). Default: hybrid when --robot is "
                   "given, else rf")
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
    p.add_argument("--drive-gains", choices=("fixed", "identify"), default="fixed",
                   help="joint-torque targets with --robot: 'identify' when they are only "
                        "proportional to the torques (motor currents, as UR's CB3 driver "
                        "publishes in effort, or another sign convention): a gain per joint "
                        "is identified with the arm's parameters")
    p.add_argument("--identify-mounting", action="store_true",
                   help="physics/hybrid on a wrench: also identify the sensor's mounting "
                        "rotation (the wrench is then reported in the model's frame S)")
    p.add_argument("--weight-without-inertia", action="store_true",
                   help="physics/hybrid on a wrench, dynamic model: also identify a weight the "
                        "tool carries without its inertia (a hanging cable), 4 parameters")
    p.add_argument("--target-units", metavar="U,U,..",
                   help="unit per target (default: N/N*m for wrench axes, else N*m)")
    p.add_argument("--seed", type=int, default=0, help="random state of rf and gpr")
    p.add_argument("--jobs", type=int, default=-1, help="parallel CV fits (-1: all cores)")
    p.add_argument("--dask", metavar="ADDRESS", help="run the grid search on this Dask scheduler")
    p.add_argument("--out", type=Path, required=True, metavar="MODEL")
    p.add_argument("--max-rows", type=int, metavar="N",
                   help="fit on at most N rows covering the log's states (every k-th row, "
                        "then farthest-point in the model's inputs); reported in the model")
    delay = p.add_mutually_exclusive_group()
    delay.add_argument("--delay", type=float, metavar="S",
                       help="the wrench stream's delay behind the joint states (s; negative: "
                            "ahead): corrected in training, kept in the model, applied live")
    delay.add_argument("--align", action="store_true",
                       help="estimate that delay (with the model fitted once; best with a "
                            "physics or hybrid model), report it and correct it")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(run=run_train)

    p = subparsers.add_parser(
        "evaluate", help="score a saved compensator on a robot log",
        description=_COLUMNS_HELP + " Read flags not given are those the model was trained "
        "with (column and topic flags: when the file is of the same kind, table or bag), else "
        "the defaults.")
    p.add_argument("--model", type=Path, required=True, metavar="MODEL")
    p.add_argument("--data", type=Path, required=True, metavar="FILE")
    _add_read_flags(p)
    p.add_argument("--json", type=Path, metavar="OUT", help="also write the results as JSON")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=run_evaluate)


def _add_read_flags(p) -> None:
    for name, (metavar, kind, text) in _READ_FLAGS.items():
        p.add_argument(_flag_name(name), metavar=metavar, type=kind, help=text,
                       choices=_CHOICES.get(name))
    p.add_argument("--no-check-units", dest="check_units", action="store_const", const=False,
                   help="accept positions beyond ±2π rad and velocities that disagree with q")
    p.add_argument("--t-start", type=float, metavar="S", help="drop rows before this time (s)")
    p.add_argument("--t-end", type=float, metavar="S", help="drop rows after this time (s)")


def _flag_name(option: str) -> str:
    return "--" + option.replace("_", "-")


def flag_hint(option: str, value) -> str:
    """How an error tells a command-line user to set reader option `option` to `value`."""
    if option == "check_units":
        return "--no-check-units" if value is False else "omit --no-check-units"
    if value is None:
        return f"omit {_flag_name(option)}"
    return f"{_flag_name(option)} {value}"


def given_read_options(args) -> dict:
    """The ReadOptions fields set on the command line (the others are None)."""
    return {f.name: getattr(args, f.name, None) for f in dc.fields(ReadOptions)}


def _with_flags(base: ReadOptions, args) -> ReadOptions:
    """`base` updated with the flags given; an invalid value's error names its flag."""
    try:
        return base.updated(**given_read_options(args))
    except ConfigError as e:
        message = str(e)
        for f in dc.fields(ReadOptions):
            if message.startswith(f.name + " "):
                message = _flag_name(f.name) + message[len(f.name):]
        raise ConfigError(message) from None


def _read(args, options: ReadOptions, say, static_poses: bool | None = False) -> TrainingData:
    say(f"reading {args.data} …")
    if not args.data.exists():
        raise LogError(f"--data {args.data}: no such file or folder")
    with option_spelling(flag_hint):
        try:
            data = load_training_data(args.data, options, t_start=args.t_start,
                                      t_end=args.t_end, report=_warn,
                                      static_poses=static_poses)
        except LogError as e:
            from ..compensation.calibration import static_table_hint

            hint = static_table_hint(args.data)
            if hint is None:
                raise
            raise LogError(f"{e}; {hint}") from None
    say(_describe(data))
    return data


# -- the model factory --------------------------------------------------------------------------
@dc.dataclass(frozen=True)
class RobotOptions:
    """The robot description a physics-based compensator identifies its payload on.

    robot: URDF/SDF file, or ``"ftdrake"`` for the simulated arm (the arm of a ``collect``
    dataset's scenario, `scenario_yaml`, else the default arm). sensor_frame: frame S of the
    targets in `robot`.
    base_frame: frame of `robot` welded to the world (default: its root).
    """

    robot: str | None = None
    sensor_frame: str | None = None
    base_frame: str | None = None
    scenario_yaml: str | None = None
    drive_gains: str = "fixed"  # joint-torque models: "identify" for currents or unknown signs
    identify_mounting: bool = False  # wrench models: also the sensor's mounting rotation
    weight_without_inertia: bool = False  # wrench models: also a weight without inertia


def make_estimator(model: str, *, features: str | None = None, seed: int = 0,
                   target_names=(), robot: RobotOptions | None = None):
    """The unfitted compensator registered as `model`, with `train`'s defaults.

    Args:
      model: a registry name (``rf``, ``svr``, ``gpr``, ``physics``, ``hybrid``).
      features: ``q``, ``q,qd`` or ``q,qd,qdd``; None: the model's default (physics: q is
        static, q,qd,qdd dynamic; hybrid: the residual forest's, default q).
      seed: random state of the models that have one.
      target_names: the data's targets; a wrench-only model refuses others.
      robot: the robot description of physics and hybrid.

    Errors name the ``train`` flag that fixes them.
    """
    from ..compensation import registry
    from ..compensation.forest import RandomForestCompensator

    entry = registry.entry(model)
    robot = robot or RobotOptions()
    if robot.identify_mounting and (model not in ("physics", "hybrid")
                                    or (target_names and not is_wrench(target_names))):
        raise ConfigError("--identify-mounting is for --model physics or hybrid on a wrench "
                          "(the sensor's mounting rotation)")
    if robot.weight_without_inertia and (model not in ("physics", "hybrid")
                                         or (target_names and not is_wrench(target_names))):
        raise ConfigError("--weight-without-inertia is for --model physics or hybrid on a "
                          "wrench (a weight the tool carries without its inertia)")
    if model in ("physics", "hybrid", "arm") and target_names and not is_wrench(target_names):
        # Joint torques (or anything per joint): the whole arm's rigid-body model.
        physics = _arm(model, robot)
        if model == "hybrid":
            residual = RandomForestCompensator(features=features or "q", min_samples_leaf=5,
                                               random_state=seed)
            return entry.build(physics=physics, residual=residual)
        return physics
    if entry.wrench_only and not is_wrench(target_names):
        raise ConfigError(
            f"--model {model} predicts a wrench: 6 targets named *Fx, *Fy, *Fz, *Tx, *Ty, "
            f"*Tz (N, N·m) in the sensor frame; got {list(target_names)}. Joint torques need "
            f"rf, svr, gpr, or arm/physics/hybrid with --robot (or choose the wrench columns "
            f"with --targets)"
        )
    if model == "hybrid":
        residual = RandomForestCompensator(features=features or "q", min_samples_leaf=5,
                                           random_state=seed)
        return entry.build(physics=_physics(model, robot, "q,qd,qdd"), residual=residual)
    if model == "physics":
        return _physics(model, robot, features or "q,qd,qdd")
    overrides = {"features": features} if features else {}
    if "random_state" in entry.cls().get_params():
        overrides["random_state"] = seed
    return entry.build(**overrides)


def default_model(robot: RobotOptions) -> str:
    """The hybrid (physics + residual) when a robot description is available (a wrench with
    the payload model, joint torques with the arm's rigid-body model): it extrapolates where
    a black box cannot; otherwise the random forest."""
    return "hybrid" if robot.robot is not None else "rf"


def _arm(model: str, robot: RobotOptions):
    """The arm's rigid-body torque model (:class:`~ftdrake.compensation.arm.
    ArmDynamicsCompensator`) on `robot`, with the registry's defaults."""
    from ..compensation.registry import entry
    from ..physics.robot import ftdrake_arm
    from ..physics.scenario_robot import robot_description

    if robot.robot is None:
        raise ConfigError(f"--model {model} on joint torques needs --robot FILE (the arm's "
                          f"URDF/SDF), or --robot {BUILTIN_ROBOT} for the simulated arm")
    options = {"drive_gains": robot.drive_gains}
    if robot.robot == BUILTIN_ROBOT:
        from ..config import parse_config

        description = (robot_description(parse_config(robot.scenario_yaml))
                       if robot.scenario_yaml else ftdrake_arm())
        return entry("arm").build(robot=description.model,
                                  package_xmls=description.package_xmls, **options)
    path = Path(robot.robot)
    if not path.is_file():
        raise RobotModelError(f"--robot {path}: no such file")
    return entry("arm").build(robot=str(path.resolve()), base_frame=robot.base_frame,
                              **options)


def _physics(model: str, robot: RobotOptions | None, features: str):
    from ..compensation.registry import entry

    PhysicsPayloadCompensator = entry("physics").build  # with the registry's defaults
    from ..config import parse_config
    from ..physics.robot import ftdrake_arm
    from ..physics.scenario_robot import robot_description

    robot = robot or RobotOptions()
    if robot.robot is None:
        raise ConfigError(f"--model {model} needs --robot FILE (URDF/SDF) with "
                          f"--sensor-frame NAME, or --robot {BUILTIN_ROBOT} for the simulated "
                          f"arm")
    if features == "q,qd":
        raise ConfigError("physics takes --features q (static: gravity only) or q,qd,qdd")
    mode = "static" if features == "q" else "dynamic"
    if robot.identify_mounting and mode == "static":
        raise ConfigError("--identify-mounting needs --features q,qd,qdd (the dynamic model); "
                          "`ftdrake calibrate` identifies it from static poses")
    if robot.weight_without_inertia and mode == "static":
        raise ConfigError("--weight-without-inertia needs --features q,qd,qdd (only "
                          "accelerations tell a weight without inertia from the tool's mass)")
    build = functools.partial(PhysicsPayloadCompensator, features=features, mode=mode,
                              identify_mounting=robot.identify_mounting,
                              weight_without_inertia=robot.weight_without_inertia)
    if robot.robot == BUILTIN_ROBOT:
        # The arm of the scenario that made the data (a collect dataset stores it), as a
        # robot description; the shipped default arm is robot=None.
        description = ftdrake_arm()
        if robot.scenario_yaml:
            description = robot_description(parse_config(robot.scenario_yaml))
        if description == ftdrake_arm():
            return build()
        return build(robot=description.model, sensor_frame=description.sensor_frame,
                     package_xmls=description.package_xmls)
    path = Path(robot.robot)
    if not path.is_file():
        raise RobotModelError(f"--robot {path}: no such file")
    if not robot.sensor_frame:
        raise ConfigError(f"--robot {path} needs --sensor-frame (the frame of the targets)")
    return build(robot=str(path.resolve()), sensor_frame=robot.sensor_frame,
                 base_frame=robot.base_frame)


def is_wrench(names) -> bool:
    """True for 6 names ending in Fx, Fy, Fz, Tx, Ty, Tz (or force_x … torque_z), in order."""
    if len(names) != 6:
        return False
    aliases = [(a.lower(), ("force" if a[0] == "F" else "torque") + a[1]) for a in WRENCH_AXES]
    squashed = [re.sub(r"[^a-z]", "", n.lower()) for n in names]
    return all(s.endswith(alias) for s, alias in zip(squashed, aliases, strict=True))


def target_units(text: str | None, names: list[str]) -> list[str]:
    """The unit of each target: from ``--target-units``, else N/N·m for a wrench, else N·m."""
    if text:
        units = [u.strip() for u in text.split(",")]
        if len(units) != len(names):
            raise ConfigError(f"--target-units gives {len(units)} units for {len(names)} "
                              f"targets {names}")
        return units
    if is_wrench(names):
        return list(WRENCH_UNITS)
    return ["N*m"] * len(names)


# -- train --------------------------------------------------------------------------------------
def run_train(args) -> int:
    from ..compensation import registry
    from ..compensation.persistence import save_model

    say = _reporter(args.quiet)
    options = _with_flags(ReadOptions(), args)
    data = _read(args, options, say)
    robot = RobotOptions(args.robot, args.sensor_frame, args.base_frame, data.scenario_yaml,
                         args.drive_gains, args.identify_mounting,
                         args.weight_without_inertia)
    if args.model is None:
        args.model = default_model(robot)
        say(f"--model not given: {args.model} "
            + ("(a robot description and wrench targets: physics + learned residual)"
               if args.model == "hybrid" else "(no --robot: a black box)"))
    estimator = make_estimator(args.model, features=args.features, seed=args.seed,
                               target_names=data.target_names, robot=robot)
    units = target_units(args.target_units, data.target_names)
    data, stream_delay = _align_streams(args, data, estimator, say)
    data, subsample = _subsample(args, data, estimator, say)
    search = None
    if args.preset == "quick" and "quick" in registry.entry(args.model).presets:
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
        say(f"fitting {args.model}{why} on {len(data.X)} rows …")
        started = time.perf_counter()
        model = _fit(estimator, data, needs_robot=registry.entry(args.model).needs_robot)
        say(f"fitted in {time.perf_counter() - started:.1f} s")
    if hasattr(model, "summary"):  # physics and hybrid: the identified payload
        print(model.summary())
    extra = provenance(args.data, data, model, search, kind=args.model,
                       time_window=(args.t_start, args.t_end), dask=args.dask)
    if subsample is not None:
        extra["subsample"] = subsample
    if stream_delay is not None:  # the chain applies it live (CompensationChain)
        model.wrench_delay_s_ = stream_delay["delay_s"]
        extra["stream_delay"] = stream_delay
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sensor_frame = args.sensor_frame or ("S" if is_wrench(data.target_names) else "joints")
    save_model(model, args.out, target_names=data.target_names, target_units=units,
               sensor_frame=sensor_frame, extra=extra)
    print(f"saved {args.out} ({file_size(args.out.stat().st_size)})")
    return 0


def _subsample(args, data: TrainingData, estimator, say):
    """--max-rows: (data cut to the covering rows, what was done) or (data, None)."""
    from ..compensation.features import check_feature_set
    from ..data.subsample import OVERSAMPLE, covering_rows

    if args.max_rows is not None and args.max_rows < 1:
        raise ConfigError(f"--max-rows {args.max_rows}: must be a whole number >= 1")
    if args.max_rows is None or len(data.X) <= args.max_rows:
        return data, None
    features = getattr(estimator, "features", None)
    columns = check_feature_set(features) * data.n_joints if features else None
    say(f"choosing {args.max_rows} of {len(data.X)} rows that cover the log's states …")
    started = time.perf_counter()
    rows = covering_rows(data.X, args.max_rows, groups=data.groups, columns=columns)
    elapsed = time.perf_counter() - started
    say(f"chose {len(rows)} rows in {elapsed:.1f} s")
    done = {"rows_in": len(data.X), "rows_used": len(rows), "max_rows": args.max_rows,
            "method": "every k-th row, then farthest-point in the model's scaled inputs",
            "oversample": OVERSAMPLE, "metric_columns": columns or data.X.shape[1]}
    return dc.replace(data, X=data.X[rows], Y=data.Y[rows], t=data.t[rows],
                      groups=data.groups[rows], rows=dict(data.rows, used=len(rows))), done


def _align_streams(args, data: TrainingData, estimator, say):
    """--delay / --align: (data with the targets moved the delay earlier, the delay as a
    dict) or (data, None) without either (:mod:`ftdrake.data.stream_delay`)."""
    from sklearn.base import clone

    from ..compensation import registry
    from ..data.stream_delay import align_training_data, estimate_training_delay

    if args.delay is None and not args.align:
        return data, None
    if data.static:
        raise LogError("--delay/--align: a table of static poses has no time axis to align")
    if args.align:
        needs_robot = registry.entry(args.model).needs_robot
        say(f"estimating the wrench stream's delay with {args.model} …")
        estimate = estimate_training_delay(
            lambda d: _fit(clone(estimator), d, needs_robot=needs_robot), data)
        found = estimate.as_dict()
        say(f"wrench stream delay: {estimate.delay_s * 1e3:.2f} ± {estimate.std_s * 1e3:.2f} ms "
            f"({estimate.samples:.2f} samples); corrected"
            + ("" if found["distinct_from_zero"] else " (within two standard errors of 0)"))
    else:
        found = {"delay_s": float(args.delay), "given": True}
    return align_training_data(data, found["delay_s"]), found


def _fit(estimator, data: TrainingData, *, needs_robot: bool):
    """Fits `estimator`. A robot-based model's ValueErrors are about the robot description
    (joint count, frames); they name the flags that choose it."""
    if not needs_robot:
        return estimator.fit(data.X, data.Y)
    try:
        return estimator.fit(data.X, data.Y)
    except FtdrakeError:
        raise
    except ValueError as e:
        raise RobotModelError(f"{e} (check --robot, --sensor-frame, --base-frame and "
                              f"--positions)") from e


def file_size(n_bytes: int) -> str:
    """``1234567`` → ``"1.23 MB"`` (decimal units, as file managers show them)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes} B"


def provenance(path: Path, data: TrainingData, model, search, *, kind: str,
               time_window=(None, None), dask: str | None = None) -> dict:
    """What the manifest's ``extra`` keeps about a training run on `data` read from `path`."""
    return {
        "data": {
            "file": str(path),
            "kind": data.kind,
            "source": data.source,
            "options": data.options.to_dict(),
            "time_window_s": list(time_window),
        },
        "columns": {
            "joints": data.joint_names,
            "targets": data.target_names,
            "temperature": data.options.temperature if data.has_temperature else None,
            "derived": data.derivation,
        },
        "training_range": {
            "t_s": [float(data.t.min()), float(data.t.max())],
            "targets": {n: [float(lo), float(hi)] for n, lo, hi
                        in zip(data.target_names, data.Y.min(axis=0), data.Y.max(axis=0),
                               strict=True)},
            "inputs": "see the manifest's input_range",
        },
        "rows": data.rows,
        "reader_warnings": data.warnings,
        "model": {"kind": kind, "params": _plain(model.get_params(deep=False))},
        "tuning": search.to_dict() if search is not None else None,
        "dask": dask,
    }


def _plain(params: dict) -> dict:
    """The JSON-friendly parameters (numbers, strings, lists of them); others by type name."""
    out = {}
    for k, v in params.items():
        if k == "robot" and isinstance(v, str) and v.lstrip().startswith("directives:"):
            out[k] = "<model directives of the training data's robot>"
        elif v is None or isinstance(v, (bool, int, float, str)):
            out[k] = v
        elif isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
            out[k] = list(v)
        else:
            out[k] = type(v).__name__
    return out


# -- evaluate -----------------------------------------------------------------------------------
def stored_read_options(manifest: dict, path: Path) -> ReadOptions:
    """The ReadOptions a model was trained with, for reading `path`: all of them when `path`
    is of the same kind (table or bag) as the training data, else only those that are not
    about columns and topics."""
    trained_on = manifest.get("extra", {}).get("data", {})
    stored = dict(trained_on.get("options") or {})
    if trained_on.get("kind") != ("bag" if is_bag(path) else "table"):
        stored = {k: v for k, v in stored.items() if k not in _FILE_OPTIONS}
    try:
        return ReadOptions.from_dict(stored)
    except ConfigError as e:
        raise ModelFileError(f"--model: the manifest's read options: {e}") from None


def run_evaluate(args) -> int:
    from ..compensation.metrics import report
    from ..compensation.persistence import load_model, read_manifest

    say = _reporter(args.quiet)
    if not args.model.is_file():
        raise ModelFileError(f"--model {args.model}: no such file")
    manifest = read_manifest(args.model)
    options = _with_flags(stored_read_options(manifest, args.data), args)
    # A table without its time column is a table of static poses (what `calibrate` takes).
    data = _read(args, options, say, static_poses=None)
    _check_compatible(manifest, data, args)
    model = load_model(args.model, expect_n_joints=data.n_joints)
    _check_temperature(model, data, args)

    prediction = np.asarray(model.predict(data.X)).reshape(data.Y.shape)
    std = (np.asarray(model.predict_std(data.X)).reshape(data.Y.shape)
           if getattr(model, "provides_std", False) else None)
    outside = model.out_of_domain(data.X)
    names = data.target_names
    metrics = {"all": report(data.Y, prediction, target_names=names, std=std)}
    for key, rows in (("in_domain", ~outside), ("out_of_domain", outside)):
        metrics[key] = (report(data.Y[rows], prediction[rows], target_names=names,
                               std=None if std is None else std[rows])
                        if rows.sum() >= 2 else None)
    trust = _trust(names, prediction, std, outside,
                   *_trust_references(model, manifest, names, std))
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
        "target_units": dict(zip(names, manifest["target_units"], strict=True)),
        "std": (None if std is None else "calibrated" if getattr(model, "std_includes_noise",
                                                                   False) else "not calibrated"),
        "metrics": metrics,
        "trust": trust,
    }
    print_evaluation(result)
    for line in trust["warnings"]:
        _warn(line)
    if args.json is not None:
        from ..io import atomic_write_text

        atomic_write_text(args.json, json.dumps(result, indent=2))
        say(f"wrote {args.json}")
    return 0


def _trust_references(model, manifest: dict, names, std):
    """What `evaluate` compares predictions with to flag them: the model's RMS residual on
    its training rows (models with a calibrated std that keep ``residual_rms_``: the GP,
    physics) and the training range of every target (from the manifest), or None."""
    residual = None
    if std is not None and getattr(model, "std_includes_noise", False):
        value = getattr(model, "residual_rms_", None)
        if value is not None and np.size(value) == len(names):
            residual = np.asarray(value, dtype=float)
    ranges = manifest.get("extra", {}).get("training_range", {}).get("targets")
    target_range = None
    if isinstance(ranges, dict) and all(n in ranges for n in names):
        target_range = tuple(np.array([ranges[n][i] for n in names], dtype=float)
                             for i in (0, 1))
    return residual, target_range


def _trust(names, prediction, std, outside, residual, target_range) -> dict:
    """Per target, the share of rows whose prediction should not be trusted, and why.

    A row is flagged when any used input lies outside its training range, when the
    predictive std exceeds ``UNCERTAIN_STD_FACTOR`` × the training residual (the model lacks
    data there), or when the prediction lies outside the training range of its target
    widened by ``TARGET_RANGE_MARGIN`` (extrapolating). One warning line per cause that
    flags more than ``UNTRUSTED_WARN_FRACTION`` of the rows on some target.
    """
    from ..compensation.metrics import TARGET_RANGE_MARGIN, UNCERTAIN_STD_FACTOR

    k = len(names)
    causes = {"inputs_outside_range": np.repeat(outside[:, None], k, axis=1)}
    if std is not None and residual is not None:
        causes["std_above_factor_x_residual"] = std > UNCERTAIN_STD_FACTOR * residual
    if target_range is not None:
        lo, hi = target_range
        pad = TARGET_RANGE_MARGIN * (hi - lo)
        causes["prediction_outside_target_range"] = ((prediction < lo - pad)
                                                     | (prediction > hi + pad))
    flagged = np.logical_or.reduce(list(causes.values()))
    share = {cause: dict(zip(names, np.round(rows.mean(axis=0), 4).tolist(), strict=True))
             for cause, rows in causes.items()}
    said = {
        "inputs_outside_range": "inputs outside the training range",
        "std_above_factor_x_residual": (f"predictive std > {UNCERTAIN_STD_FACTOR:g}× the "
                                        "training residual (the model lacks data there)"),
        "prediction_outside_target_range": (f"predictions beyond the training range of the "
                                            f"target (±{100 * TARGET_RANGE_MARGIN:.0f} %)"),
    }
    warnings = []
    if outside.mean() > UNTRUSTED_WARN_FRACTION:
        warnings.append(f"warning: {said['inputs_outside_range']} on "
                        f"{100 * outside.mean():.0f} % of rows")
    for cause, per_target in list(share.items())[1:]:
        worst = {n: v for n, v in per_target.items() if v > UNTRUSTED_WARN_FRACTION}
        if worst:
            listed = ", ".join(f"{n} {100 * v:.0f} %" for n, v in worst.items())
            warnings.append(f"warning: {said[cause]} on {listed} of rows")
    if warnings:
        warnings.append("warning: predictions on flagged rows cannot be trusted; see "
                        "'trust' in --json (share of rows flagged per target and cause)")
    return {
        "uncertain_std_factor": UNCERTAIN_STD_FACTOR if "std_above_factor_x_residual" in causes
        else None,
        "target_range_margin": TARGET_RANGE_MARGIN,
        "residual_rms": None if residual is None else dict(
            zip(names, residual.round(6).tolist(), strict=True)),
        "untrusted_fraction": dict(zip(names, np.round(flagged.mean(axis=0), 4).tolist(),
                                       strict=True)),
        "by_cause": share,
        "warnings": warnings,
    }


def _check_compatible(manifest: dict, data: TrainingData, args) -> None:
    trained = manifest.get("extra", {}).get("columns", {})
    if manifest["n_joints"] != data.n_joints:
        raise LogError(
            f"{args.model} was trained on {manifest['n_joints']} joints "
            f"{trained.get('joints', '')}; {args.data.name} gives {data.n_joints} "
            f"{data.joint_names}: another robot, or pass --positions"
        )
    if manifest["n_outputs"] != len(data.target_names):
        raise LogError(
            f"{args.model} predicts {manifest['n_outputs']} targets {manifest['target_names']}; "
            f"{args.data.name} gives {len(data.target_names)} {data.target_names}: pass --targets"
        )
    if manifest["target_names"] != data.target_names:
        _warn(f"warning: target names differ: model {manifest['target_names']}, "
              f"data {data.target_names}; compared in this order")


def _check_temperature(model, data: TrainingData, args) -> None:
    """A model trained with the sensor temperature needs it in the data, and the other way
    round; the error names the column and the flag."""
    needs = bool(getattr(model, "temperature_in_", False))
    if needs and not data.has_temperature:
        raise LogError(
            f"{args.model} was trained with the sensor temperature (°C) as an input; "
            f"{args.data.name} was read without one: name its column with --temperature COL "
            f"(e.g. --temperature {TEMPERATURE})")
    if data.has_temperature and not needs:
        raise LogError(
            f"{args.model} was trained without the sensor temperature; omit --temperature "
            f"{data.options.temperature}")


def _outside_by_input(model, X) -> dict:
    """Rows outside the training range, per used input column (only columns with any)."""
    from ..compensation.features import feature_names

    used = feature_names(model.features, model.n_joints_)
    Z = X[:, : len(used)]
    counts = ((Z < model.input_min_[: len(used)]) | (Z > model.input_max_[: len(used)])).sum(0)
    return {n: int(c) for n, c in zip(used, counts, strict=True) if c}


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
    if result.get("std"):
        rows = m["in_domain"] or m["all"]
        which = "in-domain" if m["in_domain"] else "all"
        print(f"  coverage of the predictive std ({result['std']}), {which} rows: fraction "
              "within the central 68 % / 95 % interval", file=file)
        for name, row in rows.items():
            print(f"  {name:<10}{_num(row.get('coverage_68'), 8, '.3f')}"
                  f"{_num(row.get('coverage_95'), 8, '.3f')}", file=file)
        print(file=file)
    trust = result.get("trust")
    if trust:
        shares = ", ".join(f"{n} {100 * v:.0f} %" for n, v in trust["untrusted_fraction"].items())
        print(f"  rows flagged as not to be trusted ({', '.join(trust['by_cause'])}): "
              f"{shares}\n", file=file)


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


def _describe(data: TrainingData) -> str:
    r = data.rows
    methods = {"savitzky_golay": "Savitzky–Golay", "causal": "the loop's causal estimate"}
    derived = "".join(f"; {k} from {methods[v['method']]}" for k, v in data.derivation.items())
    return (f"{r['used']} rows used of {r['in_file']} in the file ({r['dropped_by_reader']} "
            f"dropped by the reader, {r['outside_time_window']} outside the time window), "
            f"{data.n_joints} joints, {len(data.target_names)} targets{derived}")


def main(argv=None) -> int:
    """Runs train/evaluate alone (``python -m ftdrake.cli.train``), with errors reported as
    the ``ftdrake`` command does: a :class:`~ftdrake.errors.FtdrakeError` is one line and exit
    code 2; any other exception is a bug and keeps its traceback."""
    parser = argparse.ArgumentParser(prog="ftdrake")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except FtdrakeError as e:
        print(f"ftdrake {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
