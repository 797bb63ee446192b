"""Live at the sensor's rate: ``ftdrake serve`` in its own process fed by a driver (this
process) over loopback, at each rate of `--rates`, with the physics and the hybrid model, on
a free-motion log.

The models are trained as ``ftdrake train`` trains them (``make_estimator``) on `--train-s`
s of simulated free motion on ftdrake's arm; a second free-motion simulation, resampled at
each rate, is what the driver sends: a joint state and a wrench per sample, stamped k/rate,
paced by the wall clock (at rates ≥ `--burst-at`, in batches of `--burst` samples, as
SCHUNK's driver sends 16-sample batches). serve runs the live chain (compensator, bias
tracker, detector; ``chain.sensor.rate_hz`` = the rate) on ROS 2 (Cyclone DDS on a
loopback-only domain) or LCM (``udpm://239.255.76.67:<port>?ttl=0``: multicast that does not
leave the host). Per rate and model:

* sent (wrenches), received / processed / published (serve's summary), lost = sent −
  processed, dropped (serve's overload drops) and lost by stamps (serve's),
* cpu_us_per_msg: serve's process CPU time (user + system, /proc) over the timed messages
  (after `--warmup` s) divided by their count; the ratio to the compensator's own
  per-sample cost (its row predictor, timed in this process on the same rows),
* serve p50/p99 (arrival → publication, serve's own), end-to-end p50/p99/p99.9 (this
  process's write of a wrench → its receipt of serve's contact wrench),
* false_contacts: contact episodes (rising edges of the published contact flag) on the
  free-motion log,
* cpu_us_per_msg_median: the median over the run's seconds of serve's CPU per message in
  that second; main_thread_cpu_us_per_msg: its main thread's (the station's Python loop;
  the rest is the transport's threads); serve_cpu_us_per_msg: serve's own figure (its
  summary's ``cpu``, over its whole loop, the warm-up included),
* serve_start_s: serve's start to listening; first_output_s: the driver's topics
  appearing (serve already listening) to the first output received (ROS 2: DDS discovery
  included).
* rejected, fault_episodes: serve's counts of the samples it refused, per reason, and of
  its fault episodes: where samples received but not processed went.
* warnings: what serve warned of (its summary's), e.g. little headroom; printed under the
  run's line.

serve is started first; the driver then appears and sends once matched. It sleeps until
each message (or batch) is due, handling serve's outputs as they come, so that it does not
keep a core busy. `--no-yield-io-threads` leaves serve's receive threads at the default
policy (``yield_io_threads: false``); `--separate-outputs` (LCM) has serve publish on a URL
of its own (``output_url``), where the driver listens. `--load-core` keeps one core busy
with a second process during the runs
(the issue's "second process loading one core"); `--outputs` sets serve's published
outputs (the driver reads wrench_contact and contact), `--batch-period` its
``batch_period_s``; `--joint-every N` sends a joint state with every N-th wrench only (a
joint stream at the rate / N); `--profile DIR` runs serve under
cProfile.

`--floor` measures the transport's own cost at the same settings: serve runs as always
(transport, receive threads, decode, its loop and status) but each F/T message publishes the
outputs' values without the checks, the chain's update or any bookkeeping
(``station_floor.py``); the CPU per message of a normal run minus the floor's is the cost of
ftdrake's own work. `--no-chain` runs serve as always but for the chain's update
(``chain_held.py``: each update returns the outputs as they stand): a normal run minus it is
what the chain's update costs live; it minus the floor, the rest of ftdrake's work. These
measure serve's Python path: `--phases` and `--no-chain` set ``compiled_path: false``, and
the floor never reaches the compiled path's ordinary state. `--echo`
starts ``transport_echo.py`` instead of serve: the wrench
echoed back with a contact flag on the same transport, the least a Python process does per
message there (ROS 2: `--echo listener` takes the messages on Cyclone's receive thread
instead of waking the main thread; `--echo compiled` runs its loop compiled,
``compiled_echo.py``: the least a compiled path costs). `--python-path` runs serve
with ``compiled_path: false``: every message through the Python path, to compare with the
compiled one (serve's summary says how many messages each path took). `--cpu-affinity`
sets serve's ``cpu_affinity`` (all its threads on those CPUs); `--driver-cpus` keeps this
process, the driver, on others.
`--phases` splits serve's main thread by phase (``serve_phases.py``: the wait, the receive,
the joint-state and F/T callbacks, each output's write, the loop around them; µs per F/T
message over the timed messages, timed with the thread's clock, whose readings make each
read somewhat high). `--perf DIR` samples serve with Linux ``perf`` over the same
messages (``cpu_by_library.py``): its CPU by library (the interpreter, numpy, the compiled
kernels, the transport's library, the kernel, libc), each a share and µs per message.

The machine's 1-minute load average before and after each run is printed: on a shared
machine the rates a run sustains depend on what else runs. The last line is one JSON object
``{"<rate>": {"<model>": {"sent", "received", "processed", "published", "lost",
"cpu_us_per_msg", "p99_ms", "false_contacts", ...}}}``.

    python benchmarks/live_rate.py [--transport ros2|lcm] [--rates 500,1000,2000,4000]
                                   [--seconds 60] [--models physics,hybrid] [--load-core]
                                   [--outputs wrench_contact,contact]
                                   [--separate-outputs] [--no-yield-io-threads] [--floor]
                                   [--no-chain]
                                   [--echo [wait|listener|compiled]] [--python-path]
                                   [--cpu-affinity 1]
                                   [--driver-cpus 0] [--joint-every 2] [--perf DIR]

The issue's soaks (long: run them on an otherwise idle machine)::

    python benchmarks/live_rate.py --transport ros2 --rates 1000 --seconds 600
    python benchmarks/live_rate.py --transport ros2 --rates 2000,4000 --seconds 60
    python benchmarks/live_rate.py --transport lcm --rates 1000 --seconds 600
    python benchmarks/live_rate.py --transport lcm --rates 2000,4000 --seconds 60

(4000 Hz is sent in 16-sample batches; add ``--load-core`` for the loaded table.)
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cpu_by_library
import numpy as np

from ftdrake import RobotOptions, ScenarioConfig, make_estimator, save_model
from ftdrake.conventions import (
    MEASURED,
    QD,
    QDD,
    WRENCH_AXES,
    WRENCH_UNITS,
    Q,
    joint_columns,
    wrench_columns,
)
from ftdrake.hardware.threads import pin_process, usable_cpus
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station

DOMAIN = 170 + os.getpid() % 30
N = 7

# serve with the per-message work taken out (--floor; station_floor.py, beside this file),
# with its phases timed (--phases; serve_phases.py), or without the chain's update
# (--no-chain; chain_held.py).
SERVE_WITH = """
import sys
sys.path.insert(0, {folder!r})
import {module}
from ftdrake.cli.main import main
{module}.install()
sys.exit(main(sys.argv[1:]))
"""
FLOOR_SERVE, PHASES_SERVE, NO_CHAIN_SERVE = (
    SERVE_WITH.format(folder=str(Path(__file__).resolve().parent), module=module)
    for module in ("station_floor", "serve_phases", "chain_held"))


def free_motion(seconds: float, seed: int):
    """(t, X [q, q̇, q̈], wrench) of `seconds` of simulated free motion on ftdrake's arm."""
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "fourier"
    scenario.trajectory.duration_s = seconds
    scenario.trajectory.seed = seed
    station = build_station(scenario)
    log = simulate(station, progress=False).log
    X = log[[*joint_columns(Q, N), *joint_columns(QD, N), *joint_columns(QDD, N)]].to_numpy()
    return log["t"].to_numpy(), X, log[wrench_columns(MEASURED)].to_numpy(), station


def resampled(t, X, W, rate: float, count: int):
    """q, q̇ (n) and the wrench at k/rate, k = 1..count, linearly interpolated (the log
    repeated when it is shorter)."""
    span = t[-1] - t[0]
    times = (np.arange(1, count + 1) / rate) % span + t[0]
    q = np.column_stack([np.interp(times, t, X[:, j]) for j in range(N)])
    v = np.column_stack([np.interp(times, t, X[:, N + j]) for j in range(N)])
    w = np.column_stack([np.interp(times, t, W[:, j]) for j in range(6)])
    return q, v, w


def cpu_s(pid: int, task: int | None = None) -> float:
    """User + system CPU time (s) of process `pid` so far (Linux /proc); of its thread
    `task` only when given."""
    path = f"/proc/{pid}/task/{task}/stat" if task is not None else f"/proc/{pid}/stat"
    fields = Path(path).read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main_thread_cpu_s(pid: int) -> float:
    """CPU time (s) of process `pid`'s main thread (the station's loop: Python), the rest
    being the transport's threads (LCM's receive thread, Cyclone's)."""
    return cpu_s(pid, pid)


def compensator_us(model, X) -> float:
    """The model's row predictor's cost per sample (µs), median of 5 runs over 2000 rows."""
    predict = model.row_predictor()
    rows = [np.ascontiguousarray(r) for r in X[:2000]]
    for r in rows[:200]:
        predict(r)
    runs = []
    for _ in range(5):
        start = time.perf_counter()
        for r in rows:
            predict(r)
        runs.append((time.perf_counter() - start) / len(rows) * 1e6)
    return float(np.median(runs))


class Ros2Driver:
    """Writes the joint states and wrenches on DDS; collects serve's contact wrenches and
    contact flags."""

    def __init__(self, names):
        from ftdrake.hardware.ros2.config import Ros2Config
        from ftdrake.hardware.ros2.dds import Ros2Node
        from ftdrake.hardware.ros2.messages import from_stamp, header, ros2_type, wrench_stamped

        self.config = Ros2Config(joint_names=list(names), domain_id=DOMAIN,
                                 queue_depth=20_000).validate()
        self.node = Ros2Node(DOMAIN)
        self.header, self.wrench_stamped = header, wrench_stamped
        self.JointState = ros2_type("sensor_msgs/msg/JointState")
        self.names = list(names)
        self.back, self.contacts = {}, []
        self.joints = self.node.publisher(self.config.joint_state_topic,
                                          "sensor_msgs/msg/JointState", depth=20_000)
        self.wrenches = self.node.publisher(self.config.wrench_topic,
                                            "geometry_msgs/msg/WrenchStamped", depth=20_000)
        self.node.subscribe(self.config.output_topic("wrench_contact"),
                            "geometry_msgs/msg/WrenchStamped",
                            lambda m, _arrival: self.back.setdefault(
                                round(from_stamp(m.header.stamp) * 1e6), time.monotonic()),
                            depth=200_000)
        self.node.subscribe(self.config.output_topic("contact"), "std_msgs/msg/Bool",
                            lambda m, _a: self.contacts.append(bool(m.data)), depth=200_000)

    @staticmethod
    def live_section(names) -> dict:
        return {"ros2": {"joint_names": list(names), "domain_id": DOMAIN, "queue_depth": 20_000,
                         "sensor_timeout_s": 0.5, "joint_state_timeout_s": 0.5}}

    @staticmethod
    def flags(_port) -> list:
        return ["--ros2"]

    def ready(self) -> bool:
        return all(self.node.matched().values()) and len(self.node.matched()) >= 4

    def send(self, t, q, v, w, joint: bool = True) -> None:
        if joint:
            self.joints.write(self.JointState(header=self.header(t), name=self.names,
                                              position=[float(x) for x in q],
                                              velocity=[float(x) for x in v], effort=[]))
        self.wrenches.write(self.wrench_stamped(self.header(t, "ft_sensor"), w))

    def poll(self, timeout_ms: float = 0) -> None:
        self.node.spin(timeout_ms)

    def wait(self, seconds: float) -> None:
        """Handles serve's outputs as they come, for up to `seconds` (not spinning)."""
        self.node.spin(seconds * 1e3)

    def close(self) -> None:
        self.node.close()


class LcmDriver:
    """The same on LCM (multicast with ttl=0: it stays on this host)."""

    def __init__(self, port: int, _names=None, separate_outputs: bool = False):
        import lcm

        from ftdrake.hardware.config import HardwareConfig
        from ftdrake.hardware.messages import (
            decode_contact_state,
            decode_wrench,
            encode_joint_state,
            encode_wrench,
        )

        self.url = self.flags(port)[1]
        self.config = HardwareConfig(lcm_url=self.url).validate()
        self.lc = lcm.LCM(self.url)
        # serve's outputs: on the same group, or on their own (serve's output_url).
        self.out = lcm.LCM(self.output_url(port)) if separate_outputs else self.lc
        self.encode_joint_state, self.encode_wrench = encode_joint_state, encode_wrench
        self.back, self.contacts = {}, []

        def on_wrench(_channel, data):
            self.back.setdefault(round(decode_wrench(data).t * 1e6), time.monotonic())

        def on_contact(_channel, data):
            self.contacts.append(decode_contact_state(data).contact)

        self._subscriptions = []
        for channel, handler in ((self.config.output_channel("wrench_contact"), on_wrench),
                                 (self.config.output_channel("contact"), on_contact)):
            subscription = self.out.subscribe(channel, handler)
            subscription.set_queue_capacity(200_000)
            self._subscriptions.append(subscription)

    @staticmethod
    def live_section(_names) -> dict:
        return {"lcm": {"sensor_timeout_s": 0.5, "joint_state_timeout_s": 0.5}}

    @staticmethod
    def flags(port) -> list:
        return ["--lcm", f"udpm://239.255.76.67:{port}?ttl=0"]

    @staticmethod
    def output_url(port) -> str:
        return f"udpm://239.255.76.67:{port + 1}?ttl=0"

    def ready(self) -> bool:
        return True

    def send(self, t, q, v, w, joint: bool = True) -> None:
        c = self.config
        if joint:
            self.lc.publish(c.joint_state_channel,
                            self.encode_joint_state("iiwa_status", t, q, v))
        self.lc.publish(c.ft_channel, self.encode_wrench(t, w))

    def poll(self, timeout_ms: float = 0) -> None:
        while self.out.handle_timeout(int(timeout_ms)) > 0:
            timeout_ms = 0

    def wait(self, seconds: float) -> None:
        """Handles serve's outputs as they come, for up to `seconds` (not spinning)."""
        if select.select([self.out.fileno()], [], [], max(0.0, seconds))[0]:
            self.poll(0)

    def close(self) -> None:
        """Leaves the multicast group: a driver left in it (its handlers hold it in a
        reference cycle) would receive every datagram of the next runs, on its own thread,
        and serve's sends would deliver to one socket more, raising serve's CPU per message
        in each later run."""
        for subscription in self._subscriptions:
            self.out.unsubscribe(subscription)
        self._subscriptions.clear()
        self.lc = self.out = None
        gc.collect()  # LCM's own deletion leaves the group and stops its receive thread


def start_serve(model, rate, kind, names, port, folder: Path, profile: Path | None = None,
                keys=None, floor: bool = False, echo: str = "", phases: bool = False,
                no_chain: bool = False):
    """serve in its own process on the transport of driver class `kind`, `keys` set in its
    transport's section of the live file (`floor`: with FLOOR_SERVE's per-message work;
    `echo`: transport_echo.py in its place, with that delivery; `phases`: its phases timed,
    written to `folder`/phases.json at its exit; `no_chain`: without the chain's update);
    returns the process and the s it took to listen."""
    import yaml

    save_model(model, folder / "model.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    live = {"chain": {"sensor": {"rate_hz": float(rate)}}, **kind.live_section(names)}
    for section in live.values():
        if "sensor_timeout_s" in section:  # the transport's
            section.update(keys or {})
    (folder / "live.yaml").write_text(yaml.safe_dump(live))
    err_path = folder / "serve.err"
    with open(err_path, "w") as err:
        serve = subprocess.Popen(
            echo_command(kind, port, keys or {}, echo, folder / "model.ftd") if echo else
            [sys.executable, *(["-m", "cProfile", "-o", profile] if profile else []),
             *(["-c", FLOOR_SERVE] if floor else ["-c", PHASES_SERVE] if phases
               else ["-c", NO_CHAIN_SERVE] if no_chain else ["-m", "ftdrake"]), "serve",
             *kind.flags(port), "--model",
             folder / "model.ftd", "--config", folder / "live.yaml"],
            stdout=subprocess.PIPE, stderr=err, text=True,
            env={**os.environ, "FTDRAKE_PHASES_FILE": str(folder / "phases.json")}
            if phases else None)
    started = time.monotonic()
    while "out: " not in err_path.read_text():
        if serve.poll() is not None:
            raise RuntimeError(err_path.read_text())
        time.sleep(0.01)
        if time.monotonic() - started > 60:
            raise RuntimeError("serve did not start in 60 s")
    return serve, time.monotonic() - started


def echo_command(kind, port, keys: dict, delivery: str, model: Path) -> list:
    """transport_echo.py's command line on the transport of driver class `kind` (`model`:
    the chain's, for the ``chain`` delivery)."""
    script = str(Path(__file__).resolve().parent / "transport_echo.py")
    if kind is LcmDriver:
        return [sys.executable, script, "lcm", kind.flags(port)[1],
                *([keys["output_url"]] if "output_url" in keys else [])]
    del model  # the echo has no chain
    return [sys.executable, script, "ros2", str(DOMAIN), delivery]


def cpu_list(text: str) -> str:
    """An option's CPU ids, e.g. ``1`` or ``0,1`` ("": none; argparse's type: a clear
    error)."""
    try:
        [int(cpu) for cpu in text.split(",") if text]
    except ValueError:
        raise argparse.ArgumentTypeError(f"CPU ids separated by commas, e.g. 1 or 0,1; got "
                                         f"{text!r}") from None
    return text


def serve_keys(args, kind, port) -> dict:
    """The keys of serve's transport section the options set."""
    keys = {"batch_period_s": float(args.batch_period),
            "yield_io_threads": not args.no_yield_io_threads}
    if args.outputs:
        keys["outputs"] = args.outputs.split(",")
    if args.separate_outputs and kind is LcmDriver:
        keys["output_url"] = kind.output_url(port)
    if args.cpu_affinity:
        keys["cpu_affinity"] = [int(cpu) for cpu in args.cpu_affinity.split(",")]
    if args.python_path or args.phases or args.no_chain:  # those time or alter Python's
        keys["compiled_path"] = False
    return keys


def start_driver(kind, names, port, separate_outputs: bool = False):
    """The driver, once DDS discovery matched it with serve both ways (LCM: at once);
    returns it and when it was made (its topics appeared then)."""
    appeared = time.monotonic()
    driver = kind(port, separate_outputs=separate_outputs) if kind is LcmDriver else kind(names)
    while not driver.ready():
        driver.poll(10)
        if time.monotonic() - appeared > 60:
            raise RuntimeError("DDS discovery did not complete in 60 s")
    return driver, appeared


def drive(driver, serve, rate, data, args, perf_data: Path | None = None) -> dict:
    """Sends the messages paced by the wall clock; returns what was sent and measured (with
    `perf_data`, serve's CPU by library over the timed messages: cpu_by_library.py)."""
    period = 1.0 / rate
    warmup = round(args.warmup * rate)
    count = warmup + round(args.seconds * rate)
    q, v, w = resampled(*data, rate, count)
    burst = args.burst if rate >= args.burst_at else 1
    sent, load_before = {}, os.getloadavg()[0]
    start = time.perf_counter()
    cpu_start, main_start, recorder = cpu_s(serve.pid), main_thread_cpu_s(serve.pid), None
    per_second, second = [], round(rate)  # serve's CPU µs per message, each second
    first_sent = time.monotonic()
    for k in range(count):
        if k % burst == 0:  # the driver sleeps until the batch is due, handling outputs
            due = start + (k + burst - 1) * period
            while (now := time.perf_counter()) < due:
                driver.wait(due - now)
        if k == warmup:
            cpu_start, main_start, recorder = timed_part_starts(serve, args, perf_data)
            mark = cpu_start
        elif k > warmup and (k - warmup) % second == 0:
            cpu = cpu_s(serve.pid)
            per_second.append((cpu - mark) / second * 1e6)
            mark = cpu
        t = (k + 1) * period
        if k >= warmup:
            sent[round(t * 1e6)] = time.monotonic()
        driver.send(t, q[k], v[k], w[k], joint=k % args.joint_every == 0)
        driver.poll(0)
    if recorder is not None:
        cpu_by_library.stop(recorder)
    end = time.monotonic() + 10
    while len(driver.back) < count and time.monotonic() < end:
        driver.poll(10)
    return {"count": count, "timed": count - warmup, "sent": sent, "first_sent": first_sent,
            "per_second_us": per_second,
            "cpu_s": cpu_s(serve.pid) - cpu_start,
            "main_cpu_s": main_thread_cpu_s(serve.pid) - main_start, "load_before": load_before,
            "load_after": os.getloadavg()[0],
            "cpu_by_library": cpu_by_library.shares(perf_data) if perf_data else None}


def timed_part_starts(serve, args, perf_data: Path | None):
    """At the end of the warm-up: serve's process and main-thread CPU times (s), and perf
    sampling serve from now on (None without `perf_data`); serve_phases' sums start now."""
    if args.phases:
        serve.send_signal(signal.SIGUSR1)
    recorder = cpu_by_library.start(serve.pid, perf_data) if perf_data is not None else None
    return cpu_s(serve.pid), main_thread_cpu_s(serve.pid), recorder


def run_one(model, name, rate, data, names, args, folder: Path) -> dict:
    """serve started and listening first; then the driver (its topics appear), which sends
    as soon as DDS discovery matched."""
    kind = Ros2Driver if args.transport == "ros2" else LcmDriver
    port = 7700 + os.getpid() % 200
    serve = driver = None
    everywhere = usable_cpus()
    try:
        profile = (Path(args.profile) / f"serve-{args.transport}-{rate:g}-{name}.prof"
                   if args.profile else None)
        serve, serve_start_s = start_serve(model, rate, kind, names, port, folder, profile,
                                           serve_keys(args, kind, port), args.floor,
                                           args.echo, args.phases, args.no_chain)
        if args.driver_cpus:  # serve started on every CPU; the driver's threads inherit this
            pin_process({int(cpu) for cpu in args.driver_cpus.split(",")})
        driver, appeared = start_driver(kind, names, port, args.separate_outputs)
        run = drive(driver, serve, rate, data, args,
                    Path(args.perf) / f"serve-{args.transport}-{rate:g}-{name}.perf.data"
                    if args.perf else None)
        serve.send_signal(signal.SIGINT)
        out, _ = serve.communicate(timeout=60)
    finally:
        if serve is not None and serve.poll() is None:
            serve.kill()
        if driver is not None:
            driver.close()
        if args.driver_cpus:  # the next serve starts on every CPU
            pin_process(everywhere)
    if args.keep_logs:  # serve's console: its header, warnings and fault events
        Path(args.keep_logs).mkdir(parents=True, exist_ok=True)
        shutil.copy(folder / "serve.err",
                    Path(args.keep_logs) / f"serve-{args.transport}-{rate:g}-{name}.err")
    summary = json.loads(out.strip().splitlines()[-1])
    sent = run["sent"]
    trip = np.array([driver.back[key] - sent[key] for key in sent if key in driver.back]) * 1e3
    trip = trip if len(trip) else np.array([np.nan])
    flags = np.array(driver.contacts, dtype=bool)
    episodes = int(np.count_nonzero(flags[1:] & ~flags[:-1]) + bool(len(flags) and flags[0]))
    load = summary.get("load", {})
    return {"sent": run["count"], "received": summary["received"].get("ft", 0),
            "processed": summary["processed"], "published": summary["published_wrench"],
            "lost": run["count"] - summary["processed"], "dropped": load.get("dropped_ft"),
            "lost_by_stamps": load.get("lost_ft"),
            "cpu_us_per_msg": run["cpu_s"] / run["timed"] * 1e6,
            "cpu_us_per_msg_median": (float(np.median(run["per_second_us"]))
                                      if run["per_second_us"] else None),
            "main_thread_cpu_us_per_msg": run["main_cpu_s"] / run["timed"] * 1e6,
            # serve's own figure (its summary's, over its whole loop, warm-up included).
            "serve_cpu_us_per_msg": summary.get("cpu", {}).get("us_per_message"),
            "p50_ms": summary["latency_ms"]["p50"], "p99_ms": summary["latency_ms"]["p99"],
            "e2e_p50_ms": float(np.percentile(trip, 50)),
            "e2e_p99_ms": float(np.percentile(trip, 99)),
            "e2e_p999_ms": float(np.percentile(trip, 99.9)),
            "false_contacts": episodes, "sustained_hz": load.get("sustained_hz"),
            "serve_start_s": serve_start_s,
            "first_output_s": (min(driver.back.values()) - appeared if driver.back
                               else None),
            "first_sent_s": run["first_sent"] - appeared, "load_core": int(args.load_core),
            "batch_period_s": args.batch_period, "joint_every": args.joint_every,
            # Where samples received but not processed went (serve's summary).
            "rejected": summary.get("rejected", {}),
            "fault_episodes": summary.get("fault_episodes", {}),
            # What serve warned of (e.g. little headroom), as its summary gives it.
            "warnings": summary.get("warnings", []),
            "yield_io_threads": int(not args.no_yield_io_threads),
            "separate_outputs": int(args.separate_outputs and kind is LcmDriver),
            "floor": int(args.floor), "no_chain": int(args.no_chain), "echo": args.echo,
            # ROS 2: whether serve's compiled per-message path ran, the messages it handled
            # and those it handed to the Python path (serve's summary).
            "compiled_path": summary.get("compiled_path"),
            "cpu_affinity": args.cpu_affinity, "driver_cpus": args.driver_cpus,
            "phases": (json.loads((folder / "phases.json").read_text()) if args.phases
                       else None),
            "load_before": run["load_before"], "load_after": run["load_after"],
            "cpu_by_library": run["cpu_by_library"]}


def refuse_combinations(parser, args) -> None:
    """parser.error for options that cannot run together (or a bad value)."""
    if args.joint_every < 1:
        parser.error("--joint-every: a whole number ≥ 1 (1: a joint state with every wrench)")
    if args.perf and args.profile:
        parser.error("--perf and --profile: perf would sample cProfile's own work")
    if args.floor and args.profile:
        parser.error("--floor and --profile: cProfile cannot run serve's floor (python -c)")
    if args.phases and (args.floor or args.profile or args.echo):
        parser.error("--phases times serve's own methods: not with --floor, --profile or "
                     "--echo")
    if args.no_chain and (args.floor or args.profile or args.phases):
        parser.error("--no-chain runs serve without the chain's update: not with --floor "
                     "(which has none either), --profile or --phases")
    ignored = [flag for flag, value in (
        ("--floor", args.floor), ("--no-chain", args.no_chain), ("--profile", args.profile),
        ("--outputs", args.outputs),
        ("--cpu-affinity", args.cpu_affinity), ("--batch-period", args.batch_period),
        ("--no-yield-io-threads", args.no_yield_io_threads)) if value]
    if args.echo and ignored:
        parser.error(f"--echo replaces serve (two outputs, receive threads yielding): "
                     f"{', '.join(ignored)} would be ignored")
    if args.echo in ("listener", "compiled") and args.transport != "ros2":
        parser.error(f"--echo {args.echo}: a Cyclone DDS delivery, only with --transport ros2")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--transport", choices=("ros2", "lcm"), default="ros2")
    parser.add_argument("--rates", default="500,1000,2000,4000", help="Hz, comma-separated")
    parser.add_argument("--seconds", type=float, default=60.0, help="s per rate and model")
    parser.add_argument("--warmup", type=float, default=1.0,
                        help="s of messages first, not timed (serve compiles on them)")
    parser.add_argument("--models", default="physics,hybrid")
    parser.add_argument("--train-s", type=float, default=20.0, help="simulated training s")
    parser.add_argument("--burst", type=int, default=16, help="samples per batch at high rates")
    parser.add_argument("--burst-at", type=float, default=4000.0,
                        help="rates from this one up are sent in batches of --burst")
    parser.add_argument("--outputs", default="",
                        help="serve's outputs (comma-separated; default: all); the driver "
                             "reads wrench_contact and contact")
    parser.add_argument("--batch-period", type=float, default=0.0,
                        help="serve's batch_period_s (s between its wake-ups; 0: per message)")
    parser.add_argument("--separate-outputs", action="store_true",
                        help="LCM: serve publishes on its own URL (output_url), the driver "
                             "reads there")
    parser.add_argument("--no-yield-io-threads", action="store_true",
                        help="serve's yield_io_threads false (its receive threads at the "
                             "default policy)")
    parser.add_argument("--cpu-affinity", default="", type=cpu_list,
                        help="serve's cpu_affinity: CPUs for all its threads, e.g. 1")
    parser.add_argument("--driver-cpus", default="", type=cpu_list,
                        help="CPUs this process (the driver) keeps to, e.g. 0 (default: the "
                             "scheduler's choice)")
    parser.add_argument("--load-core", action="store_true",
                        help="a second process keeps one core busy during the runs")
    parser.add_argument("--floor", action="store_true",
                        help="serve without its per-message work (FLOOR_SERVE): the "
                             "transport's own CPU per message at these settings")
    parser.add_argument("--no-chain", action="store_true",
                        help="serve as always but for the chain's update (chain_held.py): "
                             "what the update costs live, by difference")
    parser.add_argument("--echo", nargs="?", const="wait", default="",
                        choices=("wait", "listener", "compiled"),
                        help="transport_echo.py in serve's place: the least a Python process "
                             "does per message on the transport (ROS 2: 'listener' takes "
                             "each message on Cyclone's receive thread; 'compiled' runs the "
                             "loop compiled, compiled_echo.py)")
    parser.add_argument("--keep-logs", metavar="DIR",
                        help="copy each run's serve console (stderr) into DIR")
    parser.add_argument("--python-path", action="store_true",
                        help="serve with compiled_path false (every message in Python), to "
                             "compare with its compiled path")
    parser.add_argument("--phases", action="store_true",
                        help="serve's main thread split by phase (serve_phases.py), µs per "
                             "F/T message")
    parser.add_argument("--joint-every", type=int, default=1, metavar="N",
                        help="a joint state with every N-th wrench only (a joint stream at "
                             "rate / N, as a 500 Hz /joint_states beside a 1 kHz sensor)")
    parser.add_argument("--profile", metavar="DIR",
                        help="run serve under cProfile, its statistics in DIR (slower)")
    parser.add_argument("--perf", metavar="DIR",
                        help="sample serve with Linux perf over the timed messages, its files "
                             "in DIR: serve's CPU by library (cpu_by_library.py)")
    args = parser.parse_args()
    refuse_combinations(parser, args)
    if args.perf:
        cpu_by_library.require_perf()
        Path(args.perf).mkdir(parents=True, exist_ok=True)
    _, X, W, station = free_motion(args.train_s, seed=0)
    replay = free_motion(max(10.0, args.train_s / 2), seed=1)[:3]
    from ftdrake.sim.ros2_publisher import arm_joint_names

    names = arm_joint_names(station)
    robot = RobotOptions(robot="ftdrake")
    makers = {
        "physics": lambda: make_estimator("physics", robot=robot,
                                          target_names=[f"meas_{a}" for a in WRENCH_AXES]),
        "hybrid": lambda: make_estimator("hybrid", robot=robot,
                                         target_names=[f"meas_{a}" for a in WRENCH_AXES]),
    }
    busy = (subprocess.Popen([sys.executable, "-c", "while True: pass"]) if args.load_core
            else None)
    try:
        results = run_all(args, makers, X, W, replay, names)
    finally:
        if busy is not None:
            busy.kill()
            busy.wait()
    print(json.dumps(results))


def run_all(args, makers, X, W, replay, names) -> dict:
    """Every model at every rate: {rate: {model: row}}, each row printed as it comes."""
    results, costs = {}, {}
    for name in args.models.split(","):
        model = makers[name]().fit(X, W)
        costs[name] = compensator_us(model, replay[1])
        for rate in (float(r) for r in args.rates.split(",")):
            with tempfile.TemporaryDirectory() as folder:
                row = run_one(model, name, rate, replay, names, args, Path(folder))
            row["compensator_us"] = costs[name]
            row["cpu_ratio_to_compensator"] = row["cpu_us_per_msg"] / costs[name]
            results.setdefault(f"{rate:g}", {})[name] = row
            what = ("FLOOR " * args.floor + "NO CHAIN " * args.no_chain
                    + "ECHO " * bool(args.echo) + "PYTHON PATH " * args.python_path)
            print(f"{args.transport} {rate:6.0f} Hz {name:<8} {what}"
                  f"sent {row['sent']:>7} received {row['received']:>7} "
                  f"processed {row['processed']:>7} "
                  f"published {row['published']:>7} lost {row['lost']:>6} "
                  f"cpu {row['cpu_us_per_msg']:7.1f} µs/msg (median of seconds "
                  f"{row['cpu_us_per_msg_median'] or float('nan'):.1f}) "
                  f"(main thread {row['main_thread_cpu_us_per_msg']:.1f}; serve's own "
                  f"{row['serve_cpu_us_per_msg'] or float('nan'):.1f}) "
                  f"({row['cpu_ratio_to_compensator']:.0f}× the compensator's "
                  f"{costs[name]:.1f} µs)  serve p50/p99 {row['p50_ms']:.3f}/"
                  f"{row['p99_ms']:.3f} ms  e2e p50/p99/p99.9 {row['e2e_p50_ms']:.2f}/"
                  f"{row['e2e_p99_ms']:.2f}/{row['e2e_p999_ms']:.2f} ms  false contacts "
                  f"{row['false_contacts']}  serve listening after {row['serve_start_s']:.2f} s, "
                  f"first output {row['first_output_s'] or float('nan'):.2f} s after the "
                  f"driver's topics appeared  load {row['load_before']:.2f}→"
                  f"{row['load_after']:.2f}  rejected {row['rejected'] or 'none'}  fault "
                  f"episodes {row['fault_episodes'] or 'none'}", flush=True)
            for warning in row["warnings"]:
                print(f"  serve warned: {warning}", flush=True)
            if row["compiled_path"]:
                print(f"  serve's compiled path: {row['compiled_path']}", flush=True)
            if row["cpu_by_library"]:
                print_by_library(row["cpu_by_library"], row["cpu_us_per_msg"])
            if row["phases"]:
                print("  phases, µs per F/T message: " + "  ".join(
                    f"{key} {value:.1f}" for key, value in row["phases"].items()
                    if key != "ft_messages"), flush=True)
    return results


def print_by_library(shares: dict, cpu_us_per_msg: float) -> None:
    """serve's CPU by library group: % of perf's samples and µs per message."""
    print(f"  CPU by library (perf, {shares['samples']} samples): " + ", ".join(
        f"{group} {share:.0f} % ({share / 100 * cpu_us_per_msg:.0f} µs)"
        for group, share in shares["groups"].items()), flush=True)


if __name__ == "__main__":
    main()
