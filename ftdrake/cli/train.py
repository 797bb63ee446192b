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

`train` parses its flags into a :class:`~ftdrake.training.TrainOptions` (a flag is its
field's name with dashes; ``--delay`` is ``delay_s``), calls :func:`ftdrake.train` — which
tunes the model with the ``quick`` grid and grouped CV (``--preset none`` fits the
defaults), locally or on a Dask cluster (``--cluster ADDRESS``) — saves the result with
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

import dataclasses as dc
import sys

from ..compensation.calibration.calibration import static_table_hint
from ..compensation.estimators import registry
from ..compensation.estimators.build import BUILTIN_ROBOT
from ..compensation.estimators.domain import IN_DOMAIN_SOURCES
from ..data.logs import QDD_ESTIMATES, option_spelling
from ..data.training import ReadOptions, TrainingData, load_training_data
from ..errors import ConfigError, LogError, option_names
from ..training import TrainOptions, train
from ..training.options import SEARCH_BUDGET_S
from ..training.pipeline import describe
from . import args as a
from .args import flag_hint

FEATURE_SETS = ("q", "q,qd", "q,qd,qdd")

COLUMNS_HELP = ("PAT is a glob ('q_*'), a comma-separated list of names, or a regular "
                 "expression after 're:'. Times are in s on the log's own axis (a bag's: since "
                 "its first joint state).")
# ReadOptions field → (metavar, type, help). Every field is a flag of both commands.
_READ_FLAGS = {
    "positions": ("PAT", str, "joint position columns (rad); bags: joint names (default: 'q_*')"),
    "targets": ("PAT", str, ("target columns; bags: effort, wrench or a pattern (default: "
                            "'meas_*')")),
    "velocities": ("PAT", str, ("velocity columns (rad/s), or 'derive': Savitzky–Golay of q "
                               "(default: derive)")),
    "accelerations": ("PAT", str, ("acceleration columns (rad/s²), or 'derive': see "
                                   "--qdd-estimate (default: derive)")),
    "time": ("COL", str, "time column (s) (default: 't')"),
    "group": ("COL", str, ("trajectory id column: reads a file joining several recordings "
                          "as separate trajectories (default: 'trajectory' if there is one)")),
    "joint_topic": ("T", str, "bags: JointState topic (default: /joint_states)"),
    "wrench_topic": ("T", str, "bags: WrenchStamped topic"),
    "position_unit": (None, str, "angle unit of the joint columns (default: rad)"),
    "qdd_estimate": (None, str, ("missing accelerations: savgol (Savitzky–Golay of q) or "
                     "causal (the estimate the compensator makes in the loop, from q̇; use it "
                     "for q,qd,qdd models that run in the loop) (default: savgol)")),
    "acceleration_cutoff_hz": ("HZ", a.positive_float, (
        "cut-off of --qdd-estimate causal (default: the dataset scenario's "
        "compensator.acceleration_cutoff_hz, else 25)")),
    "sg_window": ("S", a.positive_float, "Savitzky–Golay window (s) (default: 0.1)"),
    "sg_polyorder": ("N", a.non_negative_int, "Savitzky–Golay polynomial order (default: 4)"),
    "gap_factor": ("X", a.positive_float, ("a time step longer than X × the median period is "
                                           "a gap (default: 3)")),
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
    p.add_argument("--features", choices=FEATURE_SETS,
                   help="inputs the model uses; physics: q = static, q,qd,qdd = dynamic; "
                        "hybrid: the residual forest's (default: q,qd,qdd; hybrid: q)")
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
    p.add_argument("--search-budget", type=_budget, default=SEARCH_BUDGET_S, metavar="S",
                   help="bound on the grid search's time (s): no candidate is started that "
                        "would pass it, and the best of those scored is chosen (0: the first "
                        "candidate only; inf: no bound)")
    p.add_argument("--out", type=a.output_file, required=True, metavar="MODEL",
                   help="the model file to write (e.g. m.ftd)")
    _add_domain_flags(p)
    p.add_argument("--motion-std", action="store_true",
                   help="wrap the model in a std that grows with the motion (‖q̇‖, ‖q̈‖), "
                        "fitted from its training residuals; not with a domain calibration")
    p.add_argument("--max-rows", type=a.positive_int, metavar="N",
                   help="fit on at most N rows covering the log's states (every k-th row, "
                        "then farthest-point in the model's inputs); reported in the model")
    a.add_stream_delay(p, corrected="corrected in training, kept in the model, applied live",
                       estimated="with the model fitted once; best with a physics or hybrid "
                                 "model")
    a.add_quiet(p, "no progress output and no table of what was identified: only the line "
                   "naming the file written (warnings still print)")
    p.set_defaults(run=run_train)


def _add_domain_flags(p) -> None:
    """--domain-holdout / --domain-calibration: where the hybrid's out-of-domain std is
    calibrated
    (:class:`~ftdrake.compensation.estimators.domain_calibrated.DomainCalibratedHybrid`)."""
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
        text = option.describe(flag_of).replace("%", "%%")  # argparse formats help with %
        if option.kind is bool:
            p.add_argument(flag_of(option.name), action="store_true", help=text)
        else:
            p.add_argument(flag_of(option.name), type=option.kind, default=option.default,
                           choices=option.choices, metavar=option.metavar, help=text)


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
    say(describe(data))
    return data


# -- train --------------------------------------------------------------------------------------
def run_train(args) -> int:
    say = reporter(args.quiet)
    with option_names(flag_of):
        options = train_options(args)
        result = train(args.data, options, progress=None if args.quiet else say, warn=warn)
    if result.summary is not None and not args.quiet:  # physics, hybrid: the payload found
        print(result.summary)
    result.save(args.out)
    print(f"saved {args.out} ({file_size(args.out.stat().st_size)})")
    return 0


#: TrainOptions fields whose flag is not the field's name with dashes.
_FLAGS = {"delay_s": "--delay", "search_budget_s": "--search-budget"}


def flag_of(option: str) -> str:
    """The flag of TrainOptions field `option` (``read.positions``: a read flag)."""
    name = option.removeprefix("read.")
    return _FLAGS.get(name, _flag_name(name))


def _budget(text: str) -> float | None:
    """--search-budget's value: seconds >= 0; 'inf' is no bound (None)."""
    value = a.number(float, lambda v: v >= 0, "must be a number of seconds >= 0, or inf")(text)
    return None if value == float("inf") else value


def train_options(args) -> TrainOptions:
    """The TrainOptions the flags give (an invalid value's error names its flag)."""
    return TrainOptions(
        kind=args.kind, features=args.features, preset=args.preset, robot=args.robot,
        sensor_frame=args.sensor_frame, base_frame=args.base_frame, joints=args.joints,
        fixed_joints=args.fixed_joints, model_options=_model_options(args),
        target_units=args.target_units, seed=args.seed, jobs=args.jobs, cluster=args.cluster,
        search_budget_s=args.search_budget,
        max_rows=args.max_rows, delay_s=args.delay, align=args.align,
        domain_holdout=args.domain_holdout, domain_calibration=args.domain_calibration,
        domain_shared_growth=args.domain_shared_growth, domain_level=args.domain_level,
        read=with_flags(ReadOptions(), args), t_start=args.t_start, t_end=args.t_end,
        motion_std=args.motion_std)


def file_size(n_bytes: int) -> str:
    """``1234567`` → ``"1.23 MB"`` (decimal units, as file managers show them)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes} B"


# -- output ---------------------------------------------------------------------------------------
def reporter(quiet: bool):
    def say(message: str) -> None:
        if not quiet:
            print(message, file=sys.stderr, flush=True)

    return say


def warn(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main(argv=None) -> int:
    """Runs train alone (``python -m ftdrake.cli.train``), with errors reported as
    the ``ftdrake`` command does: a :class:`~ftdrake.errors.FtdrakeError` is one line and exit
    code 2; any other exception is a bug and keeps its traceback."""
    parser = a.Parser(prog="ftdrake")
    register(parser.add_subparsers(dest="command", required=True))
    return a.run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
