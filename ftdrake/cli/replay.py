"""`ftdrake replay`: the runtime chain run offline over a logged stream, one update per row.

    ftdrake replay --model FILE --log FILE --out FILE [--config YAML] [--robot FILE
                   --sensor-frame NAME] [--pairing row|simulated]
                   [--view aligned|held] [--delay S | --align] [--budget]
                   [--calibrate-detector YAML]

Writes the chain's outputs per row (:func:`ftdrake.runtime.replay.replay`: compensated and
contact wrench, std, bias, out-of-domain, fault and contact flags, contact force) as CSV or
Parquet (by the suffix of --out) and prints a JSON summary. --log is a CSV/Parquet table, a
ROS bag (with --wrench-topic) or an LCM log (read with --hardware's channels). --budget adds
what the in-motion residual is made of (offset, drift, stream delay, the sensor's filter,
remainder: :func:`ftdrake.experiments.residual_budget.residual_budget`) to the summary.
--calibrate-detector writes the chain config with its detector's thresholds set for its budget
from the log, which must be contact-free motion the model was not trained on
(:func:`ftdrake.runtime.replay.calibrated_detector`); ``serve`` and ``replay`` take it as
--config.
"""

from __future__ import annotations

import dataclasses as dc
import json
import sys

from ..compensation.files.persistence import load_model
from ..config import save_config
from ..data.bag import is_bag
from ..data.logs import is_table, write_log
from ..data.stream_delay import estimate_stream_delay
from ..errors import ConfigError, LogError
from ..experiments.residual_budget import residual_budget
from ..hardware.recording import read_lcm_log
from ..runtime.replay import (
    calibrated_detector,
    chain_config_of,
    read_replay_log,
    replay,
    summary,
    to_replay_layout,
)
from . import args as a
from .hardware import add_transport_flags, hardware_from_args


def register(sub) -> None:
    """Adds ``ftdrake replay`` to an argparse subparsers."""
    p = a.add_command(
        sub, "replay", "the runtime chain run offline over a log",
        "Per row: the compensated and contact wrench, std, bias, out-of-domain, fault and "
        "contact flags, as the chain in the loop gives them.")
    a.add_model_file(p, required=True)
    p.add_argument("--log", type=a.existing_path, required=True, metavar="FILE",
                   help="CSV/Parquet table (t, q_i, qd_i, meas_*), ROS bag or LCM log")
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
    p.add_argument("--calibrate-detector", type=a.output_file, metavar="YAML",
                   help="also write the chain config (--config's, the log's or the "
                        "defaults) with the detector's thresholds set for its false-positive "
                        "budget from this log, which must be contact-free motion the model "
                        "was not trained on (detector.test auto: the χ² test for a physics, "
                        "hybrid or GP model)")
    p.add_argument("--wrench-topic", metavar="TOPIC", help="a ROS bag's WrenchStamped topic")
    for flag, default, what in (("--positions", "q_*", "joint position columns (rad)"),
                                ("--velocities", "qd_*", "joint velocity columns (rad/s)"),
                                ("--targets", "meas_*", "the sensor's wrench columns (N, N·m)")):
        p.add_argument(flag, metavar="PAT", help=f"tables: {what}, default '{default}'; a glob, "
                       "a comma-separated list or a regular expression after 're:'")
    p.add_argument("--time", metavar="COL", help="tables: the time column (s), default 't'")
    add_transport_flags(p, lcm_help="unused by replay (an LCM log is read with --hardware's "
                                    "channels)")
    a.add_quiet(p, "no warnings on stderr; the JSON summary still prints")
    p.set_defaults(run=run_replay)


def run_replay(args) -> int:
    _check_flags(args)
    with a.naming("--model", args.model):
        model = load_model(args.model)
    with a.naming("--log", args.log):
        frame = _read_log(args)
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
    result = replay(model, frame, config, pairing=args.pairing, view=args.view)
    write_log(result, args.out)
    report = {"out": str(args.out), **summary(result)}
    if delay is not None:
        report["wrench_delay_s"] = delay
    if estimate is not None:
        report["delay_estimate"] = estimate.as_dict()
    if args.budget:
        report["residual_budget"] = residual_budget(model, frame, config, result=result).as_dict()
    if args.calibrate_detector is not None:
        report["detector"] = _write_calibrated(args.calibrate_detector, result, model,
                                               chain_config_of(frame, config))
    print(json.dumps(report))
    return 0


def _check_flags(args) -> None:
    if args.out.suffix not in (".csv", ".parquet"):
        raise LogError(f"--out {args.out}: give a .csv or .parquet file name")
    if args.calibrate_detector is not None and (args.delay is not None or args.align):
        raise ConfigError("--calibrate-detector with --delay/--align: serve corrects only the "
                          "delay the model was trained with, so thresholds set on a corrected "
                          "replay would not hold there; train with --delay/--align instead")


def _chain_given(args) -> bool:
    """Whether the command line sets the chain config (else: the log's, see replay)."""
    return any(v is not None for v in (args.config, args.robot, args.sensor_frame,
                                       args.base_frame))


def _write_calibrated(path, result, model, chain) -> dict:
    """Writes the chain config `chain` with the detector calibrated on `result`; returns the
    detector."""
    detector = calibrated_detector(result, model, chain)
    save_config(chain.replace(detector=detector), path)
    return {"file": str(path), **dc.asdict(detector)}


def _read_log(args):
    if is_table(args.log):
        return to_replay_layout(read_replay_log(args.log), positions=args.positions,
                                velocities=args.velocities, targets=args.targets,
                                time=args.time)
    if is_bag(args.log):
        return read_replay_log(args.log, wrench_topic=args.wrench_topic)
    table, _ = read_lcm_log(args.log, hardware_from_args(args))
    return table
