"""CompiledPath: the ROS 2 station's per-message work done by the compiled loop
(:mod:`.loop`) whenever the station is in its ordinary state, by its Python path otherwise.

Why: about half of the Python path's CPU per message is the interpreter, spread over
decode, checks, chain update and encode; what each path costs is on the results page
(docs/results/live.md). The two paths share one state:
before each call the compiled loop gets the station's (the monitor's stamps, arrivals and
history, the load monitor's baseline, the counts) and after it the station gets it back,
with the counts, latencies and history the Python objects keep; the chain's arrays are the
ChainStep's own.

When the compiled loop is used (:attr:`CompiledPath.why_not` None), per spin
(:meth:`CompiledPath.ready`): the inputs fault-free, nothing settling, dropped or overloaded,
the F/T rate measured, both streams and the joint name list known, no recording, nothing
held by the node. Anything unusual in a message goes back to Python with what follows it
(:mod:`.loop`), so faults, warnings and events are the Python path's, unchanged. Not at all
(said at start): ``ros2.compiled_path: false``; Cyclone's C declarations do not hold
(:func:`.cyclone.self_test`); a station clock other than time.monotonic; a reorder window;
inputs beyond the joint states and wrenches (temperature, IMU, tare, payload topics); a
chain the compiled update does not cover (:func:`.chain.chain_problem`).
"""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

from ...overload import WINDOW
from . import cyclone
from .cdr import names_cdr
from .chain import chain_problem, step_arguments
from .loop import (
    F_SIZE,
    ITEMS,
    K_SIZE,
    RING,
    STOP_HEADROOM,
    TAKE,
    F,
    K,
    run,
)

#: s the compiled loop works per call before Python's periodic work (diagnostics, the
#: console, Ctrl-C) runs again; a stream silent past its timeout returns at once. Each call
#: costs the interpreter about as much as a few messages, so it is made long (the results
#: page has what a shorter one cost).
BUDGET_S = 0.05
#: bytes of the largest message the loop reads itself (larger ones go to Python).
MAX_MESSAGE = 65536
_SOURCES = {"wrench_compensated": 0, "wrench_contact": 1, "bias": 2, "contact": 3,
            "contact_force": 4}


class CompiledPath:
    """The compiled per-message path of a :class:`~ftdrake.hardware.ros2.station.Ros2Station`
    (see the module). `budget_s`: s per call (0: one pass over what has arrived, for
    ``batch_period_s``). Found in numba's cache, the loop is loaded here at once, before
    the station serves. Else, with `background`, it is compiled in a process of its own
    (:mod:`.warm`; a first start after an install) while the station's Python path
    serves, and loaded here once that is done; without, it is compiled here and now."""

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

    # -- whether ------------------------------------------------------------------------------
    def _problem(self) -> str | None:
        s, c = self.station, self.station.config
        if not c.compiled_path:
            return "ros2.compiled_path is false"
        if s.clock is not time.monotonic:
            return "the station's clock is not time.monotonic"
        if c.reorder_window_s > 0:
            return "ros2.reorder_window_s holds messages (> 0)"
        if len(s.node._handlers) != 2:
            return "the station reads topics beyond the joint states and wrenches"
        if s._step is None:
            return "the chain is driven through the Drake diagram"
        problem = chain_problem(s._step)
        if problem is not None:
            return problem
        loaded = cyclone.load()
        if isinstance(loaded, str):
            return loaded
        problem = cyclone.self_test(s.node.participant, loaded)
        if problem is not None:
            return f"Cyclone DDS's C declarations do not hold: {problem}"
        self._c = loaded
        return None

    def ready(self) -> bool:
        """Whether the loop is loaded and the station is in the state it handles (the
        module)."""
        if not self._loaded and not self._compiled_meanwhile():
            return False
        s = self.station
        m, load = s.monitor, s.load
        return not (m.fault or s._settling or s.node._pending or load.overloaded
                    or s.rate_check.measured_hz is None or s.recorder is not None
                    or m._joint_bad is not None or s._last_t is None or load._min_lag is None
                    or load._last_t is None or m._last_t["joint"] is None
                    or m._last_t["ft"] is None or s._order[1] is None or s._header is None
                    or (m.pair_tolerance_s > 0 and not m._history)
                    or self._outputs_for(s._header.frame_id) is None)

    # -- building -----------------------------------------------------------------------------
    def _build(self, background: bool) -> None:
        from cyclonedds.core import InstanceState, SampleState, ViewState  # noqa: PLC0415

        s = self.station
        step, n = s._step, s.n_joints
        readers = [reader for reader, *_ in s.node._handlers]
        self._handlers = {k: (kind, handler, read)
                          for k, (_, kind, handler, _, read) in enumerate(s.node._handlers)}
        self._readers = np.array([r._ref for r in readers], dtype=np.int32)
        self._mask = int(SampleState.Any | ViewState.Any | InstanceState.Any)
        self._f, self._k = np.zeros(F_SIZE), np.zeros(K_SIZE, dtype=np.int64)
        self._items = (np.zeros(ITEMS, dtype=np.uint64), np.zeros(ITEMS, dtype=np.int64),
                       np.zeros(ITEMS, dtype=np.int8))
        self._rings = (np.zeros(RING), np.zeros((RING, 2 * n)), np.zeros(RING),
                       np.zeros(RING), np.zeros(RING))
        self._take = (np.zeros(TAKE, dtype=np.uint64),
                      np.zeros(TAKE * cyclone.INFO_BYTES, dtype=np.uint8),
                      np.zeros(MAX_MESSAGE, dtype=np.uint8))
        self._buffers = (np.zeros(MAX_MESSAGE, dtype=np.uint8), np.zeros(2, dtype=np.uint64),
                         np.zeros(2, dtype=np.int64))
        self._scratch = np.zeros(8, dtype=np.uint8)
        self._chain = step_arguments(step)
        outputs = step.outputs
        self._chain_out = (outputs["wrench_compensated"], outputs["wrench_contact"],
                           outputs.get("bias", np.zeros(6)), outputs["contact"],
                           outputs["contact_force"],
                           outputs["fault"])
        self._names = (None, None)  # (names list, (CDR bytes, order, values scratch))
        self._frames: dict[str, tuple | None] = {}
        self._limit = np.asarray(s.joint_bounds.limit, dtype=float)
        self._x_new = np.zeros(2 * n)
        self._wrench_new = np.zeros(6)
        self._sertypes = {}
        self._started = time.monotonic()
        self._pack(self._f, self._k, 0.0, dry=True)
        arguments = self._arguments(dry=True)
        if background and not _in_cache(self._c, arguments) and _survives_pickling(arguments):
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
        """:mod:`.warm` in a process of its own, on the dry call's arguments (pickled)."""
        self._folder = tempfile.mkdtemp(prefix="ftdrake_compile_")
        path = os.path.join(self._folder, "arguments.pkl")
        with open(path, "wb") as f:
            pickle.dump(arguments, f)
        self._child_err = open(os.path.join(self._folder, "stderr"), "w+b")  # noqa: SIM115
        self._child = subprocess.Popen(
            [sys.executable, "-m", "ftdrake.hardware.ros2.fast.warm", path],
            stdout=subprocess.DEVNULL, stderr=self._child_err)

    def _compiled_meanwhile(self) -> bool:
        """Whether the process compiling the loop is done; then the loop is loaded here
        (from the cache it wrote), or, when that process failed, the Python path kept and
        said why."""
        if self._child is None or self._child.poll() is None:
            return False
        code, self._child = self._child.returncode, None
        self._child_err.seek(0)
        err = self._child_err.read().decode(errors="replace").strip().splitlines()
        self._child_err.close()
        shutil.rmtree(self._folder, ignore_errors=True)
        if code != 0:
            self.why_not = (f"compiling it failed (exit {code}: "
                            f"{err[-1] if err else 'no message'})")
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
        """Stops a compile still running."""
        if self._child is not None:
            self._child.kill()
            self._child.wait()
            self._child = None
            self._child_err.close()
            shutil.rmtree(self._folder, ignore_errors=True)

    def _outputs_for(self, frame_id: str):
        """(expected frame bytes, the outputs tuple) for wrenches in `frame_id`; None when a
        writer cannot write them packed (then the Python path writes them)."""
        if frame_id in self._frames:
            return self._frames[frame_id]
        s = self.station
        writers, sertypes, heads, sources = [], [], [], []
        for name, out in s._wrench_out:
            packing = out._struct(frame_id)
            if packing is None:
                self._frames[frame_id] = None
                return None
            writers.append(out.writer)
            heads.append(np.frombuffer(packing[1], dtype=np.uint8))
            sources.append(_SOURCES[name])
        for name, out in s._value_out.items():
            if not out.packed:
                self._frames[frame_id] = None
                return None
            writers.append(out.writer)
            heads.append(np.frombuffer(out._head, dtype=np.uint8))
            sources.append(_SOURCES[name])
        for writer in writers:
            if writer._ref not in self._sertypes:
                self._sertypes[writer._ref] = cyclone.sertype_of(writer._ref)
            sertypes.append(self._sertypes[writer._ref])
        frame = np.frombuffer(frame_id.encode("utf-8") + b"\0", dtype=np.uint8).copy()
        found = (frame, (np.array([w._ref for w in writers], dtype=np.int32),
                  np.array(sertypes, dtype=np.uint64),
                  np.array(heads, dtype=np.uint8).reshape(len(heads), 4),
                  np.array(sources, dtype=np.int64), bool(s._value_out)))
        self._frames[frame_id] = found
        return found

    def _names_for(self):
        names, order = self.station._order
        if self._names[0] is not names:
            self._names = (names, (names_cdr(names), np.asarray(order, dtype=np.int64),
                                   np.zeros(len(names))))
        return self._names[1]

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
        a time), then what it handed back through the node's Python path; the messages
        handled."""
        before = self._handled()
        self._spin(timeout_s=timeout_ms / 1e3)
        handed = self._hand_back()
        extra = self.station.node.spin(0) if handed else 0
        return self._handled() - before + extra

    def _handled(self) -> int:
        m = self.station.monitor
        return m.received["joint"] + m.received["ft"]

    def _spin(self, timeout_s: float = 0.0, dry: bool = False) -> None:
        self._pack(self._f, self._k, timeout_s, dry)
        run(self._c, *self._arguments(dry))
        if not dry:
            self.calls += 1
            self._unpack(self._f, self._k)

    def _arguments(self, dry: bool) -> tuple:
        """:func:`.loop.run`'s arguments after the C functions."""
        s = self.station
        frame, outputs = self._outputs_for("" if dry else s._header.frame_id)
        names, order, values = self._names_for_or_dummy(dry)
        joint = (names, order, self._x_new, values, self._limit, self._scratch,
                 s.monitor.joint_state)
        ft = (frame, self._wrench_new, self._scratch, s.monitor.wrench, s.monitor.joint_state,
              s._step._wrench, s._step._joint_state, self._chain_out)
        return (s.node._waitset._ref, self._readers, self._mask, self._items, self._f,
                self._k, joint, ft, self._rings, self._chain, outputs, self._buffers,
                self._take)

    def _names_for_or_dummy(self, dry: bool):
        if dry:
            return (np.zeros(4, dtype=np.uint8), np.arange(self.station.n_joints),
                    np.zeros(self.station.n_joints))
        return self._names_for()

    def _pack(self, f, k, timeout_s: float, dry: bool) -> None:
        s = self.station
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

    def _unpack(self, f, k) -> None:
        s = self.station
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
            from cyclonedds.core import DDSException  # noqa: PLC0415 (ROS 2 only)

            raise DDSException(-1, f"{int(k[K['errors']])} writes of the station's outputs "
                               "failed in the compiled loop")
        load._until_headroom_check = int(k[K["until_headroom"]])
        if k[K["stop"]] == STOP_HEADROOM or load._until_headroom_check <= 0:
            load._until_headroom_check = WINDOW
            if not load.headroom_warned:
                s.warn(load._headroom_warning())

    def _hand_back(self) -> int:
        """The samples the loop left (still referenced): their bytes read into the node's
        pending list, in order, as its own take would have; how many."""
        count = int(self._k[K["handback"]])
        if not count:
            return 0
        c, node = self._c, self.station.node
        ptrs, stamps, streams = self._items
        now = time.monotonic()
        for i in range(count):
            pointer = int(ptrs[i])
            size = c.serdata_size(pointer)
            data = bytearray(size)
            c.serdata_to_ser(pointer, 0, size, (np.frombuffer(data, dtype=np.uint8)
                                                .ctypes.data))
            c.serdata_unref(pointer)
            kind, handler, read = self._handlers[int(streams[i])]
            node.hold(int(stamps[i]), bytes(data), kind, handler, read, now)
        self.handed_back += count
        return count



def _numba_types(value):
    if isinstance(value, tuple):
        return tuple(_numba_types(v) for v in value)
    return numba.typeof(value)


def _survives_pickling(arguments) -> bool:
    """Whether `arguments` have the same numba types after a pickle round trip (a
    non-contiguous or read-only array would not: the process compiling them would then
    compile another signature than this one loads)."""
    return _numba_types(pickle.loads(pickle.dumps(arguments))) == _numba_types(arguments)


def _in_cache(c, arguments) -> bool:
    """Whether numba's on-disk cache holds the loop for these arguments' types (then it
    is loaded before the station serves, not by a pause of the stream later). Asks the
    dispatcher's cache as its own compile() does; False if numba's internals moved (the
    loop is then compiled or loaded in the background)."""
    try:
        signature = tuple(run.typeof_pyval(a) for a in (c, *arguments))
        return run._cache.load_overload(signature, run.targetctx) is not None
    except (AttributeError, TypeError):
        return False
