"""The compiled per-message path's Python side, shared by the transports: whether it may run,
its state crossing to and from the station's Python objects, its start and its summary.

Why: about half of the Python path's CPU per message is the interpreter, spread over
decode, checks, chain update and encode; what each path costs is on the results page
(docs/results/live.md). The two paths share one state:
before each call the compiled loop gets the station's (the monitor's stamps, arrivals and
history, the load monitor's baseline, the counts) and after it the station gets it back,
with the counts, latencies and history the Python objects keep; the chain's arrays are the
ChainStep's own.

When the compiled loop is used (:attr:`CompiledPathBase.why_not` None), per spin
(:meth:`CompiledPathBase.ready`): the inputs fault-free, nothing settling, dropped or
overloaded, the F/T rate measured, both streams known, no recording, and what the transport
adds. Anything unusual in a message goes back to Python with what follows it, so faults,
warnings and events are the Python path's, unchanged. Not at all (said at start): the
transport's ``compiled_path: false``; its C declarations do not hold; a station clock other
than time.monotonic; inputs beyond the joint states and wrenches (temperature, IMU, events);
a chain the compiled update does not cover (:func:`.chain.chain_problem`); what the
transport adds.

A transport's path (``ftdrake.hardware.ros2.fast.path``, ``ftdrake.hardware.lcm.fast.path``)
subclasses :class:`CompiledPathBase`: it loads its C functions, builds its own arguments of
its loop, reads the messages its loop hands back into the station's Python path, and names
the module (``WARM_MODULE``, with a ``warm(arguments)`` function) that compiles its loop in a
process of its own.
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from typing import ClassVar

import numba
import numpy as np

from ..overload import WINDOW
from .accept import F_SIZE, K_SIZE, RING, STOP_HEADROOM, F, K
from .chain import chain_problem, step_arguments

#: s the compiled loop works per call before Python's periodic work (diagnostics, the
#: console, Ctrl-C) runs again; a stream silent past its timeout returns at once. Each call
#: costs the interpreter about as much as a few messages, so it is made long (the results
#: page has what a shorter one cost).
BUDGET_S = 0.05


class CompiledPathBase:
    """The compiled per-message path of a station (see the module). `budget_s`: s per call
    (0: one pass over what has arrived, for ``batch_period_s``). Found in numba's cache, the
    loop is loaded here at once, before the station serves. Else, with `background`, it is
    compiled in a process of its own (``WARM_MODULE``; a first start after an install)
    while the station's Python path serves, and loaded here once that is done; without, it
    is compiled here and now."""

    #: The transport's config section (its ``compiled_path`` key is named in why_not).
    SECTION = ""
    #: The module whose ``warm(arguments)`` compiles the loop, run as ``fast.warm``'s child.
    WARM_MODULE = ""
    #: The compiled loop (``staticmethod(run)``), called with the C functions and
    #: :meth:`_arguments`.
    _loop = None

    def __init__(self, station, budget_s: float = BUDGET_S, background: bool = True):
        self.station = station
        self.budget_s = float(budget_s)
        self.calls = self.handed_back = self.loop_messages = 0
        self.compile_s = None  # s from start until the loop was loaded (None: not yet)
        self.load_s = None  # s the load took in this process
        self.on_ready = None  # called with this path once the loop is loaded
        self._child = None
        self._loaded = False
        self.why_not = self._problem()
        if self.why_not is None:
            self._build(background)

    # -- what a transport implements ------------------------------------------------------------
    def _transport_problem(self) -> str | None:
        """Why the transport's loop cannot run for this station (its C functions loaded and
        checked here), or None."""
        raise NotImplementedError

    def _transport_ready(self) -> bool:
        """Whether the transport's own state lets the loop run now."""
        raise NotImplementedError

    def _build_transport(self) -> None:
        """The transport's arrays and handles, before the dry call."""
        raise NotImplementedError

    def _arguments(self, dry: bool) -> tuple:
        """The loop's arguments after its C functions (``self._c``)."""
        raise NotImplementedError

    def _hand_back(self) -> int:
        """What the loop left, through the station's Python path; the messages that path
        handled."""
        raise NotImplementedError

    def _write_failed(self, count: int) -> None:
        """Raises the transport's error for `count` writes that failed in the loop."""
        raise NotImplementedError

    # -- whether ------------------------------------------------------------------------------
    def _problem(self) -> str | None:
        s = self.station
        if not s.config.compiled_path:
            return f"{self.SECTION}.compiled_path is false"
        if s.clock is not time.monotonic:
            return "the station's clock is not time.monotonic"
        if s._step is None:
            return "the chain is driven through the Drake diagram"
        if s._temperature_in is not None or s.imu is not None or s._signals:
            return "the station reads inputs beyond the joint states and wrenches"
        problem = chain_problem(s._step)
        if problem is not None:
            return problem
        return self._transport_problem()

    def ready(self) -> bool:
        """Whether the loop is loaded and the station is in the state it handles (the
        module)."""
        s = self.station
        if s._step is None:  # use_diagram() since: the diagram is the reference, in Python
            self.why_not = "the chain is driven through the Drake diagram"
            return False
        if not self._loaded and not self._compiled_meanwhile():
            return False
        m, load = s.monitor, s.load
        return not (m.fault or s._settling or load.overloaded
                    or s.rate_check.measured_hz is None or s.recorder is not None
                    or m._joint_bad is not None or s._last_t is None or load._min_lag is None
                    or load._last_t is None or m._last_t["joint"] is None
                    or m._last_t["ft"] is None
                    or (m.pair_tolerance_s > 0 and not m._history)) and self._transport_ready()

    # -- building -----------------------------------------------------------------------------
    def _build(self, background: bool) -> None:
        s = self.station
        step, n = s._step, s.n_joints
        self._f, self._k = np.zeros(F_SIZE), np.zeros(K_SIZE, dtype=np.int64)
        self._rings = (np.zeros(RING), np.zeros((RING, 2 * n)), np.zeros(RING),
                       np.zeros(RING), np.zeros(RING))
        self._scratch = np.zeros(8, dtype=np.uint8)
        self._spec = np.zeros(2, dtype=np.int64)
        self._chain = step_arguments(step)
        outputs = step.outputs
        zero = np.zeros(1)
        # The chain's outputs the loops publish, in this order (the loops index them).
        self._chain_out = (outputs["wrench_compensated"], outputs["wrench_contact"],
                           outputs.get("bias", np.zeros(6)), outputs["contact"],
                           outputs["contact_force"], outputs["fault"],
                           outputs["out_of_domain"], outputs.get("payload_change", zero))
        self._limit = np.asarray(s.joint_bounds.limit, dtype=float)
        self._x_new = np.zeros(2 * n)
        self._wrench_new = np.zeros(6)
        self._started = time.monotonic()
        self._build_transport()
        self._pack(0.0, dry=True)
        arguments = self._arguments(dry=True)
        if (background and not _in_cache(self._loop, self._c, arguments)
                and _survives_pickling(arguments)):
            self._start_compiling(arguments)
        else:  # from numba's cache (tens of ms), or compiled here, before serving
            self._load()

    def _load(self) -> None:
        """The loop compiled, or loaded from numba's cache, in this process."""
        started = time.monotonic()
        self._spin(dry=True)
        self.load_s = time.monotonic() - started  # the station's messages wait this long
        self.compile_s = time.monotonic() - self._started
        self._loaded = True
        if self.on_ready is not None:
            self.on_ready(self)

    def _start_compiling(self, arguments) -> None:
        """``fast.warm`` in a process of its own on the dry call's arguments, or the one
        already compiling the same types (:class:`_Compile`)."""
        self._child = _Compile.of(self.WARM_MODULE, arguments)
        self._child.users += 1

    def _compiled_meanwhile(self) -> bool:
        """Whether the process compiling the loop is done; then the loop is loaded here
        (from the cache it wrote), or, when that process failed, the Python path kept and
        said why."""
        if self._child is None:
            return False
        result = self._child.poll()
        if result is None:
            return False
        self._child = None
        code, last_line = result
        if code != 0:
            self.why_not = f"compiling it failed (exit {code}: {last_line})"
            self.station.warn(f"the compiled per-message path is not used: {self.why_not}; "
                              "every message goes through the Python path")
            return False
        self._load()
        return True

    def wait(self, timeout_s: float = 300.0) -> bool:
        """Blocks until the loop is loaded (or compiling it failed); whether it is."""
        end = time.monotonic() + timeout_s
        while self._child is not None and time.monotonic() < end:
            if self._compiled_meanwhile():
                break
            time.sleep(0.05)
        return self._loaded

    def close(self) -> None:
        """Stops a compile still running that no other path waits for."""
        if self._child is not None:
            self._child.users -= 1
            if self._child.users <= 0:
                self._child.kill()
            self._child = None

    def summary(self) -> dict:
        """``used`` (whether the compiled loop runs when the station is in its ordinary
        state), ``why_not`` (None, or why not), ``ready_after_s`` (s from the station's
        start until the loop was loaded; None: not yet), ``load_s`` (s its load took in
        this process: the messages waited that long), ``calls``, ``messages`` (those it
        handled) and ``handed_back`` (those it gave to the Python path)."""
        return {"used": self.why_not is None, "why_not": self.why_not,
                "ready_after_s": self.compile_s, "load_s": self.load_s, "calls": self.calls,
                "messages": self.loop_messages, "handed_back": self.handed_back}

    # -- running ------------------------------------------------------------------------------
    def spin(self, timeout_ms: float) -> int:
        """One call of the compiled loop (up to `budget_s`, waiting at most `timeout_ms` at
        a time), then what it handed back through the station's Python path; the messages
        handled."""
        before = self._handled()
        self._spin(timeout_s=timeout_ms / 1e3)
        extra = self._hand_back()
        return self._handled() - before + extra

    def _handled(self) -> int:
        m = self.station.monitor
        return m.received["joint"] + m.received["ft"]

    def _spin(self, timeout_s: float = 0.0, dry: bool = False) -> None:
        self._pack(timeout_s, dry)
        self._loop(self._c, *self._arguments(dry))
        if not dry:
            self.calls += 1
            self._unpack()

    def _monitor_state(self):
        """The arrays the loop writes in place: the monitor's held joint state and wrench,
        and the step's wrench and joint-state inputs."""
        s = self.station
        return (s.monitor.joint_state, s.monitor.wrench, s._step._wrench, s._step._joint_state)

    def _pack(self, timeout_s: float, dry: bool) -> None:
        s, f, k = self.station, self._f, self._k
        m, load = s.monitor, s.load
        f[:] = 0.0
        k[:] = 0
        f[F["period"]], f[F["joint_timeout"]] = s.period, m.joint_state_timeout_s
        f[F["pair_tolerance"]], f[F["max_backlog"]] = m.pair_tolerance_s, load.max_backlog_s
        f[F["budget"]], f[F["wait"]] = self.budget_s, timeout_s
        f[F["sensor_timeout"]] = m.sensor_timeout_s
        k[K["dry"]] = dry
        if dry:
            return
        f[F["last_t_joint"]], f[F["last_arrival_joint"]] = m._last_t["joint"], \
            m._last_arrival["joint"]
        f[F["last_t_ft"]], f[F["last_arrival_ft"]] = m._last_t["ft"], m._last_arrival["ft"]
        f[F["core_last_t"]], f[F["load_last_t"]] = s._last_t, load._last_t
        f[F["min_lag"]], f[F["lag"]] = load._min_lag, load._lag
        f[F["backlog"]], f[F["max_backlog_seen"]] = load.backlog_s, load.max_backlog_seen_s
        f[F["pending_busy"]] = load._pending_busy
        k[K["processed"]], k[K["published"]] = s.processed, s.published
        k[K["contact_published"]] = s.contact_published
        k[K["until_headroom"]] = load._until_headroom_check
        history = m._history
        self._prefill = min(2, len(history)) if m.pair_tolerance_s > 0 else 0
        hist_t, hist_x = self._rings[0], self._rings[1]
        for i in range(self._prefill):
            t, x = history[len(history) - self._prefill + i]
            hist_t[i], hist_x[i] = t, x
        k[K["history"]] = self._prefill

    def _unpack(self) -> None:
        s, f, k = self.station, self._f, self._k
        m, load = s.monitor, s.load
        m._last_t["joint"], m._last_arrival["joint"] = (float(f[F["last_t_joint"]]),
                                                         float(f[F["last_arrival_joint"]]))
        m._last_t["ft"], m._last_arrival["ft"] = (float(f[F["last_t_ft"]]),
                                                   float(f[F["last_arrival_ft"]]))
        for stream, key in (("joint", "received_joint"), ("ft", "received_ft")):
            self.loop_messages += int(k[K[key]])
            if k[K[key]]:
                m.received[stream] += int(k[K[key]])
                m.accepted[stream] += int(k[K[key]])
        s._last_t, load._last_t = float(f[F["core_last_t"]]), float(f[F["load_last_t"]])
        load._min_lag, load._lag = float(f[F["min_lag"]]), float(f[F["lag"]])
        load.backlog_s, load.max_backlog_seen_s = (float(f[F["backlog"]]),
                                                   float(f[F["max_backlog_seen"]]))
        load._pending_busy = float(f[F["pending_busy"]])
        s.processed, s.published = int(k[K["processed"]]), int(k[K["published"]])
        s.contact_published = int(k[K["contact_published"]])
        hist_t, hist_x, latencies, busy, stamps = self._rings
        for i in range(self._prefill, int(k[K["history"]])):
            m._history.append((float(hist_t[i]), hist_x[i].copy()))
        s.latencies.extend(latencies[:k[K["latencies"]]].tolist())
        load._busy.extend(busy[:k[K["busy"]]].tolist())
        load._stamps.extend(stamps[:k[K["stamps"]]].tolist())
        if k[K["errors"]]:
            self._write_failed(int(k[K["errors"]]))
        load._until_headroom_check = int(k[K["until_headroom"]])
        if k[K["stop"]] == STOP_HEADROOM or load._until_headroom_check <= 0:
            load._until_headroom_check = WINDOW
            if not load.headroom_warned:
                s.warn(load._headroom_warning())


class _Compile:
    """One compile of a loop for one signature in a process of its own
    (``python -m ftdrake.hardware.fast.warm MODULE ARGUMENTS.pkl``), shared by the paths of
    one process that need it: a process that builds several stations of one kind (a test
    suite, a program with two sensors) starts one, not one per station."""

    running: ClassVar[dict] = {}  # (module, the arguments' numba types) → _Compile

    @classmethod
    def of(cls, module: str, arguments) -> _Compile:
        key = (module, _numba_types(arguments))
        found = cls.running.get(key)
        if found is None:
            found = cls.running[key] = cls(module, arguments, key)
        return found

    def __init__(self, module: str, arguments, key):
        self.key, self.users, self.result = key, 0, None
        self.folder = tempfile.mkdtemp(prefix="ftdrake_compile_")
        path = os.path.join(self.folder, "arguments.pkl")
        with open(path, "wb") as f:
            pickle.dump(arguments, f)
        self.err = open(os.path.join(self.folder, "stderr"), "w+b")  # noqa: SIM115
        self.child = subprocess.Popen(
            [sys.executable, "-m", "ftdrake.hardware.fast.warm", module, path],
            stdout=subprocess.DEVNULL, stderr=self.err)

    def poll(self) -> tuple[int, str] | None:
        """None while it runs; then (exit code, the last line it wrote to stderr)."""
        if self.result is None and self.child.poll() is not None:
            self.err.seek(0)
            lines = self.err.read().decode(errors="replace").strip().splitlines()
            self.result = (self.child.returncode, lines[-1] if lines else "no message")
            self._forget()
        return self.result

    def kill(self) -> None:
        if self.result is None:
            self.child.kill()
            self.child.wait()
            self.result = (self.child.returncode, "stopped")
            self._forget()

    def _forget(self) -> None:
        self.err.close()
        shutil.rmtree(self.folder, ignore_errors=True)
        if _Compile.running.get(self.key) is self:
            del _Compile.running[self.key]


def _numba_types(value):
    if isinstance(value, tuple):
        return tuple(_numba_types(v) for v in value)
    return numba.typeof(value)


def _survives_pickling(arguments) -> bool:
    """Whether `arguments` have the same numba types after a pickle round trip (a
    non-contiguous or read-only array would not: the process compiling them would then
    compile another signature than this one loads)."""
    return _numba_types(pickle.loads(pickle.dumps(arguments))) == _numba_types(arguments)


def _in_cache(loop, c, arguments) -> bool:
    """Whether numba's on-disk cache holds `loop` for these arguments' types (then it is
    loaded before the station serves, not by a pause of the stream later). Asks the
    dispatcher's cache as its own compile() does; False if numba's internals moved (the
    loop is then compiled or loaded in the background)."""
    try:
        signature = tuple(loop.typeof_pyval(a) for a in (c, *arguments))
        return loop._cache.load_overload(signature, loop.targetctx) is not None
    except (AttributeError, TypeError):
        return False
