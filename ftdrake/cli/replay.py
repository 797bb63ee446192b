"""`ftdrake replay`: the runtime chain run offline over a logged stream, one update per row.

    ftdrake replay --model FILE --data FILE --out FILE [--config YAML] [--robot FILE
                   --sensor-frame NAME] [--pairing row|simulated]
                   [--view aligned|held] [--delay S | --align] [--budget [--noise-std S]]
                   [--resample]
                   [--calibrate-detector YAML]

Writes the chain's outputs per row (:func:`ftdrake.offline.replay.replay`: compensated and
contact wrench, std, bias, out-of-domain, fault and contact flags, contact force) as CSV or
Parquet (by the suffix of --out) and prints a JSON summary. --data is a CSV/Parquet table, a
ROS bag (with --wrench-topic) or an LCM log (read with --hardware's channels); ``--log`` is its
old spelling. --budget adds
what the in-motion residual is made of (offset, drift, stream delay, the sensor's filter,
remainder: :func:`ftdrake.offline.residual_budget.residual_budget`) to the summary.
--calibrate-detector writes the chain config with its detector's thresholds set for its budget
from the log, which must be contact-free motion the model was not trained on
(:func:`ftdrake.offline.replay.calibrated_detector`); ``serve`` and ``replay`` take it as
--config.
"""

from __future__ import annotations

import dataclasses as dc
import json
import sys

from ..config import save_config
from ..conventions import TIME
from ..errors import ConfigError, LogError
from . import args as a
from .hardware import add_transport_flags, hardware_from_args


def register(sub) -> None:
    """Adds ``ftdrake replay`` to an argparse subparsers."""
    p = a.add_command(
        sub, "replay", "the runtime chain run offline over a log",
        "Per row: the compensated and contact wrench, std, bias, out-of-domain, fault and "
        "contact flags, as the chain in the loop gives them.")
    a.add_model_file(p, required=True)
    data = p.add_argument("--data", type=a.existing_path, required=True, metavar="FILE",
                          help="CSV/Parquet table (t, q_i, qd_i, meas_*), ROS bag or LCM log")
    a.add_deprecated(p, "--log", data)
    p.add_argument("--out", type=a.output_file, required=True, metavar="FILE",
                   help="result table (.csv or .parquet)")
    a.add_chain_config(p)
    p.add_argument("--pairing", choices=["row", "simulated"], default="row",
                   help="row: each update reads its row's wrench and joint state (a recorded "
                        "log); simulated: the previous row's wrench, as a simulated station's "
                        "compensator reads it (reproduces simulate's columns)")
    p.add_argument("--view", choices=["aligned", "held"], default="aligned",
                   help="aligned: row k holds the outputs of the update that read row k; "
                        "held: what the output ports held when row k arrived (one row later)")
    a.add_stream_delay(p, corrected="corrected by a delay line on the joint state",
                       estimated="from the log, with a physics or hybrid model")
    p.add_argument("--budget", action="store_true",
                   help="also split the in-motion residual into offset, drift, stream delay, "
                        "the sensor's filter and what is left, in units of the resting noise")
    p.add_argument("--noise-std", type=a.noise_values, metavar="S[,S...]",
                   help="--budget: the sensor's resting noise std (N, N·m), one value or six "
                        "(default: measured on the log's rows at rest, else the chain config "
                        "sensor's: a warning says so)")
    p.add_argument("--resample", action="store_true",
                   help="put the log on a uniform time grid at its median period first "
                        "(linear interpolation; events kept): what --budget needs of a log "
                        "whose time steps jitter by more than 5 %%")
    p.add_argument("--calibrate-detector", type=a.output_file, metavar="YAML",
                   help="also write the chain config (--config's, the log's or the "
                        "defaults) with the detector's thresholds set for its false-positive "
                        "budget from this log, which must be contact-free motion the model "
                        "was not trained on (detector.test auto: the χ² test for a physics, "
                        "hybrid or GP model)")
    p.add_argument("--wrench-topic", metavar="TOPIC", help="a ROS bag's WrenchStamped topic")
    for flag, default, what in (("--positions", "q_*", "joint position columns (rad)"),
                                ("--velocities", "qd_*", ("joint velocity columns (rad/s), or "
                                 "'derive' to compute them from q as train does (so done when "
                                 "the log has no qd_* columns)")),
                                ("--targets", "meas_*", "the sensor's wrench columns (N, N·m)")):
        p.add_argument(flag, metavar="PAT", help=f"tables: {what}; a glob, a comma-separated "
                       f"list or a regular expression after 're:' (default: '{default}')")
    p.add_argument("--time", metavar="COL", help="tables: the time column (s) (default: 't')")
    p.add_argument("--gap-factor", type=a.number(float, lambda v: 1 < v < float("inf"),
                                                 "must be a number above 1"),
                   default=3.0, metavar="X",
                   help="a time step longer than X × the median step is a gap: the chain "
                        "restarts after it (bias tracker, q̇/q̈ estimates, detector) "
                        "(default: %(default)s)")
    p.add_argument("--t-start", type=a.finite_float, metavar="S",
                   help="replay only the rows from this time on (s, the log's time axis)")
    p.add_argument("--t-end", type=a.finite_float, metavar="S",
                   help="replay only the rows up to this time (s, the log's time axis)")
    add_transport_flags(p, lcm=False)
    a.add_quiet(p, "no warnings on stderr; the JSON summary still prints")
    p.set_defaults(run=run_replay)


def run_replay(args) -> int:
    from ..compensation.files.persistence import load_model
    from ..data.logs import write_log
    from ..data.stream_delay import estimate_stream_delay
    from ..offline.replay import chain_config_of, gaps_text, replay, summary

    _check_flags(args)
    with a.naming("--model", args.model):
        model = load_model(args.model)
    with a.naming("--data", args.data):
        frame = _prepared_log(args)
    config = a.load_chain(args) if _chain_given(args) else None
    delay, estimate = args.delay, None
    if args.align:
        estimate = estimate_stream_delay(model, frame)
        delay = estimate.delay_s
        if abs(delay) <= 2 * estimate.std_s and not args.quiet:
            print(f"warning: the estimated delay {delay * 1e3:.2f} ms is within two of its "
                  f"standard errors ({estimate.std_s * 1e3:.2f} ms) of zero; corrected anyway",
                  file=sys.stderr)
    if delay is not None:
        config = chain_config_of(frame, config)
        config.sensor.wrench_delay_s = delay
    result = replay(model, frame, config, pairing=args.pairing, view=args.view,
                    gap_factor=args.gap_factor)
    gaps = gaps_text(result.attrs["gaps"])
    if gaps is not None and not args.quiet:
        print(f"warning: replay: {gaps} (--gap-factor X sets the rule)", file=sys.stderr)
    write_log(result, args.out)
    report = {"out": str(args.out), **summary(result)}
    if args.t_start is not None or args.t_end is not None:
        report["time_window"] = {"t_start": args.t_start, "t_end": args.t_end,
                                 "rows": len(frame)}
    if delay is not None:
        report["wrench_delay_s"] = delay
    if estimate is not None:
        report["delay_estimate"] = estimate.as_dict()
    if args.budget:
        report["residual_budget"] = _budget(args, model, frame, config, result)
    if args.calibrate_detector is not None:
        report["detector"] = _write_calibrated(args.calibrate_detector, result, model,
                                               chain_config_of(frame, config), args.quiet)
    print(json.dumps(report))
    return 0


def _budget(args, model, frame, config, result) -> dict:
    """The residual budget of the replay, and on stderr which resting noise it is in units of
    (--noise-std, the log's rows at rest, or the chain config sensor's: then a warning)."""
    import numpy as np

    from ..offline.residual_budget import MIN_REST_ROWS, REST_SPEED, residual_budget

    noise = None if args.noise_std is None else np.broadcast_to(args.noise_std, (6,))
    budget = residual_budget(model, frame, config, result=result, noise_std=noise)
    sigma = ", ".join(f"{v:.3g}" for v in budget.noise_std)
    if budget.noise_source == "given":
        line = f"note: --budget: in units of the resting noise σ of --noise-std ({sigma})"
    elif budget.noise_source == "rest rows":
        line = (f"note: --budget: in units of the resting noise σ ({sigma}) measured on the "
                f"log's {budget.rows['rest']} rows at rest (every joint ≤ {REST_SPEED:g} rad/s)")
    else:
        line = (f"warning: --budget: the log has {budget.rows['rest']} rows at rest, too few "
                f"to measure the noise on ({MIN_REST_ROWS} needed): its σ ({sigma}, N and N·m) "
                "is the chain config sensor's, not necessarily yours; give yours with --noise-std "
                "S[,S...]")
    if not args.quiet or line.startswith("warning"):
        print(line, file=sys.stderr)
    for note in [] if args.quiet else budget.notes():
        print(f"note: --budget: {note}", file=sys.stderr)
    return budget.as_dict()


def _check_flags(args) -> None:
    if args.out.suffix not in (".csv", ".parquet"):
        raise LogError(f"--out {args.out}: give a .csv or .parquet file name")
    if args.noise_std is not None and not args.budget:
        raise ConfigError("--noise-std is the noise --budget judges the residual against: add "
                          "--budget")
    if args.noise_std is not None and len(args.noise_std) not in (1, 6):
        raise ConfigError(f"--noise-std gives {len(args.noise_std)} values: give one, or six "
                          "(Fx Fy Fz in N, Tx Ty Tz in N·m)")
    if args.calibrate_detector is not None and (args.delay is not None or args.align):
        raise ConfigError("--calibrate-detector with --delay/--align: serve corrects only the "
                          "delay the model was trained with, so thresholds set on a corrected "
                          "replay would not hold there; train with --delay/--align instead")


def _chain_given(args) -> bool:
    """Whether the command line sets the chain config (else: the log's, see replay)."""
    return any(v is not None for v in (args.config, args.robot, args.sensor_frame,
                                       args.base_frame))


def _write_calibrated(path, result, model, chain, quiet: bool = False) -> dict:
    """Writes the chain config `chain` with the detector calibrated on `result`; returns the
    detector and the outliers its robust threshold left out (each also a warning line)."""
    from ..offline.replay import calibrated_detector
    from ..offline.thresholds import ROBUST_FENCE, threshold_text

    detector, outliers = calibrated_detector(result, model, chain)
    save_config(chain.replace(detector=detector), path)
    if outliers and not quiet:
        print(f"warning: --calibrate-detector: {len(outliers)} stretch(es) of the log were left "
              f"out of the threshold ({threshold_text(dc.asdict(detector))}): their peaks lie "
              f"more than {ROBUST_FENCE:g} robust standard deviations above the log's other "
              "peaks (a start transient, a knock, a contact?); the detector would fire there. "
              "Calibrate on a log without them (--t-start/--t-end), or check them:",
              file=sys.stderr)
        for outlier in outliers:
            print(f"  {outlier.text()}", file=sys.stderr)
    return {"file": str(path), **dc.asdict(detector),
            "ignored_outliers": [o.as_dict() for o in outliers]}


def _prepared_log(args):
    """The log read, resampled with --resample, and checked for what --budget needs before
    the replay (which takes minutes on a long log)."""
    from ..data.robot_log import resample_uniform
    from ..offline.residual_budget import check_uniform_sampling

    frame = time_window(_read_log(args), args.t_start, args.t_end)
    if args.resample:
        rows = len(frame)
        frame = resample_uniform(frame)
        if not args.quiet:
            print(f"note: --resample: {rows} rows onto a uniform grid of {len(frame)} at "
                  f"{(frame[TIME].iloc[1] - frame[TIME].iloc[0]) * 1e3:.4g} ms",
                  file=sys.stderr)
    if args.budget:
        check_uniform_sampling(frame[TIME].to_numpy(float))
    return frame


def time_window(frame, t_start, t_end):
    """The rows of `frame` with t_start ≤ t ≤ t_end (s, the log's time axis; None: open);
    a LogError when fewer than two are left, naming the log's time span."""
    if t_start is None and t_end is None:
        return frame
    t = frame[TIME].to_numpy(float)
    keep = (t >= (-float("inf") if t_start is None else t_start)) & (
        t <= (float("inf") if t_end is None else t_end))
    if keep.sum() < 2:
        raise LogError(f"--t-start/--t-end keep {int(keep.sum())} rows of the log, whose times "
                       f"run from {t[0]:.6g} s to {t[-1]:.6g} s: choose a window inside it")
    out = frame.loc[keep].reset_index(drop=True)
    out.attrs = dict(frame.attrs)
    return out


def _read_log(args):
    from ..data.bag import is_bag
    from ..data.logs import is_table
    from ..hardware.recording import read_lcm_log
    from ..offline.replay import read_replay_log, to_replay_layout

    if is_table(args.data):
        return to_replay_layout(read_replay_log(args.data), positions=args.positions,
                                velocities=args.velocities, targets=args.targets,
                                time=args.time)
    if is_bag(args.data):
        return read_replay_log(args.data, wrench_topic=args.wrench_topic)
    table, _ = read_lcm_log(args.data, hardware_from_args(args))
    return table
