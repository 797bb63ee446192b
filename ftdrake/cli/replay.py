"""`ftdrake replay`: the runtime chain run offline over a logged stream, one update per row.

    ftdrake replay --model FILE --log FILE --out FILE [--config YAML] [--pairing row|simulated]
                   [--view aligned|held] [--delay S | --align]

Writes the chain's outputs per row (:func:`ftdrake.runtime.replay.replay`: compensated and
contact wrench, std, bias, out-of-domain, fault and contact flags, contact force) as CSV or
Parquet (by the suffix of --out) and prints a JSON summary. --log is a CSV/Parquet table, a
ROS bag (with --wrench-topic) or an LCM log (read with --hardware's channels).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import LogError, ModelFileError
from .main import existing_file, naming, output_path


def register(sub) -> None:
    """Adds ``ftdrake replay`` to an argparse subparsers."""
    p = sub.add_parser(
        "replay", help="the runtime chain (compensator, bias tracker, detector) run offline "
                       "over a log: per-row compensated wrench, std, flags, contact")
    p.add_argument("--model", type=Path, required=True, help="a model file (.ftd)")
    p.add_argument("--log", type=Path, required=True,
                   help="CSV/Parquet table (t, q_i, qd_i, meas_*), ROS bag or LCM log")
    p.add_argument("--out", type=Path, required=True, help="result table (.csv or .parquet)")
    p.add_argument("--config", type=Path,
                   help="scenario YAML: compensator, bias_tracker, detector, sensor rate "
                        "(default: the log's own scenario, else the shipped one)")
    p.add_argument("--pairing", choices=["row", "simulated"], default="row",
                   help="row: each update reads its row's wrench and joint state (a recorded "
                        "log); simulated: the previous row's wrench, as a simulated station's "
                        "compensator reads it (reproduces simulate's columns)")
    p.add_argument("--view", choices=["aligned", "held"], default="aligned",
                   help="aligned: row k holds the outputs of the update that read row k; "
                        "held: what the output ports held when row k arrived (one row later)")
    delay = p.add_mutually_exclusive_group()
    delay.add_argument("--delay", type=float, metavar="S",
                       help="the wrench stream's delay behind the joint states (s, may be "
                            "negative); corrected by a delay line on the joint state")
    delay.add_argument("--align", action="store_true",
                       help="estimate that delay from the log (physics or hybrid model) and "
                            "correct it")
    p.add_argument("--wrench-topic", help="a ROS bag's WrenchStamped topic")
    p.add_argument("--hardware", type=Path,
                   help="HardwareConfig YAML whose channels an LCM log is read with")
    p.add_argument("--quiet", action="store_true", help="no output but the JSON summary")
    p.set_defaults(run=_replay)


def _replay(args) -> int:
    from ..compensation.persistence import load_model
    from ..config import load_config
    from ..runtime.replay import read_replay_log, replay, summary

    existing_file("--model", args.model, ModelFileError)
    with naming("--model", args.model):
        model = load_model(args.model)
    if not args.log.exists():
        raise LogError(f"--log {args.log}: no such file or folder")
    output_path("--out", args.out, folder=False)
    if args.out.suffix not in (".csv", ".parquet"):
        raise LogError(f"--out {args.out}: give a .csv or .parquet file name")
    with naming("--log", args.log):
        frame = _read_log(args, read_replay_log)
    config = None
    if args.config is not None:
        existing_file("--config", args.config)
        with naming("--config", args.config):
            config = load_config(args.config)
    delay = args.delay
    estimate = None
    if args.align:
        from ..data.stream_delay import estimate_stream_delay

        estimate = estimate_stream_delay(model, frame)
        delay = estimate.delay_s
        if abs(delay) <= 2 * estimate.std_s:
            print(f"warning: the estimated delay {delay * 1e3:.2f} ms is within two of its "
                  f"standard errors ({estimate.std_s * 1e3:.2f} ms) of zero; corrected anyway",
                  file=sys.stderr)
    result = replay(model, frame, config, pairing=args.pairing, view=args.view,
                    wrench_delay_s=delay)
    if args.out.suffix == ".csv":
        result.to_csv(args.out, index=False)
    else:
        result.to_parquet(args.out, index=False)
    report = {"out": str(args.out), **summary(result)}
    if delay is not None:
        report["wrench_delay_s"] = delay
    if estimate is not None:
        report["delay_estimate"] = estimate.as_dict()
    print(json.dumps(report))
    return 0


def _read_log(args, read_replay_log):
    from ..data.bag import is_bag
    from ..data.logs import is_table

    if is_table(args.log) or is_bag(args.log):
        return read_replay_log(args.log, wrench_topic=args.wrench_topic)
    from ..hardware.recording import read_lcm_log
    from .hardware import hardware_from_args

    table, _ = read_lcm_log(args.log, hardware_from_args(args))
    return table
