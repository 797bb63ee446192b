"""`ftdrake train` and `ftdrake evaluate`: fit a compensator on a robot log, score it on another.

Both commands read a log with :func:`ftdrake.data.training.load_training_data` — a CSV/Parquet
table or a ROS bag (a ROS 1 ``.bag`` file or a ROS 2 bag folder) — into the model layout
``X = [q, q̇, q̈]`` (rad, rad/s, rad/s²) and targets ``Y`` (a wrench in N, N·m, or joint
torques in N·m; any number of columns)::

    ftdrake train --data id1.csv --targets 'tau_*' --velocities 'qd_*' --kind rf --out m.ftd
    ftdrake evaluate --model m.ftd --data id2.csv --json eval.json

The read flags are the fields of :class:`~ftdrake.data.training.ReadOptions` (``--positions``
↔ ``positions``; see it for their meaning); the model's manifest keeps them, and `evaluate`
reads with the same ones unless told otherwise (column and topic flags only when the data is
of the same kind, table or bag). ``--t-start``/``--t-end`` keep the rows in a time window
(s, on the log's own time axis); derivatives are computed on the whole log first.
``--qdd-estimate causal`` trains on the q̈ estimate the loop makes (see ReadOptions).

`train` tunes the model with the ``quick`` grid and grouped CV (``--preset none`` fits the
defaults), locally or on a Dask cluster (``--cluster ADDRESS``), saves it with
:func:`~ftdrake.compensation.files.persistence.save_model` and prints the file's size. The
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
import sys
import time
from pathlib import Path

import numpy as np
from sklearn.base import clone

from ..compensation.calibration.calibration import static_table_hint
from ..compensation.estimators import registry
from ..compensation.estimators.build import BUILTIN_ROBOT, RobotOptions, is_wrench
from ..compensation.estimators.domain import IN_DOMAIN_SOURCES, MIN_GROUPS
from ..compensation.estimators.hybrid import HybridCompensator
from ..compensation.estimators.tuning import segment_groups, tune
from ..compensation.evaluation.evaluation import target_ranges
from ..compensation.evaluation.metrics import coverage
from ..compensation.features import check_feature_set
from ..compensation.files.persistence import save_model
from ..conventions import WRENCH_UNITS
from ..data.logs import QDD_ESTIMATES, option_spelling
from ..data.stream_delay import align_training_data, estimate_training_delay
from ..data.subsample import OVERSAMPLE, covering_rows
from ..data.training import ReadOptions, TrainingData, load_training_data
from ..errors import ConfigError, FtdrakeError, LogError, RobotModelError
from ..parallel import dask_backend
from . import args as a
from .args import flag_hint

FEATURE_SETS = ("q", "q,qd", "q,qd,qdd")

COLUMNS_HELP = ("PAT is a glob ('q_*'), a comma-separated list of names, or a regular "
                 "expression after 're:'. Times are in s on the log's own axis (a bag's: since "
                 "its first joint state).")
# ReadOptions field → (metavar, type, help). Every field is a flag of both commands.
_READ_FLAGS = {
    "positions": ("PAT", str, "joint position columns (rad), default 'q_*'; bags: joint names"),
    "targets": ("PAT", str, ("target columns, default 'meas_*'; bags: effort, wrench or a "
                            "pattern")),
    "velocities": ("PAT", str, ("velocity columns (rad/s); default (or 'derive'): "
                               "Savitzky–Golay of q")),
    "accelerations": ("PAT", str, ("acceleration columns (rad/s²); default (or 'derive'): see "
                                   "--qdd-estimate")),
    "time": ("COL", str, "time column (s), default 't'"),
    "group": ("COL", str, ("trajectory id column: reads a file joining several recordings "
                          "as separate trajectories; default 'trajectory' if there is one")),
    "joint_topic": ("T", str, "bags: JointState topic, default /joint_states"),
    "wrench_topic": ("T", str, "bags: WrenchStamped topic"),
    "position_unit": ("rad|deg", str, "angle unit of the joint columns, default rad"),
    "qdd_estimate": ("savgol|causal", str, ("missing accelerations: savgol (Savitzky–Golay "
                     "of q, default) or causal (the estimate the compensator makes in the "
                     "loop, from q̇; use it for q,qd,qdd models that run in the loop)")),
    "acceleration_cutoff_hz": ("HZ", a.positive_float, (
        "cut-off of --qdd-estimate causal; default the dataset scenario's "
        "compensator.acceleration_cutoff_hz, or 25")),
    "sg_window": ("S", a.positive_float, "Savitzky–Golay window (s), default 0.1"),
    "sg_polyorder": ("N", a.non_negative_int, "Savitzky–Golay polynomial order, default 4"),
    "gap_factor": ("X", a.positive_float, ("a time step longer than X × the median period is "
                                           "a gap, default 3")),
    "temperature": ("COL", str, ("the sensor's temperature column (°C, tables): read as the "
                                "models' last input, so the model learns the zero drift "
                                "with temperature; evaluate then needs it too")),
}
_CHOICES = {"position_unit": ("rad", "deg"), "qdd_estimate": QDD_ESTIMATES}
# Options that describe the file (columns, topics): carried to `evaluate` only from the same
# kind of file. The others (units, derivatives) always are.
FILE_OPTIONS = ("positions", "targets", "velocities", "accelerations", "time", "group",
                 "joint_topic", "wrench_topic", "temperature")


def register(subparsers) -> None:
    """Adds ``train`` to an ``argparse`` subparsers object."""
    models = registry.names()
    p = a.add_command(subparsers, "train", "fit a compensator on a robot log; save it",
                      description=COLUMNS_HELP)
    p.add_argument("--data", type=a.existing_path, required=True, metavar="FILE",
                   help="CSV/Parquet table, ROS 1 .bag file or ROS 2 bag folder")
    add_read_flags(p)
    kind = p.add_argument(
        "--kind", choices=models,
        help=", ".join(f"{n}: {registry.entry(n).summary}" for n in models)
        + "; physics and hybrid need --robot: on a wrench they identify the payload, on joint "
        "torques the whole arm (as arm). (default: hybrid when --robot is given, else rf)")
    a.add_deprecated(p, "--model", kind)
    p.add_argument("--features", choices=FEATURE_SETS, metavar="q|q,qd|q,qd,qdd",
                   help="inputs the model uses (default: q,qd,qdd; physics: q = static, "
                        "q,qd,qdd = dynamic; hybrid: the residual forest's, default q)")
    p.add_argument("--preset", choices=["quick", "none"], default="quick",
                   help="quick: grid search with grouped CV (rf, svr; gpr, physics and hybrid "
                        "fit their parameters from data); none: the kind's own parameters")
    p.add_argument("--robot", metavar="FILE",
                   help=f"URDF/SDF holding the sensor frame, or '{BUILTIN_ROBOT}' for the "
                        "simulated arm (physics, hybrid)")
    p.add_argument("--sensor-frame", metavar="NAME", help="frame S of the targets in --robot")
    p.add_argument("--base-frame", metavar="NAME", help="frame of --robot welded to the world")
    a.add_joint_mapping(p)
    _add_model_options(p)
    p.add_argument("--target-units", metavar="U,U,..",
                   help="unit per target (default: N/N*m for wrench axes, else N*m)")
    a.add_seed(p, 0, "random state of rf and gpr")
    a.add_jobs(p, "parallel CV fits (-1: all cores)")
    cluster = a.add_cluster(p, "run the grid search on this Dask scheduler")
    a.add_deprecated(p, "--dask", cluster)
    p.add_argument("--out", type=a.output_file, required=True, metavar="MODEL",
                   help="the model file to write (e.g. m.ftd)")
    _add_domain_flags(p)
    p.add_argument("--max-rows", type=a.positive_int, metavar="N",
                   help="fit on at most N rows covering the log's states (every k-th row, "
                        "then farthest-point in the model's inputs); reported in the model")
    a.add_stream_delay(p, corrected="corrected in training, kept in the model, applied live",
                       estimated="with the model fitted once; best with a physics or hybrid "
                                 "model")
    a.add_quiet(p)
    p.set_defaults(run=run_train)


def _add_domain_flags(p) -> None:
    """--domain-holdout / --domain-calibration: where the hybrid's out-of-domain std is
    calibrated (:meth:`~ftdrake.compensation.estimators.hybrid.HybridCompensator.fit_calibrated`,
    :meth:`~ftdrake.compensation.estimators.hybrid.HybridCompensator.calibrate_domain`)."""
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--domain-holdout", type=a.holdout_share, metavar="SHARE",
        help="hybrid: calibrate how its std grows out of domain on this share of the rows, "
             "held out: whole runs (the --group column's), those farthest from the others "
             "(in a log of fewer than 3 runs: contiguous time blocks), then refit on all "
             "rows; e.g. 0.2")
    group.add_argument(
        "--domain-calibration", type=a.existing_path, metavar="LOG",
        help="hybrid: calibrate how its std grows out of domain on this contact-free log "
             "(read with the same flags, not trained on): motion that leaves the training "
             "data, e.g. runs over other configurations")
    p.add_argument(
        "--domain-shared-growth", action="store_true",
        help="with --domain-holdout/--domain-calibration: one growth of the std for all axes, "
             "in units of each axis' training error (default: one per axis)")
    p.add_argument(
        "--domain-level", choices=IN_DOMAIN_SOURCES, default="cross_fit",
        help="with --domain-holdout/--domain-calibration: where the std's level next to the "
             "data comes from: the fit's cross-fit or the held-out rows too (with "
             "--domain-shared-growth one multiple of each axis' training error; the demo's "
             "choice) (default: cross_fit)")


def _add_model_options(p) -> None:
    """The options the registered compensators take (their registry entries' train options)."""
    for option in registry.train_options():
        if option.kind is bool:
            p.add_argument(option.flag, action="store_true", help=option.help)
        else:
            p.add_argument(option.flag, type=option.kind, default=option.default,
                           choices=option.choices, metavar=option.metavar, help=option.help)


def _model_options(args) -> dict:
    return {option.name: getattr(args, option.name) for option in registry.train_options()}


def add_read_flags(p) -> None:
    for name, (metavar, kind, text) in _READ_FLAGS.items():
        p.add_argument(_flag_name(name), metavar=metavar, type=kind, help=text,
                       choices=_CHOICES.get(name))
    p.add_argument("--no-check-units", dest="check_units", action="store_const", const=False,
                   help="accept positions beyond ±2π rad and velocities that disagree with q")
    p.add_argument("--t-start", type=a.finite_float, metavar="S",
                   help="drop rows before this time (s)")
    p.add_argument("--t-end", type=a.finite_float, metavar="S",
                   help="drop rows after this time (s)")


def _flag_name(option: str) -> str:
    return "--" + option.replace("_", "-")


def given_read_options(args) -> dict:
    """The ReadOptions fields set on the command line (the others are None)."""
    return {f.name: getattr(args, f.name, None) for f in dc.fields(ReadOptions)}


def with_flags(base: ReadOptions, args) -> ReadOptions:
    """`base` updated with the flags given; an invalid value's error names its flag."""
    try:
        return base.updated(**given_read_options(args))
    except ConfigError as e:
        message = str(e)
        for f in dc.fields(ReadOptions):
            if message.startswith(f.name + " "):
                message = _flag_name(f.name) + message[len(f.name):]
        raise ConfigError(message) from None


def read_data(args, options: ReadOptions, say, static_poses: bool | None = False) -> TrainingData:
    say(f"reading {args.data} …")
    with option_spelling(flag_hint):
        try:
            data = load_training_data(args.data, options, t_start=args.t_start,
                                      t_end=args.t_end, report=warn,
                                      static_poses=static_poses)
        except LogError as e:
            hint = static_table_hint(args.data, options.time, options.positions)
            if hint is None:
                raise
            raise LogError(f"{e}; {hint}") from None
    say(_describe(data))
    return data


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
    say = reporter(args.quiet)
    for flag, given in (("--domain-shared-growth", args.domain_shared_growth),
                        ("--domain-level", args.domain_level != "cross_fit")):
        if given and args.domain_holdout is None and args.domain_calibration is None:
            raise ConfigError(f"{flag} needs --domain-holdout or --domain-calibration")
    options = with_flags(ReadOptions(), args)
    data = read_data(args, options, say)
    robot = RobotOptions(args.robot, args.sensor_frame, args.base_frame, data.scenario_yaml,
                         joints=args.joints, fixed_joints=args.fixed_joints)
    if args.kind is None:
        args.kind = registry.default_kind(robot)
        say(f"--kind not given: {args.kind} "
            + ("(a robot description and wrench targets: physics + learned residual)"
               if args.kind == "hybrid" else "(no --robot: a black box)"))
    estimator = registry.make_estimator(args.kind, features=args.features, seed=args.seed,
                                        target_names=data.target_names, robot=robot,
                                        options=_model_options(args))
    units = target_units(args.target_units, data.target_names)
    data, stream_delay = _align_streams(args, data, estimator, say)
    data, subsample = _subsample(args, data, estimator, say)
    search = None
    if args.preset == "quick" and "quick" in registry.entry(args.kind).presets:
        where = f"Dask scheduler {args.cluster}" if args.cluster else "local processes"
        say(f"tuning {args.kind} (quick grid, grouped 5-fold CV) on {where} …")
        with dask_backend(args.cluster):
            model, search = tune(estimator, data.X, data.Y, groups=segment_groups(data.groups),
                                 preset="quick", cv="grouped", target_names=data.target_names,
                                 n_jobs=args.jobs, progress=not args.quiet)
        say(f"best {search.best_params[0]}, CV MSE {-search.mean_score[0]:.4g}")
    else:
        why = "" if args.preset == "none" else " (no grid: its parameters are fitted from data)"
        say(f"fitting {args.kind}{why} on {len(data.X)} rows …")
        started = time.perf_counter()
        model = _fit(estimator, data, needs_robot=registry.entry(args.kind).needs_robot,
                     holdout=args.domain_holdout, shared_growth=args.domain_shared_growth,
                     in_domain=args.domain_level)
        say(f"fitted in {time.perf_counter() - started:.1f} s")
    domain = _calibrate_domain(args, options, model, data, say)
    if hasattr(model, "summary"):  # physics and hybrid: the identified payload
        print(model.summary())
    extra = provenance(args.data, data, model, search, kind=args.kind,
                       time_window=(args.t_start, args.t_end), dask=args.cluster)
    if subsample is not None:
        extra["subsample"] = subsample
    if domain is not None:
        extra["domain_calibration"] = domain
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
    if args.delay is None and not args.align:
        return data, None
    if data.static:
        raise LogError("--delay/--align: a table of static poses has no time axis to align")
    if args.align:
        needs_robot = registry.entry(args.kind).needs_robot
        say(f"estimating the wrench stream's delay with {args.kind} …")
        estimate = estimate_training_delay(
            lambda d: _fit(clone(estimator), d, needs_robot=needs_robot), data)
        found = estimate.as_dict()
        say(f"wrench stream delay: {estimate.delay_s * 1e3:.2f} ± {estimate.std_s * 1e3:.2f} ms "
            f"({estimate.samples:.2f} samples); corrected"
            + ("" if found["distinct_from_zero"] else " (within two standard errors of 0)"))
    else:
        found = {"delay_s": float(args.delay), "given": True}
    return align_training_data(data, found["delay_s"]), found


def _fit(estimator, data: TrainingData, *, needs_robot: bool, holdout: float | None = None,
         shared_growth: bool = False, in_domain: str = "cross_fit"):
    """Fits `estimator` (with `holdout`, a hybrid's :meth:`fit_calibrated` on that share of
    the runs). A robot-based model's ValueErrors are about the robot description (joint
    count, frames); they name the flags that choose it."""
    def fit():
        if holdout is None:
            return estimator.fit(data.X, data.Y)
        runs = data.groups if len(np.unique(data.groups)) >= MIN_GROUPS else None
        return estimator.fit_calibrated(data.X, data.Y, groups=runs, share=holdout,
                                        shared_growth=shared_growth, in_domain=in_domain)

    if holdout is not None:
        _needs_hybrid(estimator, "--domain-holdout")
    if not needs_robot:
        return fit()
    try:
        return fit()
    except FtdrakeError:
        raise
    except ValueError as e:
        raise RobotModelError(f"{e} (check --robot, --sensor-frame, --base-frame and "
                              f"--positions)") from e


def _needs_hybrid(model, flag: str) -> None:
    residual = getattr(model, "residual", None)
    own_std = getattr(residual, "provides_std", False) and getattr(
        residual, "std_includes_noise", False)  # a GP residual: no support term
    if not isinstance(model, HybridCompensator) or own_std:
        raise ConfigError(f"{flag} is for --kind hybrid with its forest residual (the "
                          "support term of its std); omit it")


def _calibrate_domain(args, options: ReadOptions, model, data: TrainingData, say):
    """--domain-calibration: calibrates `model`'s support term on that log; returns what
    the manifest keeps about the calibration (or None without either domain flag)."""
    if args.domain_calibration is not None:
        _needs_hybrid(model, "--domain-calibration")
        say(f"reading {args.domain_calibration} (out-of-domain calibration) …")
        with option_spelling(flag_hint):
            log = load_training_data(args.domain_calibration, options, report=warn)
        if log.target_names != data.target_names or log.X.shape[1] != data.X.shape[1]:
            raise LogError(f"--domain-calibration {args.domain_calibration}: its columns "
                           f"({log.target_names}) are not the training data's "
                           f"({data.target_names}); give a log of the same robot and sensor")
        before = coverage(log.Y, model.predict(log.X), model.predict_std(log.X))
        model.calibrate_domain(log.X, log.Y, shared_growth=args.domain_shared_growth,
                               in_domain=args.domain_level)
        found = {"file": str(args.domain_calibration), "rows": len(log.X),
                 "length": (float(model.domain_length_) if np.isfinite(model.domain_length_)
                            else None),  # None: ∞
                 "growth": model.domain_growth_.tolist(),
                 "shared_growth": bool(args.domain_shared_growth),
                 "in_domain": args.domain_level,
                 "in_domain_std": np.sqrt(model.residual_noise_var_).tolist(),
                 "parameter_variance_scale": float(model.domain_parameter_scale_),
                 "coverage_95_before": before.tolist(),
                 "coverage_95_after": coverage(log.Y, model.predict(log.X),
                                               model.predict_std(log.X)).tolist()}
    elif args.domain_holdout is not None:
        found = dict(model.domain_calibration_)
    else:
        return None
    length = "∞" if found["length"] is None else f"{found['length']:.3g}"
    say(f"out-of-domain std: ℓ = {length}, g = "
        + ", ".join(f"{g:.3g}" for g in found["growth"])
        + "; 95 % coverage on the calibration rows "
        + ", ".join(f"{c:.2f}" for c in found["coverage_95_after"])
        + " (before: " + ", ".join(f"{c:.2f}" for c in found["coverage_95_before"]) + ")")
    return found


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
            "targets": target_ranges(data.Y, data.target_names),
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














# -- output ---------------------------------------------------------------------------------------
def reporter(quiet: bool):
    def say(message: str) -> None:
        if not quiet:
            print(message, file=sys.stderr, flush=True)

    return say


def warn(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _describe(data: TrainingData) -> str:
    r = data.rows
    methods = {"savitzky_golay": "Savitzky–Golay", "causal": "the loop's causal estimate"}
    derived = "".join(f"; {k} from {methods[v['method']]}" for k, v in data.derivation.items())
    return (f"{r['used']} rows used of {r['in_file']} in the file ({r['dropped_by_reader']} "
            f"dropped by the reader, {r['outside_time_window']} outside the time window), "
            f"{data.n_joints} joints, {len(data.target_names)} targets{derived}")


def main(argv=None) -> int:
    """Runs train alone (``python -m ftdrake.cli.train``), with errors reported as
    the ``ftdrake`` command does: a :class:`~ftdrake.errors.FtdrakeError` is one line and exit
    code 2; any other exception is a bug and keeps its traceback."""
    parser = argparse.ArgumentParser(prog="ftdrake")
    register(parser.add_subparsers(dest="command", required=True))
    return a.run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
