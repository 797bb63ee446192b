"""`ftdrake calibrate`: payload, biases, mounting and temperature coefficients of a wrist F/T
sensor from a short calibration log, with standard errors, as a YAML a user reads and (when
the sensor's orientation comes from joint angles) a model file ``evaluate`` and the station use::

    ftdrake calibrate --data poses.csv --robot arm.urdf --sensor-frame ft_link --out cal/
    ftdrake calibrate --data poses.csv --out cal/          # qw,qx,qy,qz / r00..r22 /
                                                           # roll,pitch,yaw / gx,gy,gz columns
    ftdrake calibrate --data log.parquet --time-series --robot ftdrake --out cal/
    ftdrake calibrate --data poses.csv --correction full --known-mass 1.5 \
                      --known-com 0.02,0.0067,0.0867 --out cal/   # + gain/cross-talk matrix
    ftdrake calibrate --data poses.csv --robot ftdrake --joint-offsets auto --out cal/

A table of static poses (one pose and one wrench a row; no time column needed) is calibrated
by :func:`ftdrake.compensation.calibration.calibration.calibrate_table`. A time series
(``--time-series``, or a table with a time column and no orientation columns and not all velocities
zero) is read like ``train`` does and fitted by the physics model (dynamic, physically consistent).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import yaml

from ..compensation.calibration.calibration import ORIENTATIONS, calibrate_table, orientation_kind
from ..compensation.calibration.joint_offsets import identify_joint_offsets
from ..compensation.calibration.orientation_model import OrientationPayloadCompensator
from ..compensation.calibration.static_table import joint_layout
from ..compensation.estimators.build import RobotOptions
from ..compensation.estimators.physics import ExcitationWarning
from ..compensation.estimators.registry import make_estimator
from ..compensation.estimators.robot_file import check_robot_frames
from ..compensation.files.persistence import save_model
from ..compensation.identification.consistent import PayloadPrior
from ..conventions import MEASURED, TEMPERATURE, TIME, WRENCH_AXES, WRENCH_UNITS
from ..data.logs import expand_columns, option_spelling, read_frame, time_columns
from ..data.training import ReadOptions, load_training_data
from ..errors import ConfigError, LogError
from ..io import atomic_write_text
from . import args as a
from .train import flag_hint


def point(text: str) -> tuple[float, float, float]:
    """An argument type: a point ``X,Y,Z`` in m."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in m; got {text!r}")
    return values


def register(subparsers) -> None:
    """Adds ``calibrate`` to an ``argparse`` subparsers object."""
    p = a.add_command(
        subparsers, "calibrate", "identify payload, biases, mounting, drift",
        "Of the sensor and its tool, from static poses (or a slow motion): writes "
        "calibration.yaml and a model file.")
    p.add_argument("--data", type=a.existing_file, required=True, metavar="FILE",
                   help="CSV/Parquet: one row per static pose, 6 wrench columns and joint "
                        "angles or an orientation (qw,qx,qy,qz | r00..r22 | roll,pitch,yaw | "
                        "gx,gy,gz gravity in S); optional 'temperature' (°C)")
    p.add_argument("--robot", metavar="FILE", help="URDF/SDF holding the sensor frame, or "
                   "'ftdrake' for the simulated arm (with joint-angle columns)")
    p.add_argument("--sensor-frame", metavar="NAME", help="frame S of the wrench in --robot")
    p.add_argument("--base-frame", metavar="NAME", help="frame of --robot welded to the world")
    a.add_joint_mapping(p)
    p.add_argument("--positions", default="q_*", metavar="PAT", help="joint angle columns")
    p.add_argument("--time", default=TIME, metavar="COL",
                   help="a motion log's time column (s); a table with a time column whose "
                        "joints move is calibrated as a motion")
    p.add_argument("--targets", default=f"{MEASURED}_*", metavar="PAT",
                   help="wrench columns Fx..Tz")
    p.add_argument("--position-unit", choices=("rad", "deg"), default="rad",
                   help="angle unit of the joint columns")
    p.add_argument("--prior-mass", type=a.positive_float, metavar="KG",
                   help="prior mass of the tool")
    p.add_argument("--prior-com", type=point, metavar="X,Y,Z",
                   help="prior centre of mass in S (m), with --prior-mass")
    p.add_argument("--least-squares", action="store_true",
                   help="plain least squares instead of the physically consistent fit")
    p.add_argument("--no-mounting", action="store_true",
                   help="do not identify the sensor's mounting rotation (joint-angle input)")
    p.add_argument("--time-series", action="store_true",
                   help="the log is a motion (time column): fit the dynamic physics model")
    p.add_argument("--correction", choices=("auto", "none", "block", "full"), default="auto",
                   help="the sensor's gain/cross-talk correction matrix C "
                        "(wrench = C·(reading − bias)): block = force and torque 3×3 blocks, "
                        "full = 6×6 (needs 3 known loads to be fully determined; with one "
                        "load it is the general linear model of that load); none = gravity + "
                        "bias only; auto = the one that lowers the cross-validated error over "
                        "the poses, else none. Static poses only")
    p.add_argument("--joint-offsets", choices=("none", "auto", "all"), default="none",
                   help="also identify the joints' zero offsets from the wrench, with the "
                        "payload (joint-angle input): auto = those that lower the held-out "
                        "error, all = every joint the data determine; joints they cannot "
                        "determine are named with the reason (calibration.yaml: joint_offsets)")
    p.add_argument("--known-mass", type=a.positive_float, metavar="KG",
                   help="the tool's known mass (weighed), for --correction: fixes the force "
                        "gain the mass would otherwise absorb")
    p.add_argument("--known-com", type=point, metavar="X,Y,Z",
                   help="the tool's known centre of mass in S (m), with --known-mass")
    p.add_argument("--out", type=a.output_folder, required=True, metavar="DIR",
                   help="folder for calibration.yaml (and model.ftd)")
    a.add_quiet(p, "print only the files written and warnings, not the identified "
                "parameters (calibration.yaml holds them)")
    p.set_defaults(run=run_calibrate)


def _prior(args):
    if args.prior_mass is None:
        if args.prior_com is not None:
            raise ConfigError("--prior-com needs --prior-mass")
        return None
    try:
        return PayloadPrior(args.prior_mass, args.prior_com or (0.0, 0.0, 0.0))
    except ConfigError as e:
        raise ConfigError(f"--prior-mass/--prior-com: {e}") from None


def _known_payload(args):
    if args.known_mass is None:
        if args.known_com is not None:
            raise ConfigError("--known-com needs --known-mass")
        return None
    if args.correction not in ("block", "full"):
        raise ConfigError("--known-mass is for the gain/cross-talk correction: add "
                          "--correction block|full")
    return {"mass": args.known_mass, "com": args.known_com or (0.0, 0.0, 0.0)}


def _print_warnings(caught, category) -> None:
    """`category` warnings as `warning: …` lines on stderr; the others re-issued."""
    for w in caught:
        if issubclass(w.category, category):
            print(f"warning: {w.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _table_joint_offsets(args, cal, frame, say):
    """--joint-offsets on a table of static poses (None with ``none``)."""
    if args.joint_offsets == "none":
        return None
    if cal.model is None:
        raise ConfigError("--joint-offsets needs joint angles (columns --positions) and a "
                          "robot (--robot); this table gives the orientation directly")
    X = joint_layout(frame, list(cal.positions), cal.position_unit)
    Y = frame[expand_columns(args.targets, list(frame.columns))].to_numpy(dtype=float)
    temperature = frame[TEMPERATURE].to_numpy(dtype=float) if TEMPERATURE in frame else None
    return _joint_offsets(args, cal.model, X, Y, temperature, say)


def run_calibrate(args) -> int:
    say = _printer(args.quiet)
    prior = _prior(args)
    if args.robot not in (None, "ftdrake") and not Path(args.robot).is_file():
        raise LogError(f"--robot {args.robot}: no such file")
    if args.robot not in (None, "ftdrake"):  # its frames, before the data is read
        check_robot_frames(args.robot, args.sensor_frame, args.base_frame, command="calibrate")
    frame = read_frame(args.data)
    known = _known_payload(args)
    # Any time-like column (t, time, stamp …) with moving joints is a motion; reading it then
    # names --time if the column is not the one given.
    timed = args.time in frame or bool(time_columns(frame.columns))
    if args.time_series or (orientation_kind(frame.columns) is None and timed
                            and _moving(frame, args.positions)):
        if args.correction in ("block", "full"):
            raise ConfigError("--correction needs a table of static poses (gravity known at "
                              "each); this log is a motion")
        return _time_series(args, prior, TEMPERATURE in frame)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ExcitationWarning)
        with option_spelling(flag_hint):  # errors name calibrate's flags
            cal = calibrate_table(
                frame, robot=args.robot, sensor_frame=args.sensor_frame,
                base_frame=args.base_frame, positions=args.positions, targets=args.targets,
                position_unit=args.position_unit, prior=prior,
                identification="least_squares" if args.least_squares else "consistent",
                identify_mounting=not args.no_mounting,
                correction=None if args.correction == "none" else args.correction,
                known_payload=known, joints=args.joints, fixed_joints=args.fixed_joints)
    say(cal.summary())
    _print_warnings(caught, ExcitationWarning)
    offsets = _table_joint_offsets(args, cal, frame, say)
    model, options = cal.model, None
    if model is None:  # the orientation given directly: its columns are the model's input
        model, options = orientation_model(cal, frame, args)
    elif cal.correction is not None:
        if cal.correction.payload is not None:
            model = model.with_correction(cal.correction)
            say("model.ftd predicts readings through the correction: M·W_S + b (M = C⁻¹)")
        else:
            say("note: model.ftd is the gravity + bias model (the correction was fitted with "
                "a known payload per row); the correction is in calibration.yaml (apply it "
                "to readings: wrench = C·(reading − bias))")
    written = _write_yaml(args.out / "calibration.yaml", {"calibration": cal.to_dict(),
                                                         **offsets_section(offsets),
                                                         "data": str(args.data)})
    if options is None:
        options = _read_options(args, model.temperature_in_)
    else:
        say(f"model.ftd takes the orientation columns {options.positions} as its inputs "
            "(evaluate reads them from a table like this one; replay and serve take them as "
            "q_0.. with zero velocities)")
    written.append(_save(model, args, model.n_joints_, options))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def orientation_model(cal, frame, args):
    """(the calibration as a compensator on the orientation columns, the read options
    that give `evaluate` those columns as its inputs)."""
    names = list(ORIENTATIONS[cal.source])
    o = frame[names].to_numpy(dtype=float)
    X = np.hstack([o, np.zeros_like(o), np.zeros_like(o)])
    temperature = cal.temperature_reference is not None
    if temperature:
        X = np.column_stack([X, frame[TEMPERATURE].to_numpy(dtype=float)])
    Y = frame[expand_columns(args.targets, list(frame.columns))].to_numpy(dtype=float)
    model = OrientationPayloadCompensator.from_calibration(cal, X, Y)
    # Gravity columns are in m/s² (not angles): no degree check on them.
    options = _read_options(args, temperature).updated(positions=",".join(names),
                                                       position_unit="rad",
                                                       check_units=False)
    return model, options


def _printer(quiet: bool):
    """`print`, or nothing under --quiet."""
    return (lambda *_: None) if quiet else print


def _moving(frame, positions) -> bool:
    try:
        cols = expand_columns(positions, list(frame.columns))
    except LogError:
        return False
    q = frame[cols].to_numpy(dtype=float)
    return bool(len(q) > 1 and np.abs(np.diff(q, axis=0)).max() > 0)


def _read_options(args, temperature: bool):
    """How `evaluate` reads data for the model file (kept in its manifest)."""
    return ReadOptions().updated(positions=args.positions, targets=args.targets,
                                 position_unit=args.position_unit, time=args.time,
                                 temperature=TEMPERATURE if temperature else None)


def _time_series(args, prior, temperature: bool) -> int:
    """A motion log: read as `train` reads it, fitted by the dynamic physics model (with the
    temperature column, if the log has one)."""
    if args.robot is None:  # said before the log is read, in calibrate's words
        raise ConfigError(
            f"{args.data} is a motion (a time column and moving joints): calibrate fits it "
            "with the dynamic payload model, which needs --robot FILE (URDF/SDF) with "
            "--sensor-frame NAME, or --robot ftdrake for the simulated arm")
    data = load_training_data(args.data, _read_options(args, temperature))
    robot = RobotOptions(args.robot, args.sensor_frame, args.base_frame, data.scenario_yaml,
                         joints=args.joints, fixed_joints=args.fixed_joints)
    # The dynamic payload model train builds on a wrench (calibrate's targets are Fx..Tz).
    model = make_estimator("physics", features="q,qd,qdd", target_names=WRENCH_AXES,
                           robot=robot)
    model.set_params(prior=prior, identify_mounting=not args.no_mounting,
                     identification="least_squares" if args.least_squares else "consistent")
    model.fit(data.X, data.Y)
    if not args.quiet:
        print(model.summary())
    offsets = None
    if args.joint_offsets != "none":
        offsets = _joint_offsets(args, model, data.X[:, :3 * data.n_joints], data.Y,
                                 data.X[:, -1] if temperature else None, _printer(args.quiet))
    table = json.loads(json.dumps(model.identified(), default=float))
    written = _write_yaml(args.out / "calibration.yaml", {"calibration": table,
                                                         **offsets_section(offsets),
                                                         "data": str(args.data)})
    written.append(_save(model, args, data.n_joints, data.options))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _joint_offsets(args, model, X, Y, temperature, say):
    """The joints' zero offsets of rows X and readings Y with fitted `model`'s robot and mode
    (:func:`~ftdrake.compensation.calibration.joint_offsets.identify_joint_offsets`), printed;
    the model's zero drift with `temperature` (°C) taken off the readings first."""
    if temperature is not None and getattr(model, "temperature_reference_", None) is not None:
        Y = Y - np.outer(temperature - model.temperature_reference_,
                         model.temperature_coefficients_)
    result = identify_joint_offsets(X, Y, model, include=args.joint_offsets)
    say(result.summary())
    say("note: model.ftd does not apply the joint offsets: add them to the joint angles at "
        "their source (q_true = q_measured + offset) or recalibrate the encoders")
    return result


def offsets_section(offsets) -> dict:
    """calibration.yaml's ``joint_offsets`` section ({} without one)."""
    return {} if offsets is None else {"joint_offsets": offsets.to_dict()}


def _write_yaml(path: Path, table: dict) -> list[Path]:
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, yaml.safe_dump(_plain(table), sort_keys=False))
    return [path]


def _plain(x):
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else str(float(x))
    if isinstance(x, np.integer):
        return int(x)
    return x


def _save(model, args, n_joints, options) -> Path:
    """model.ftd, its manifest keeping how the data was read (so `evaluate` reads held-out
    poses, temperature column included, the same way)."""
    path = args.out / "model.ftd"
    save_model(model, path, target_names=list(WRENCH_AXES), target_units=list(WRENCH_UNITS),
               sensor_frame=args.sensor_frame or "S",
               extra={"calibration": {"data": str(args.data), "n_joints": int(n_joints)},
                      "data": {"file": str(args.data), "kind": "table",
                               "options": options.to_dict()}})
    return path
