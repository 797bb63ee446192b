"""StreamMonitor: the checks between LCM messages and the compensator's inputs.

Not yet a LeafSystem (the station that wraps it is still to be written): it is the logic
that such a system's update will call once per received message, so that it can be tested
message by message.

What downstream sees: ``wrench`` (6) and ``joint_state`` (2n) are the last *accepted*
values; a rejected message never replaces them. ``fault`` is True from the first rejected
message or timeout until the next accepted F/T message that arrives while the joint stream
is also fresh; ``reason`` names the latest cause. While ``fault`` is True the held values are
stale and a consumer must not publish a result computed from them as fresh.
"""

from __future__ import annotations

import collections

import numpy as np

from .messages import JointSample, WrenchSample

#: Reasons a message is rejected or the inputs are faulted.
REASONS = ("sensor_timeout", "joint_timeout", "out_of_order", "duplicate", "not_finite",
           "joint_count", "malformed")


class StreamMonitor:
    """Checks F/T and joint-state samples; holds the last good values and counts.

    Counters: ``received[stream]``, ``accepted[stream]``, ``rejected[reason]`` with stream in
    {"ft", "joint"}; received == accepted + the rejections of that stream, always.
    """

    def __init__(self, n_joints: int, sensor_timeout_s: float, joint_state_timeout_s: float):
        self.n = int(n_joints)
        self.sensor_timeout_s = float(sensor_timeout_s)
        self.joint_state_timeout_s = float(joint_state_timeout_s)
        self.wrench = np.zeros(6)
        self.joint_state = np.zeros(2 * self.n)
        self.fault = True  # nothing received yet
        self.reason = "no_data"
        self.received = collections.Counter()
        self.accepted = collections.Counter()
        self.rejected = collections.Counter()
        self._last_t = {"ft": None, "joint": None}
        self._last_arrival = {"ft": None, "joint": None}

    def _reject(self, reason: str) -> bool:
        self.rejected[reason] += 1
        self.fault, self.reason = True, reason
        return False

    def _check_time(self, stream: str, t: float) -> str | None:
        last = self._last_t[stream]
        if last is None:
            return None
        if t == last:
            return "duplicate"
        if t < last:
            return "out_of_order"
        return None

    def on_joint(self, sample: JointSample | None, arrival: float) -> bool:
        """One joint-state message (None if it failed to decode). Returns True if accepted."""
        self.received["joint"] += 1
        if sample is None:
            return self._reject("malformed")
        if len(sample.q) != self.n or sample.v is None or len(sample.v) != self.n:
            return self._reject("joint_count")
        if not (np.isfinite(sample.q).all() and np.isfinite(sample.v).all()
                and np.isfinite(sample.t)):
            return self._reject("not_finite")
        bad = self._check_time("joint", sample.t)
        if bad:
            return self._reject(bad)
        self.joint_state[:self.n], self.joint_state[self.n:] = sample.q, sample.v
        self._last_t["joint"], self._last_arrival["joint"] = sample.t, arrival
        self.accepted["joint"] += 1
        return True

    def on_wrench(self, sample: WrenchSample | None, arrival: float) -> bool:
        """One F/T message. Returns True if it is accepted *and* the inputs are fault-free,
        i.e. the compensator may run on it and its result is fresh."""
        self.received["ft"] += 1
        if sample is None:
            return self._reject("malformed")
        if not (np.isfinite(sample.wrench).all() and np.isfinite(sample.t)):
            return self._reject("not_finite")
        bad = self._check_time("ft", sample.t)
        if bad:
            return self._reject(bad)
        self.wrench[:] = sample.wrench
        self._last_t["ft"], self._last_arrival["ft"] = sample.t, arrival
        self.accepted["ft"] += 1
        joint = self._last_arrival["joint"]
        if joint is None or arrival - joint > self.joint_state_timeout_s:
            self.fault, self.reason = True, "joint_timeout" if joint is not None else "no_data"
            return False
        self.fault, self.reason = False, ""
        return True

    def check_timeouts(self, now: float) -> bool:
        """Call periodically (wall clock, s). Raises the fault when a stream went silent;
        returns the fault flag."""
        ft = self._last_arrival["ft"]
        if ft is not None and now - ft > self.sensor_timeout_s and not self.fault:
            self.fault, self.reason = True, "sensor_timeout"
        joint = self._last_arrival["joint"]
        if joint is not None and now - joint > self.joint_state_timeout_s and not self.fault:
            self.fault, self.reason = True, "joint_timeout"
        return self.fault
