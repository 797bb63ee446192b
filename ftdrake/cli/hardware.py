"""`ftdrake serve` and `ftdrake record`: the compensator on a live robot's LCM streams (with
``--ros2``, its ROS 2 topics: cli/ros2.py).

    ftdrake serve --model m.ftd [--config scenario.yaml] [--hardware hw.yaml] [--lcm URL]
    ftdrake record --lcm URL --out log.parquet [--duration S]
    ftdrake record --data lcmlog-2025-01-01.00 --out log.parquet

``--hardware`` is a :class:`~ftdrake.hardware.config.HardwareConfig` YAML (channels, message
types, timeouts, joint count); ``--lcm`` overrides its ``lcm_url``. ``--config`` is a chain config
(:class:`~ftdrake.config.ChainConfig`): serve takes the compensator, bias-tracker, detector,
sensor stream (rate, noise, drift) and robot
settings from it. ``ftdrake simulate --lcm URL [--realtime]`` (cli/simulation.py) publishes a
simulated robot on the same channels.

serve prints the channels, then a status line twice a second (stderr; neither with
``--quiet``), each fault and recovery as it happens (stderr), and on Ctrl-C (SIGINT or
SIGTERM) or after ``--duration`` a JSON summary of the counts (stdout).
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
from typing import TYPE_CHECKING

from ..config import load_config
from . import args as a
from . import ros2
from .live import (
    describe_cpus,
    describe_path,
    load_live,
    serve_until_stopped,
    starting,
    stop_on_signals,
)

if TYPE_CHECKING:
    from ..hardware.config import HardwareConfig
    from ..hardware.live_config import LiveConfig


def register(sub) -> None:
    """Adds ``serve`` and ``record`` to an ``argparse`` subparsers object."""
    p = a.add_command(sub, "serve", "run a compensator on a live robot (LCM or ROS 2)",
                      "Reads the joint state and F/T streams; publishes the contact wrench, "
                      "the compensated wrench and the contact state.")
    a.add_model_file(p, required=True)
    a.add_chain_config(p)
    add_transport_flags(p)
    p.add_argument("--duration", type=a.positive_float, metavar="S",
                   help="stop after S seconds, wall clock (default: on Ctrl-C)")
    a.add_quiet(p, "no channel list and no status line (faults and the summary still print)")
    ros2.add_options(p)
    p.set_defaults(run=run_serve)

    p = a.add_command(sub, "record", "record a live robot (LCM or ROS 2) for train/evaluate",
                      "The joint state and F/T, in the Parquet layout of `collect`.")
    data = p.add_argument("--data", type=a.existing_file, metavar="LCMLOG",
                          help="convert an lcm-logger file instead of listening")
    a.add_deprecated(p, "--from-log", data)
    add_transport_flags(p)
    p.add_argument("--out", type=a.output_file, required=True, metavar="FILE",
                   help="FILE.parquet")
    p.add_argument("--duration", type=a.positive_float, metavar="S",
                   help="stop after S seconds (default: on Ctrl-C)")
    p.add_argument("--tolerance", type=a.positive_float, default=0.002, metavar="S",
                   help="a joint state older than this (s) matches no F/T row")
    a.add_quiet(p, "no channel line on stderr")
    ros2.add_options(p)
    p.set_defaults(run=run_record)


def add_transport_flags(p, lcm_help: str = "LCM URL, e.g. 'udpm://239.255.76.67:7667?ttl=0' "
                        "or 'memq://' (default: the --hardware file's lcm_url)",
                        lcm: bool = True) -> None:
    """``--hardware FILE`` and (with `lcm`) ``--lcm URL``: the live robot's channels and
    transport."""
    p.add_argument("--hardware", type=a.existing_file, metavar="FILE",
                   help="HardwareConfig YAML: channels, message types, timeouts, n_joints "
                        "(default: ftdrake's channels)")
    if lcm:
        p.add_argument("--lcm", metavar="URL", help=lcm_help)


def hardware_from_args(args, live: LiveConfig | None = None) -> HardwareConfig:
    """The HardwareConfig of --hardware (else the live config's ``lcm:`` section, else the
    defaults) with --lcm applied."""
    from ..hardware.config import HardwareConfig

    if args.hardware is None:
        config = live.lcm if live is not None else HardwareConfig()
    else:
        with a.naming("--hardware", args.hardware):
            config = load_config(args.hardware, schema=HardwareConfig)
    url = getattr(args, "lcm", None)  # replay reads a log: it has no --lcm
    if url:
        config.lcm_url = url
    with a.naming("--lcm", url) if url else contextlib.nullcontext():
        return config.validate()


def open_transport(args, hardware: HardwareConfig):
    from ..hardware.transport import open_lcm

    where = (f"--lcm {args.lcm}" if args.lcm
             else f"--hardware {args.hardware}" if args.hardware else "hardware.lcm_url")
    return open_lcm(hardware.lcm_url, where=where, native=hardware.compiled_path)


def describe_channels(hardware) -> str:
    h = hardware
    joint = f"{h.joint_state_channel} ({h.joint_state_type})"
    if h.joint_state_type == "robot_state":
        joint += f" + velocities {h.velocity_channel}"
    return (f"LCM {h.lcm_url}\n  in:  {joint}; F/T {h.ft_channel} (force_torque)\n"
            "  out: " + "; ".join(f"{channel} ({ports})"
                                  for channel, ports in h.output_channels().items())
            + (f" on {h.output_url}" if h.output_url and h.output_url != h.lcm_url else "")
            + describe_cpus(h))






def run_serve(args) -> int:
    from ..compensation.files.persistence import load_model
    if args.ros2:
        return ros2.serve(args)
    from ..hardware.station import HardwareStation

    live = load_live(args)
    hardware = hardware_from_args(args, live)

    def on_event(event) -> None:
        print(f"ftdrake serve: {event}", file=sys.stderr, flush=True)

    def on_warning(warning: str) -> None:
        print(f"ftdrake serve: warning: {warning}", file=sys.stderr, flush=True)

    with starting(args.model, args.quiet):
        with a.naming("--model", args.model):
            model = load_model(args.model)  # its joint count against lcm.n_joints: the station's
        transport = open_transport(args, hardware)
        station = HardwareStation(hardware, model, live.chain, transport, on_event=on_event,
                                  on_warning=on_warning)
    if not args.quiet:
        print(f"ftdrake serve: {type(model).__name__} from {args.model}, "
              f"{1 / station.period:g} Hz updates, per-message path: "
              f"{describe_path(station.compiled)}\n{describe_channels(hardware)}",
              file=sys.stderr, flush=True)
    try:
        summary = serve_until_stopped(station, args.duration, args.quiet)
    finally:
        station.close()
    print(json.dumps(summary))
    return 0


def run_record(args) -> int:
    if args.ros2:
        return ros2.record(args)
    from ..hardware.recording import read_lcm_log, table_from_messages, write_table

    hardware = hardware_from_args(args)
    if args.data is not None:
        with a.naming("--data", args.data):
            table, report = read_lcm_log(args.data, hardware, args.tolerance)
    else:
        transport = open_transport(args, hardware)
        messages = []
        channels = [hardware.joint_state_channel, hardware.ft_channel]
        if hardware.joint_state_type == "robot_state":
            channels.append(hardware.velocity_channel)
        for channel in channels:
            transport.subscribe(channel, lambda data, c=channel: messages.append((c, data)))
        if not args.quiet:
            print(f"ftdrake record: {describe_channels(hardware).splitlines()[1].strip()} "
                  f"on {hardware.lcm_url} → {args.out}", file=sys.stderr, flush=True)
        start = time.monotonic()
        with stop_on_signals() as stop:
            while not stop[0]:
                transport.handle(10)
                if args.duration is not None and time.monotonic() - start >= args.duration:
                    break
        transport.handle(0)
        table, report = table_from_messages(messages, hardware, args.tolerance,
                                            source=f"--lcm {hardware.lcm_url}")
    write_table(table, args.out)
    print(json.dumps({"out": str(args.out), **report}))
    return 0
