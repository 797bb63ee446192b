"""LoadMonitor: whether the station keeps up with the F/T stream, said out loud.

Measured per F/T message, on any transport (the station's clock and the messages' stamps):

* ``lost``: messages missing by their stamps: a stamp gap of more than 1.5 configured periods
  counts the periods skipped (a network or a kernel buffer dropped them, or the driver
  skipped them; the station never saw them).
* ``backlog_s``: how far the station lags the stream: the message's lag (handled at − stamp)
  minus the smallest lag of a message run through the chain so far. A station that keeps up
  handles each message a constant time after its stamp; one that does not falls further
  behind with every message. (The
  driver's clock drifting against this machine's reads as a slow backlog, ≈ 1 ms per 10 s at
  100 ppm.)
* ``sustained_hz``: F/T messages per second of the station's busy time (the handlers of every
  stream, decode to publish), over the last :data:`WINDOW` F/T messages: the rate it can
  sustain on this machine now, an upper bound (the transport's own threads and the wait
  loop are not in it); ``input_hz`` the stream's rate by its stamps, as averaged.

**What is dropped when the input outruns the processing:** the oldest. While ``backlog_s``
exceeds `max_backlog_s`, F/T messages are counted as ``dropped`` and not run through the chain
(the inputs are faulted, reason ``overload``, naming both rates); skipping costs little, so the
station catches up with the newest messages, and processing resumes once it is less than half
`max_backlog_s` behind. Never the newest: a queue that fills up (LCM's per-subscription
capacity, a DDS reader's ``queue_depth``) would drop the messages still to come.

:class:`CpuMeter` says the headroom before that: the process's CPU time (every thread, the
transport's receive threads too) per processed F/T message and as a share of one core.
"""

from __future__ import annotations

import collections
import time

#: F/T messages the sustained rate and the input rate are averaged over.
WINDOW = 1000
#: The share of the stream's time the handlers may be busy before little headroom is said.
BUSY_WARNING = 0.8


class LoadMonitor:
    """See the module. `period`: the configured F/T period (s); `max_backlog_s`: the lag (s)
    beyond which the oldest messages are dropped; `levers`: the transport's settings that
    would lower the cost per message, in words naming their keys (:attr:`fix` starts with
    them)."""

    def __init__(self, period: float, max_backlog_s: float, levers: str = ""):
        self.period = float(period)
        self.max_backlog_s = float(max_backlog_s)
        self.levers = levers
        self.headroom_warned = False
        self._until_headroom_check = WINDOW
        self.lost = 0
        self.dropped = 0
        self.backlog_s = 0.0
        self.max_backlog_seen_s = 0.0
        self.overloaded = False
        self._min_lag = None
        self._lag = 0.0
        self._last_t = None
        self._busy = collections.deque(maxlen=WINDOW)  # s of handler time per F/T message
        self._pending_busy = 0.0  # handler time since the last F/T message (joint states …)
        self._stamps = collections.deque(maxlen=WINDOW)

    def busy(self, seconds: float) -> None:
        """Time a handler took (s), counted with the next F/T message."""
        self._pending_busy += max(0.0, seconds)

    def on_ft(self, t: float, handled_at: float) -> bool:
        """An F/T message stamped `t` (s), handled at `handled_at` (the station's clock, s).
        Returns True when it is to be dropped (the station is too far behind). A stamp
        not after the last one (out of order, or a restarted clock: the stream monitor says
        which) tells nothing of the backlog and is not dropped here (its lag, should it be
        processed, still counts for the baseline)."""
        self._lag = lag = handled_at - t
        if self._last_t is not None and t <= self._last_t:
            return False
        if self._last_t is not None:
            gap = round((t - self._last_t) / self.period)
            if (t - self._last_t) > 1.5 * self.period:
                self.lost += gap - 1
        self._last_t = t
        self._stamps.append(t)
        self.backlog_s = 0.0 if self._min_lag is None else max(0.0, lag - self._min_lag)
        self.max_backlog_seen_s = max(self.max_backlog_seen_s, self.backlog_s)
        if self.backlog_s > self.max_backlog_s:
            self.overloaded = True
        elif self.backlog_s < 0.5 * self.max_backlog_s:
            self.overloaded = False
        if self.overloaded:
            self.dropped += 1
        return self.overloaded

    def restart(self, t: float, handled_at: float) -> None:
        """The stream's clock restarted at the F/T message stamped `t`, handled at
        `handled_at`: its stamps and the lag baseline start again from it (the counts
        stay)."""
        self._last_t = self._min_lag = None
        self._stamps.clear()
        self.backlog_s, self.overloaded = 0.0, False
        self.on_ft(t, handled_at)

    def processed(self) -> str | None:
        """Closes the F/T message just run through the chain: its lag may lower the
        baseline (only such messages do: a faulted one, e.g. stamped far from the joint
        states, does not move it), and its handler time (and the handlers' since the
        previous one: joint states, dropped or faulted messages) enters the sustained
        rate. Returns the little-headroom warning (the module) the first time it applies,
        checked once per WINDOW processed messages; else None."""
        self._min_lag = self._lag if self._min_lag is None else min(self._min_lag, self._lag)
        self._busy.append(self._pending_busy)
        self._pending_busy = 0.0
        self._until_headroom_check -= 1
        if self._until_headroom_check:
            return None
        self._until_headroom_check = WINDOW
        return None if self.headroom_warned else self._headroom_warning()

    def _headroom_warning(self) -> str | None:
        """The warning when the handlers were busy more than BUSY_WARNING of the stream's
        time over the last WINDOW messages (once)."""
        sustained, rate_in = self.sustained_hz, self.input_hz
        if sustained is None or rate_in is None or sustained * BUSY_WARNING > rate_in:
            return None
        self.headroom_warned = True
        return (f"little headroom: F/T messages arrive at {rate_in:.0f} Hz and the station "
                f"sustains {sustained:.0f} Hz ({1e6 / sustained:.0f} µs per message on this "
                f"machine now), busy {100 * rate_in / sustained:.0f} % of the stream's time: "
                f"a burst or more load on this machine would make it drop messages. "
                f"{self.fix}")

    @property
    def fix(self) -> str:
        """What lowers the cost per message: the transport's unused settings first."""
        levers = f"{self.levers}; or " if self.levers else ""
        return f"Fix: {levers}a lighter model, a less loaded machine, or a lower driver rate"

    @property
    def sustained_hz(self) -> float | None:
        """F/T messages per second of busy time, over the last WINDOW (None: none yet)."""
        busy = sum(self._busy)
        return len(self._busy) / busy if busy > 0 else None

    @property
    def input_hz(self) -> float | None:
        """The F/T stream's rate by its stamps, over the last WINDOW messages."""
        if len(self._stamps) < 2 or self._stamps[-1] <= self._stamps[0]:
            return None
        return (len(self._stamps) - 1) / (self._stamps[-1] - self._stamps[0])

    def detail(self) -> str:
        """The overload in words: both rates, how far behind, what is dropped, the fix."""
        cost = 1e6 / self.sustained_hz if self.sustained_hz else float("nan")
        rate_in = f"{self.input_hz:.0f} Hz" if self.input_hz else "? Hz"
        sustained = f"{self.sustained_hz:.0f} Hz" if self.sustained_hz else "? Hz"
        return (f"overload: F/T messages arrive at {rate_in}, the station sustains "
                f"{sustained} ({cost:.0f} µs per message on this machine now) and is "
                f"{self.backlog_s * 1e3:.0f} ms behind the stream: the oldest are dropped "
                f"(not run through the chain) until it is less than "
                f"{0.5 * self.max_backlog_s * 1e3:.0f} ms behind. {self.fix}")

    def summary(self) -> dict:
        """The counts and rates (JSON-ready)."""
        return {"lost_ft": self.lost, "dropped_ft": self.dropped,
                "backlog_ms": self.backlog_s * 1e3,
                "max_backlog_ms": self.max_backlog_seen_s * 1e3,
                "sustained_hz": self.sustained_hz, "input_hz": self.input_hz,
                "overloaded": self.overloaded}


def cpu_use(cpu_s: float, wall_s: float, processed: int) -> dict:
    """The CPU over an interval: `cpu_s` s of the process's CPU time over `wall_s` s of wall
    time in which `processed` F/T messages were processed. ``core_percent``: % of one core
    (None for no wall time); ``us_per_message``: CPU µs per processed F/T message (None
    without one)."""
    return {"core_percent": 100.0 * cpu_s / wall_s if wall_s > 0 else None,
            "us_per_message": cpu_s / processed * 1e6 if processed > 0 else None}


class CpuMeter:
    """:func:`cpu_use` from one reading to the next. `now` (s, any wall clock) and
    `processed` (F/T messages processed so far) start it; `cpu_clock` gives the process's
    CPU time (s; default ``time.process_time``: every thread of the process). ``latest`` is
    the last reading (its values None before the first)."""

    def __init__(self, now: float, processed: int, cpu_clock=time.process_time):
        self.cpu_clock = cpu_clock
        self._start = (now, cpu_clock(), processed)
        self.latest = cpu_use(0.0, 0.0, 0)

    def reading(self, now: float, processed: int) -> dict:
        """:func:`cpu_use` since the last reading (or the start), at `now` with `processed`
        F/T messages processed so far; kept as ``latest``."""
        cpu = self.cpu_clock()
        then, cpu_then, processed_then = self._start
        self._start = (now, cpu, processed)
        self.latest = cpu_use(cpu - cpu_then, now - then, processed - processed_then)
        return self.latest
