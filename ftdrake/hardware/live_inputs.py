"""StreamMonitor: the checks between LCM messages and the compensator's inputs.

A plain class (the station's message callbacks call it once per received message), so that
it can be tested message by message; :class:`~ftdrake.hardware.station.HardwareStation` wraps
it.

What downstream sees: ``wrench`` (6) and ``joint_state`` (2n) are the last *accepted*
values; a rejected message never replaces them. ``fault`` is True from the first rejected
message or timeout until the inputs are good again:

* a rejected F/T message (NaN, time going back, duplicate, malformed) faults until the next
  accepted F/T message;
* a rejected joint-state message (wrong joint count, NaN, time going back, ...) faults until
  the next accepted joint-state message *and* then an accepted F/T message: the joint state
  held from before the bad message is stale, so no wrench is computed from it;
* a silent stream (``check_timeouts``) faults until its next accepted message;
* with `pair_tolerance_s` > 0, each F/T sample is paired with a joint state by their stamps:
  the newest joint state when its stamp is within the tolerance of the wrench's, else the
  nearest-stamped of the last :data:`JOINT_HISTORY` joint states within it; with none within
  it the F/T sample faults (``stamp_gap``) and is never judged (a wrench paired with a stale
  joint state would read as contact). A paired joint state stamped before the wrench is
  brought forward to the wrench's stamp (:func:`joint_state_at`): a joint stream slower
  than the F/T stream, or one that lost messages, would otherwise hold q̇ over several F/T
  samples and then jump, which the chain's q̈ estimate (a difference of q̇ per F/T period)
  reads as a burst of acceleration and the detector as contact. 0 pairs by arrival only
  (the newest joint state, as it is);
* a stamp :data:`CLOCK_RESTART_S` or more before its stream's last is that stream's clock
  restarting (a looped bag, a restarted driver): the stream is taken up again from its new
  time and ``on_restart`` is told; a stamp back by less is a message out of order, refused;
* for a model that takes an IMU, an F/T sample with no IMU sample paired to it faults
  (``imu_missing``, ``imu_stamp_gap``; raised by the station through ``flag``) until one
  pairs again.

``reason`` names the cause (one of :data:`REASONS`) and ``detail`` says it in words for a
person ("joint state has 6 joints, expected 7"). While ``fault`` is True the held values are
stale and a consumer must not publish a result computed from them as fresh.

:class:`RobotStatePairer` joins the two ``lcmt_robot_state`` streams (positions, and
velocities on the second channel; see HardwareConfig) into joint samples.
"""

from __future__ import annotations

import collections
import math

import numpy as np

from .messages import JointSample, WrenchSample

#: Reasons a message is rejected or the inputs are faulted. ``unpaired`` (robot_state only)
#: counts a position or velocity message that never met its partner; it is not a fault by
#: itself (nothing stale is used; a silent pair stream faults by timeout). ``joint_names``
#: (joint states by name, ROS 2): a configured joint missing or named twice (joints beyond
#: them are ignored).
#: ``degrees`` / ``joint_range``: joint positions radians cannot be (live_checks.JointBounds);
#: ``wrong_type``: a message of another type on an input channel or topic; ``frame_id``: a
#: wrench in another frame than the configured sensor frame (ROS 2); ``overload``: an F/T
#: message dropped because the station is too far behind the stream (overload.LoadMonitor).
#: ``stamp_gap``: no joint state stamped within the pairing tolerance of an F/T sample;
#: ``qos``: a publisher on an input topic whose QoS the subscription cannot match (ROS 2).
#: ``imu_missing`` / ``imu_stamp_gap`` (a model that takes an IMU): no IMU sample yet / none
#: stamped within ``imu_max_skew_s`` of an F/T sample (live_imu.ImuPairing; StreamMonitor.flag).
#: New reasons go at the end: the LCM status message carries a reason's index.
REASONS = ("sensor_timeout", "joint_timeout", "temperature_timeout", "out_of_order",
           "duplicate", "not_finite", "joint_count", "malformed", "unpaired", "joint_names",
           "degrees", "joint_range", "wrong_type", "frame_id", "overload",
           "stamp_gap", "qos", "imu_missing", "imu_stamp_gap")
def all_finite(values) -> bool:
    """Whether every value of a 1-D array (or sequence) is finite; for the few values of a
    message Python's math costs less than numpy's calls."""
    return all(map(math.isfinite, values.tolist() if hasattr(values, "tolist") else values))


#: Joint states kept to pair an F/T sample with by stamp.
JOINT_HISTORY = 64

#: s: a stamp this much or more before its stream's last is the driver's clock restarting (a
#: looped bag, a restarted driver or simulator), not a message out of order: no transport
#: delays one message of a stream by that much behind the next.
CLOCK_RESTART_S = 0.5


def joint_state_at(t: float, t_joint: float, x, before=None) -> np.ndarray:
    """The joint state `x` ([q; q̇], 2n: rad, rad/s) stamped `t_joint` (s) brought to the
    stamp `t` (s) with δ = t − t_joint: ``[q + q̇δ + ½q̈δ²; q̇ + q̈δ]``, q̈ (rad/s²) the
    difference of q̇ from `before` (``(t_before, x_before)``, the joint state accepted before
    it, stamped earlier) over their stamps; without `before`, q̈ = 0. A new array; `x` when
    δ is 0."""
    delta = t - t_joint
    if delta == 0.0:
        return x
    n = len(x) // 2
    q, v = x[:n], x[n:]
    if before is None:
        a = np.zeros(n)
    else:
        t_before, x_before = before
        a = (v - x_before[n:]) / (t_joint - t_before)
    return np.concatenate([q + delta * v + (0.5 * delta * delta) * a, v + delta * a])


class StreamMonitor:
    """Checks F/T and joint-state samples; holds the last good values and counts.

    Counters: ``received[stream]``, ``accepted[stream]``, ``rejected[reason]`` with stream in
    {"ft", "joint"}; received == accepted + the rejections of that stream, always
    (``rejected_by[stream][reason]`` splits them).
    """

    def __init__(self, n_joints: int, sensor_timeout_s: float, joint_state_timeout_s: float,
                 temperature_timeout_s: float | None = None, joint_check=None,
                 pair_tolerance_s: float = 0.0):
        self.n = int(n_joints)
        self.pair_tolerance_s = float(pair_tolerance_s)
        self._history = collections.deque(maxlen=JOINT_HISTORY)  # (t, [q; v]) accepted
        # joint_check(q) → None or (reason, detail): positions radians cannot be (degrees?).
        self.joint_check = joint_check
        # None: no temperature stream (the model needs none); else its staleness limit, s.
        self.temperature_timeout_s = temperature_timeout_s
        self.temperature = np.nan  # °C, the last accepted
        self.sensor_timeout_s = float(sensor_timeout_s)
        self.joint_state_timeout_s = float(joint_state_timeout_s)
        self.wrench = np.zeros(6)
        self.joint_state = np.zeros(2 * self.n)
        self.fault = True  # nothing received yet
        self.reason = "no_data"
        self.detail = "no message received yet"
        self.received = collections.Counter()
        self.accepted = collections.Counter()
        self.rejected = collections.Counter()
        self.rejected_by = {"ft": collections.Counter(), "joint": collections.Counter(),
                            "temperature": collections.Counter()}
        self._last_t = {"ft": None, "joint": None, "temperature": None}
        self._last_arrival = {"ft": None, "joint": None, "temperature": None}
        self._joint_bad = None  # (reason, detail) of a rejected joint message not yet made good
        # stream → (reason, detail): why it has no message yet, when a transport knows
        # (another type published on its topic); said instead of "no_data".
        self.missing: dict[str, tuple[str, str]] = {}
        # A stream's clock restarted: its stamps taken up again from the new time, counted
        # per stream, and on_restart(stream, detail, t, arrival) called for the message that
        # showed it (the station settles its chain).
        self.restarts = collections.Counter()
        self.on_restart = None
        self.pair_key = "pair_tolerance_s"  # the config key a stamp gap's fix names

    # -- bookkeeping --------------------------------------------------------------------------
    def _reject(self, stream: str, reason: str, detail: str) -> bool:
        self.rejected[reason] += 1
        self.rejected_by[stream][reason] += 1
        self.fault, self.reason, self.detail = True, reason, detail
        if stream == "joint":
            self._joint_bad = (reason, detail)
        return False

    def reject_joint(self, reason: str, detail: str) -> bool:
        """A joint-state message the transport could not turn into a sample (e.g. its joint
        names do not match): counted as received and rejected, faulted like a bad sample."""
        self.received["joint"] += 1
        return self._reject("joint", reason, detail)

    def flag(self, reason: str, detail: str) -> None:
        """Faults the inputs of the F/T sample just accepted for a cause found outside the
        monitor (no IMU sample paired with it): until an F/T sample that ``on_wrench``
        accepts fault-free and nothing flags."""
        self.fault, self.reason, self.detail = True, reason, detail

    def count_unpaired(self, detail: str = "") -> None:
        """A joint message that was received but never formed a sample (robot_state)."""
        del detail  # counted, not a fault: see REASONS
        self.received["joint"] += 1
        self.rejected["unpaired"] += 1
        self.rejected_by["joint"]["unpaired"] += 1

    def last_time(self, stream: str) -> float | None:
        """Timestamp (s) of the last accepted message of `stream`."""
        return self._last_t[stream]

    def last_arrival(self, stream: str) -> float | None:
        """Arrival (the caller's clock, s) of the last accepted message of `stream`."""
        return self._last_arrival[stream]

    def _check_time(self, stream: str, t: float, arrival: float) -> tuple[str, str] | None:
        last = self._last_t[stream]
        if last is None or t > last:
            return None
        name = "F/T" if stream == "ft" else "joint state"
        if t == last == 0.0:
            return "duplicate", (
                f"{name} messages are not stamped (their stamp is 0 again): the station "
                "orders, pairs and times the streams by their stamps, so it takes only the "
                "first. Fix: have the driver stamp each message with its sampling time (ROS 2: "
                "header.stamp; LCM: timestamp or utime, µs)")
        if t == last:
            return "duplicate", f"{name} message with the same timestamp {t:.6f} s again"
        if last - t >= CLOCK_RESTART_S:
            self._restart(stream, name, last, t, arrival)
            return None
        return "out_of_order", (f"{name} time went back from {last:.6f} s to {t:.6f} s "
                                f"({(t - last) * 1e3:.3f} ms)")

    def _restart(self, stream: str, name: str, last: float, t: float, arrival: float) -> None:
        """The stream's clock restarted: its stamps start again from `t` (a joint stream's
        history for pairing with it)."""
        self._last_t[stream] = None
        if stream == "joint":
            self._history.clear()
        self.restarts[stream] += 1
        if self.on_restart is not None:
            self.on_restart(stream, (
                f"{name} clock restarted: its time went back {last - t:.3f} s, from "
                f"{last:.6f} s to {t:.6f} s (a looped bag, a restarted driver or simulator); "
                "the stream is taken up again from its new time"), t, arrival)

    # -- messages -----------------------------------------------------------------------------
    def on_joint(self, sample: JointSample | None, arrival: float,
                 problem: tuple[str, str] | None = None) -> bool:
        """One joint-state message (None if it failed to decode; `problem`: the transport's
        (reason, detail) for it). Returns True if accepted."""
        self.received["joint"] += 1
        if sample is None:
            return self._reject("joint", *(problem or (
                "malformed", "joint-state message failed to decode")))
        nv = None if sample.v is None else len(sample.v)
        if len(sample.q) != self.n or nv != self.n:
            return self._reject("joint", "joint_count", (
                f"joint state has {len(sample.q)} positions and "
                f"{'no' if nv is None else nv} velocities, expected {self.n}"))
        if not (math.isfinite(sample.t) and all_finite(sample.q) and all_finite(sample.v)):
            return self._reject("joint", "not_finite", "joint state holds NaN or inf")
        bad = self._check_time("joint", sample.t, arrival)
        if bad:
            return self._reject("joint", *bad)
        bad = self.joint_check(sample.q) if self.joint_check is not None else None
        if bad:
            return self._reject("joint", *bad)
        self.joint_state[:self.n], self.joint_state[self.n:] = sample.q, sample.v
        if self.pair_tolerance_s > 0:
            self._history.append((sample.t, self.joint_state.copy()))
        self._last_t["joint"], self._last_arrival["joint"] = sample.t, arrival
        self.accepted["joint"] += 1
        self._joint_bad = None
        return True

    def on_temperature(self, sample: tuple[float, float] | None, arrival: float) -> bool:
        """One temperature message ``(t s, °C)``. A rejected one leaves the last good value,
        which then ages into a ``temperature_timeout``; nothing is faulted by it alone."""
        self.received["temperature"] += 1
        if sample is None:
            self.rejected["malformed"] += 1
            self.rejected_by["temperature"]["malformed"] += 1
            return False
        t, celsius = sample
        if not (np.isfinite(t) and np.isfinite(celsius)):
            self.rejected["not_finite"] += 1
            self.rejected_by["temperature"]["not_finite"] += 1
            return False
        self.temperature = float(celsius)
        self._last_t["temperature"], self._last_arrival["temperature"] = t, arrival
        self.accepted["temperature"] += 1
        return True

    def _temperature_problem(self, arrival: float) -> tuple[str, str] | None:
        if self.temperature_timeout_s is None:
            return None
        last = self._last_arrival["temperature"]
        if last is None:
            return "no_data", "no sensor temperature received yet (the model needs it)"
        if arrival - last > self.temperature_timeout_s:
            return "temperature_timeout", (
                f"last sensor temperature arrived {(arrival - last):.2f} s before this F/T "
                f"message (timeout {self.temperature_timeout_s:g} s)")
        return None

    def on_wrench(self, sample: WrenchSample | None, arrival: float,
                  problem: tuple[str, str] | None = None) -> bool:
        """One F/T message (None if it failed to decode; `problem`: the transport's (reason,
        detail) for a message it refused, e.g. another frame_id). Returns True if it is
        accepted *and* the inputs are fault-free, i.e. the compensator may run on it and its
        result is fresh."""
        self.received["ft"] += 1
        if sample is None or problem is not None:
            problem = problem or ("malformed", "F/T message failed to decode")
            return self._reject("ft", *problem)
        if not (math.isfinite(sample.t) and all_finite(sample.wrench)):
            return self._reject("ft", "not_finite", f"F/T message at {sample.t:.6f} s holds "
                                "NaN or inf")
        bad = self._check_time("ft", sample.t, arrival)
        if bad:
            return self._reject("ft", *bad)
        self.wrench[:] = sample.wrench
        self._last_t["ft"], self._last_arrival["ft"] = sample.t, arrival
        self.accepted["ft"] += 1
        joint = self._last_arrival["joint"]
        if self._joint_bad is not None:
            self.fault = True
            self.reason, self.detail = self._joint_bad
            return False
        if joint is None:
            self.fault = True
            self.reason, self.detail = self.missing.get(
                "joint", ("no_data", "no joint state received yet"))
            return False
        if arrival - joint > self.joint_state_timeout_s:
            self.fault, self.reason = True, "joint_timeout"
            self.detail = (f"last joint state arrived {(arrival - joint) * 1e3:.1f} ms before "
                           f"this F/T message (timeout {self.joint_state_timeout_s * 1e3:g} ms)")
            return False
        problem = self._temperature_problem(arrival) or self._pair(sample.t)
        if problem is not None:
            self.fault, (self.reason, self.detail) = True, problem
            return False
        self.fault, self.reason, self.detail = False, "", ""
        return True

    def _pair(self, t: float) -> tuple[str, str] | None:
        """Puts into ``joint_state`` the joint state paired with an F/T sample stamped `t`
        (see the module); (reason, detail) when none is within the tolerance."""
        tol, history = self.pair_tolerance_s, self._history
        if tol <= 0 or not history:
            return None
        newest_t, newest = history[-1]
        if abs(newest_t - t) <= tol:  # per message: the common case inline
            self.joint_state[:] = (newest if t <= newest_t
                                   else self._brought_forward(len(history) - 1, t))
            return None
        nearest = min(range(len(history)), key=lambda i: abs(history[i][0] - t))
        nearest_t, x = history[nearest]
        if abs(nearest_t - t) <= tol:
            self.joint_state[:] = x if t <= nearest_t else self._brought_forward(nearest, t)
            return None
        if abs(nearest_t - t) >= CLOCK_RESTART_S:  # no transport delays a stream that much
            return "stamp_gap", (
                f"the F/T stamps and the joint states' are on different clocks: the nearest "
                f"joint state is {nearest_t - t:+.3f} s from the F/T sample at {t:.6f} s, "
                f"the tolerance {tol * 1e3:g} ms: the wrench is not judged. Fix: stamp both "
                "streams on one clock (the time each was sampled), or set "
                f"{self.pair_key}: 0 to pair each wrench with the newest joint state as it "
                "arrives")
        return "stamp_gap", (
            f"no joint state stamped within {tol * 1e3:g} ms of the F/T sample at {t:.6f} s "
            f"(the nearest of the last {len(self._history)} is {(nearest_t - t) * 1e3:+.1f} ms "
            f"away): the wrench is not judged. Fix: the drivers' clocks or stamps, or "
            f"{self.pair_key}")

    def _brought_forward(self, index: int, t: float) -> np.ndarray:
        """The joint state `index` of the history, stamped before the F/T stamp `t`, brought
        forward to it (joint_state_at; q̈ from the one before it, when kept). _pair takes one
        stamped after `t` as it is: that is a wrench arriving after the next sample's joint
        state, as the simulated robot's do (lcm_publisher), whose chain the live one
        equals."""
        t_joint, x = self._history[index]
        before = self._history[index - 1] if index > 0 else None
        return joint_state_at(t, t_joint, x, before)

    def check_timeouts(self, now: float) -> bool:
        """Call periodically (same clock as the arrivals, s). Raises the fault when a stream
        went silent; returns the fault flag."""
        for stream, timeout, reason, name in (
                ("ft", self.sensor_timeout_s, "sensor_timeout", "F/T"),
                ("joint", self.joint_state_timeout_s, "joint_timeout", "joint-state")):
            last = self._last_arrival[stream]
            if last is not None and now - last > timeout and not self.fault:
                self.fault, self.reason = True, reason
                self.detail = (f"no {name} message for {(now - last) * 1e3:.1f} ms "
                               f"(timeout {timeout * 1e3:g} ms)")
        problem = self._temperature_problem(now)
        if problem is not None and problem[0] == "temperature_timeout" and not self.fault:
            self.fault, (self.reason, self.detail) = True, problem
        return self.fault


class RobotStatePairer:
    """Joins ``lcmt_robot_state`` positions and velocities with the same ``utime``.

    ``add("q" | "v", sample)`` returns the joined JointSample once both halves of a utime
    are in, else None. When a pair completes, the halves still waiting with an older utime
    can never complete (the streams are in time order): they are returned by ``add`` through
    ``self.dropped`` (a list of descriptions, cleared by the caller) so that they are counted.
    At most `max_pending` halves wait per stream; older ones are dropped likewise.
    """

    def __init__(self, max_pending: int = 100):
        self.max_pending = int(max_pending)
        self._pending = {"q": {}, "v": {}}
        self.dropped: list[str] = []

    def waiting(self) -> int:
        """Halves still waiting for their partner."""
        return sum(len(p) for p in self._pending.values())

    def add(self, half: str, sample: JointSample) -> JointSample | None:
        key = round(sample.t * 1e6)
        mine, other = self._pending[half], self._pending["v" if half == "q" else "q"]
        partner = other.pop(key, None)
        if partner is None:
            if key in mine:
                self.dropped.append(f"robot_state {half} at {sample.t:.6f} s arrived twice")
            mine[key] = sample
            while len(mine) > self.max_pending:
                old = min(mine)
                self.dropped.append(f"robot_state {half} at {old * 1e-6:.6f} s: partner "
                                    "never arrived")
                del mine[old]
            return None
        for stream, pending in (("q", self._pending["q"]), ("v", self._pending["v"])):
            for old in [k for k in pending if k < key]:
                self.dropped.append(f"robot_state {stream} at {old * 1e-6:.6f} s: partner "
                                    "never arrived")
                del pending[old]
        q, v = (sample, partner) if half == "q" else (partner, sample)
        return JointSample(q.t, q.q, v.q, None)
