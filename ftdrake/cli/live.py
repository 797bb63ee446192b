"""What `serve` and `record` share on every transport (LCM, ROS 2): the live config file,
stopping on Ctrl-C and the throttled status line."""

from __future__ import annotations

import contextlib
import math
import shutil
import signal
import sys
import time
from typing import TYPE_CHECKING

from . import args as a

if TYPE_CHECKING:
    from ..hardware.live_config import LiveConfig

STATUS_PERIOD_S = 0.5  # status line rate: 2 Hz


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


@contextlib.contextmanager
def starting(model_path, quiet: bool):
    """Says, around the model's loading and the station's build, that serve is starting and
    then how long it took: the build compiles the chain's kernels on the first run after an
    install (numba caches them for the next runs), which takes seconds."""
    if not quiet:
        print(f"ftdrake serve: loading {model_path} and building the chain (a first run "
              "after an install compiles its kernels; later runs load them from numba's "
              "cache)", file=sys.stderr, flush=True)
    start = time.monotonic()
    yield
    if not quiet:
        print(f"ftdrake serve: ready in {time.monotonic() - start:.1f} s", file=sys.stderr,
              flush=True)


def describe_cpus(config) -> str:
    """The line serve's header adds for a transport config's ``cpu_affinity`` ("" unset)."""
    cpus = config.cpu_affinity
    return (f"\n  every thread on CPU {', '.join(map(str, cpus))} (cpu_affinity)" if cpus
            else "")


class Status:
    """The throttled status line: message rates per stream, counts, the current state and
    serve's CPU since the last line (:class:`~ftdrake.hardware.overload.CpuMeter`;
    `cpu_clock`: the process's CPU time in s). The rates and the CPU are measured also when
    `quiet` (the summary reports the last rates)."""

    def __init__(self, station, stream=None, quiet: bool = False,
                 cpu_clock=time.process_time):
        # sys.stderr when called, not when this module was imported (the command line imports
        # it on first use, and a caller may have replaced sys.stderr in between).
        stream = sys.stderr if stream is None else stream
        self.station, self.stream, self.quiet = station, stream, quiet
        self.tty = stream.isatty() and not quiet
        self.last = time.monotonic()
        self.last_counts = dict(station.monitor.received)
        # Here, not at the top: `serve --help` imports this module, and ftdrake.hardware
        # (which overload's package imports) takes a second; the station has it by now.
        from ..hardware.overload import CpuMeter

        self.cpu_meter = CpuMeter(self.last, station.processed, cpu_clock)
        self.rates = {}

    def maybe_print(self, now: float) -> None:
        if now - self.last < STATUS_PERIOD_S:
            return
        received = self.station.monitor.received
        dt = now - self.last
        self.rates = {k: (received[k] - self.last_counts.get(k, 0)) / dt
                      for k in ("joint", "ft")}
        s = self.station
        self.cpu_meter.reading(now, s.processed)
        self.last, self.last_counts = now, dict(received)
        if self.quiet:
            return
        m = s.monitor
        # (rank, text): a terminal too narrow for the line drops the lowest ranks first.
        fields = [(3, f"joint {self.rates['joint']:6.0f} Hz"),
                  (4, f"F/T {self.rates['ft']:6.0f} Hz"), (1, f"processed {s.processed}"),
                  (0, f"published {s.published}"),
                  (2, f"rejected {sum(m.rejected.values())}"), (2, f"lost {s.load.lost}"),
                  (2, f"dropped {s.load.dropped}"),
                  (3, f"behind {s.load.backlog_s * 1e3:.0f} ms"),
                  (5, f"FAULT {m.reason}" if m.fault else "ok"),
                  (5, f"contact {'YES' if s.output('contact')[0] > 0.5 else 'no'}"),
                  (3, _describe_cpu(self.cpu_meter.latest))]
        if self.tty:  # rewritten in place: a line that wraps would leave its start behind
            width = shutil.get_terminal_size().columns - 1
            print(_fitted(fields, width).ljust(width), end="\r", file=self.stream, flush=True)
        else:
            print("  ".join(text for _, text in fields if text), file=self.stream, flush=True)


def _fitted(fields, width: int) -> str:
    """The fields' texts joined by two spaces in their order, the lowest-ranked (first of
    equals) left out until the line fits `width` columns; the one left cut to fit."""
    kept = [field for field in fields if field[1]]
    while len(kept) > 1 and len("  ".join(text for _, text in kept)) > width:
        kept.remove(min(kept, key=lambda field: field[0]))
    return "  ".join(text for _, text in kept)[:width]


def _describe_cpu(cpu: dict) -> str:
    if cpu["core_percent"] is None:
        return ""
    per_message = ("" if cpu["us_per_message"] is None
                   else f" ({cpu['us_per_message']:.0f} µs/msg)")
    return f"CPU {cpu['core_percent']:.0f} %{per_message}"


def describe_path(compiled) -> str:
    """Which per-message path serve runs (a station's ``compiled``), for its header; when
    the compiled loop is still being compiled, a line is printed once it is loaded."""
    if compiled.why_not is not None:
        return f"Python ({compiled.why_not})"
    if compiled.compile_s is None:  # loading or compiling in a process of its own
        compiled.on_ready = lambda done: print(
            f"ftdrake serve: per-message path: compiled, ready {done.compile_s:.1f} s after "
            f"start (loaded in {done.load_s:.2f} s)", file=sys.stderr, flush=True)
        return "Python until the compiled one is loaded"
    return "compiled"


def serve_until_stopped(station, duration_s: float | None, quiet: bool,
                        before_summary=None, cpu_clock=time.process_time) -> dict:
    """Spins `station` until Ctrl-C (SIGINT/SIGTERM) or `duration_s` of wall time (waking
    at most once per its config's ``batch_period_s``), printing the status line; returns its
    summary with the wall time, the last message rates, the latencies (None where nothing
    was published) and ``cpu``: :func:`~ftdrake.hardware.overload.cpu_use` over the whole
    loop (`cpu_clock`: the process's CPU time in s). `before_summary()` runs after the
    loop."""
    status = Status(station, quiet=quiet, cpu_clock=cpu_clock)
    start = time.monotonic()
    from ..hardware.overload import CpuMeter  # here: see Status

    whole_run = CpuMeter(start, station.processed, cpu_clock)
    batch = float(getattr(station.config, "batch_period_s", 0.0))  # s between wake-ups
    with stop_on_signals() as stop:
        while not stop[0]:
            woke = time.monotonic()
            station.spin_once(timeout_ms=2)
            now = time.monotonic()
            if batch > 0 and now - woke < batch:  # the next wake-up takes what came meanwhile
                time.sleep(batch - (now - woke))
                now = time.monotonic()
            status.maybe_print(now)
            if duration_s is not None and now - start >= duration_s:
                break
    if before_summary is not None:
        before_summary()
    if status.tty:
        print(file=sys.stderr)
    summary = station.summary()
    summary["wall_time_s"] = time.monotonic() - start
    summary["cpu"] = whole_run.reading(start + summary["wall_time_s"], station.processed)
    summary["last_rates_hz"] = status.rates
    summary["latency_ms"] = {k: (None if math.isnan(v) else v)  # nothing published: null
                             for k, v in summary["latency_ms"].items()}
    return summary


def load_live(args) -> LiveConfig:
    """The LiveConfig of --config (chain and transports) with the robot flags applied to its
    chain; errors name --config."""
    from ..hardware.live_config import load_live_config

    with a.naming("--config", args.config) if args.config else contextlib.nullcontext():
        live = load_live_config(args.config)
    live.chain = a.with_robot_flags(live.chain, args)
    return live
