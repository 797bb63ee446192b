"""`ftdrake serve` and `ftdrake record`: the compensator on a live robot's LCM streams.

    ftdrake serve --model m.ftd [--config scenario.yaml] [--hardware hw.yaml] [--lcm URL]
    ftdrake record --lcm URL --out log.parquet [--duration S]
    ftdrake record --from-log lcmlog-2025-01-01.00 --out log.parquet

``--hardware`` is a :class:`~ftdrake.hardware.config.HardwareConfig` YAML (channels, message
types, timeouts, joint count); ``--lcm`` overrides its ``lcm_url``. ``--config`` is the usual
scenario YAML: serve takes the compensator, bias-tracker, detector and sensor (rate, drift)
settings from it. ``ftdrake simulate --lcm URL [--realtime]`` (cli/main.py) publishes a
simulated robot on the same channels.

serve prints the channels, then a status line twice a second (stderr), each fault and
recovery as it happens (stderr), and on Ctrl-C (SIGINT or SIGTERM) or after ``--duration`` a
JSON summary of the counts (stdout).
"""

from __future__ import annotations

import contextlib
import json
import math
import signal
import sys
import time
from pathlib import Path

from ..errors import ConfigError, ModelFileError
from . import ros2
from .main import existing_file, load_scenario, naming, output_path, positive_float

STATUS_PERIOD_S = 0.5  # status line rate: 2 Hz


def register(sub) -> None:
    """Adds ``serve`` and ``record`` to an ``argparse`` subparsers object."""
    p = sub.add_parser("serve", help="run a compensator on a live robot's LCM streams; publish "
                       "the external wrench and the contact state")
    p.add_argument("--model", type=Path, required=True, help="a model file (train's --out)")
    p.add_argument("--config", type=Path, help="scenario YAML: compensator, bias_tracker, "
                   "detector, sensor settings (default: the shipped one)")
    _add_transport_flags(p)
    p.add_argument("--duration", type=positive_float, help="stop after S seconds (wall clock)")
    ros2.add_options(p)
    p.set_defaults(run=_serve)

    p = sub.add_parser("record", help="record a live robot's joint state and F/T (LCM) into the "
                       "Parquet layout of `collect`, for train/evaluate")
    source = p.add_mutually_exclusive_group()
    source.add_argument("--from-log", type=Path, metavar="LCMLOG",
                        help="convert an lcm-logger file instead of listening")
    _add_transport_flags(p)
    p.add_argument("--out", type=Path, required=True, help="FILE.parquet")
    p.add_argument("--duration", type=positive_float,
                   help="stop after S seconds (default: on Ctrl-C)")
    p.add_argument("--tolerance", type=positive_float, default=0.002, metavar="S",
                   help="a joint state older than this (s) matches no F/T row, default 0.002")
    ros2.add_options(p)
    p.set_defaults(run=_record)


def _add_transport_flags(p) -> None:
    p.add_argument("--hardware", type=Path, metavar="FILE",
                   help="HardwareConfig YAML: channels, message types, timeouts, n_joints")
    p.add_argument("--lcm", metavar="URL", help="LCM URL, e.g. 'udpm://239.255.76.67:7667?ttl=0'"
                   " or 'memq://' (default: the --hardware file's lcm_url)")


def hardware_from_args(args):
    """The HardwareConfig of --hardware (defaults without it) with --lcm applied."""
    from ..config import load_config
    from ..hardware.config import HardwareConfig

    path = getattr(args, "hardware", None)
    if path is None:
        config = HardwareConfig()
    else:
        existing_file("--hardware", path, ConfigError)
        with naming("--hardware", path):
            config = load_config(path, schema=HardwareConfig)
    if getattr(args, "lcm", None):
        config.lcm_url = args.lcm
    with naming("--lcm", args.lcm) if getattr(args, "lcm", None) else contextlib.nullcontext():
        return config.validate()


def open_transport(args, hardware):
    from ..hardware.transport import open_lcm

    where = (f"--lcm {args.lcm}" if getattr(args, "lcm", None)
             else f"--hardware {args.hardware}" if args.hardware else "hardware.lcm_url")
    return open_lcm(hardware.lcm_url, where=where)


def describe_channels(hardware) -> str:
    h = hardware
    joint = f"{h.joint_state_channel} ({h.joint_state_type})"
    if h.joint_state_type == "robot_state":
        joint += f" + velocities {h.velocity_channel}"
    return (f"LCM {h.lcm_url}\n  in:  {joint}; F/T {h.ft_channel} (force_torque)\n"
            f"  out: external wrench {h.external_wrench_channel} (force_torque); contact "
            f"{h.contact_channel} (drake_signal: contact, contact_force, fault, out_of_domain)")


@contextlib.contextmanager
def stop_on_signals():
    """Yields a one-element list that becomes [True] on SIGINT or SIGTERM; restores the
    previous handlers after."""
    stop = [False]

    def handler(_signum, _frame):
        stop[0] = True

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


class _Status:
    """The throttled status line: message rates per stream, counts, the current state."""

    def __init__(self, station, stream=sys.stderr):
        self.station, self.stream = station, stream
        self.tty = stream.isatty()
        self.last = time.monotonic()
        self.last_counts = dict(station.monitor.received)
        self.rates = {}

    def maybe_print(self, now: float) -> None:
        if now - self.last < STATUS_PERIOD_S:
            return
        received = self.station.monitor.received
        dt = now - self.last
        self.rates = {k: (received[k] - self.last_counts.get(k, 0)) / dt
                      for k in ("joint", "ft")}
        self.last, self.last_counts = now, dict(received)
        s = self.station
        m = s.monitor
        state = f"FAULT {m.reason}" if m.fault else "ok"
        contact = s._out["contact"].Eval(s.context)[0] > 0.5
        line = (f"joint {self.rates['joint']:6.0f} Hz  F/T {self.rates['ft']:6.0f} Hz  "
                f"processed {s.processed}  published {s.published}  "
                f"rejected {sum(m.rejected.values())}  {state}  "
                f"contact {'YES' if contact else 'no'}")
        end = "\r" if self.tty else "\n"
        print(line.ljust(100), end=end, file=self.stream, flush=True)


def _serve(args) -> int:
    from ..compensation.persistence import load_model
    from ..hardware.station import HardwareStation

    if args.ros2:
        return ros2.serve(args)
    scenario = load_scenario(args)
    hardware = hardware_from_args(args)
    existing_file("--model", args.model, ModelFileError)
    with naming("--model", args.model):
        model = load_model(args.model, expect_n_joints=hardware.n_joints)
    transport = open_transport(args, hardware)

    def on_event(event) -> None:
        print(f"ftdrake serve: {event}", file=sys.stderr, flush=True)

    station = HardwareStation(hardware, model, scenario, transport, on_event=on_event)
    print(f"ftdrake serve: {type(model).__name__} from {args.model}, "
          f"{1 / station.period:g} Hz updates\n{describe_channels(hardware)}",
          file=sys.stderr, flush=True)
    status = _Status(station)
    start = time.monotonic()
    with stop_on_signals() as stop:
        while not stop[0]:
            station.spin_once(timeout_ms=2)
            now = time.monotonic()
            status.maybe_print(now)
            if args.duration is not None and now - start >= args.duration:
                break
    if status.tty:
        print(file=sys.stderr)
    summary = station.summary()
    summary["wall_time_s"] = time.monotonic() - start
    summary["last_rates_hz"] = status.rates
    summary["latency_ms"] = {k: (None if math.isnan(v) else v)  # nothing published: null
                             for k, v in summary["latency_ms"].items()}
    print(json.dumps(summary))
    return 0


def _record(args) -> int:
    from ..hardware.recording import read_lcm_log, table_from_messages, write_table

    if args.ros2:
        return ros2.record(args)
    hardware = hardware_from_args(args)
    output_path("--out", args.out, folder=False)
    if args.from_log is not None:
        existing_file("--from-log", args.from_log)
        with naming("--from-log", args.from_log):
            table, report = read_lcm_log(args.from_log, hardware, args.tolerance)
    else:
        transport = open_transport(args, hardware)
        messages = []
        channels = [hardware.joint_state_channel, hardware.ft_channel]
        if hardware.joint_state_type == "robot_state":
            channels.append(hardware.velocity_channel)
        for channel in channels:
            transport.subscribe(channel, lambda data, c=channel: messages.append((c, data)))
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
