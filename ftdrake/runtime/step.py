"""ChainStep: one update of a built :class:`~ftdrake.runtime.chain.CompensationChain` per
sample, on plain arrays, without Drake's Simulator.

A live station updates the chain once per F/T message. Driving the diagram for that (fix
the inputs, ``Simulator.AdvanceTo`` to fire one periodic update, evaluate the output ports)
costs several times the compiled kernels' own work: the Simulator's event bookkeeping, a
copy of the whole discrete state per update, and a Python call into every LeafSystem
reaching its inputs through the context. ChainStep keeps the chain's discrete state in
numpy arrays and calls each system's own array method (``CompensatorSystem.compensate``,
``OnlineBiasTracker.track``, ``ContactDetector.detect``, ``PayloadChangeMonitor.monitor``,
``DelayLine.delayed``/``remember``) and JointStateGravity's compiled kernel with the same
inputs and state as the diagram's update at that sample, so its outputs equal the
diagram's; the diagram stays the reference (tests/runtime/test_chain_step.py compares them sample
by sample).

What one update reproduces — Drake's discrete update semantics: every system's update at
time t reads the state *before* the update (a state output read by another system is that
system's previous value) and the inputs at t; all states then change together. The
systems' reads form cycles (tracker ↔ detector, tracker ↔ payload monitor), so the step
keeps the two values that cross a cycle (the detector's contact flag, the monitor's
payload-change flag) from before the update and runs the systems consumers first: the
payload monitor, the detector (which reads the monitor's decision from before the update),
the tracker, the joint-state gravity, the compensator, the delay line's memory last (its
output, direct feedthrough, is computed first).

Time: the k-th update (k = 0, 1, ...) is the diagram's periodic update at t = k·period, as
a diagram started at time 0 fires them; `t` arms the detector (``arm_after_s``). The payload
monitor samples every ``payload_change.sample_period_s``: the step samples it on every m-th
update (m that period over the chain's, which must be whole), with the chain's update as
the diagram does where its sample times fall on the chain's to the last bit (a monitor
period that is not a whole number of the chain's is refused: the diagram would then sample
it between the chain's updates).

Usage (``chain`` a built CompensationChain; `t` the update's time on the chain's clock)::

    step = ChainStep(chain)                       # its initial state: chain.initialize's
    out = step.update(t, wrench_measured, joint_state, tared=1.0)
    out["wrench_contact"], out["contact"][0] ...  # every exported output port, by name
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from .joint_gravity import _apparent_gravity

__all__ = ["ChainStep", "bridge_acceleration", "restart_acceleration"]


class ChainStep:
    """The chain's per-sample update on arrays (module docstring).

    `chain`: a built :class:`~ftdrake.runtime.chain.CompensationChain` (its systems, their
    settings and the model they hold are used as they are). `root_context`: a context of the
    chain, or of a diagram holding it, to take the starting state from (e.g. the live
    station's, after ``chain.initialize``); default: the chain's default context after
    ``chain.initialize``. The step keeps its own copy of the state from then on.

    :meth:`update` takes the exported inputs of one sample and returns :attr:`outputs`:
    exported output port name → array, the same arrays every call (overwritten by the next
    update; copy what you keep). Frames, units and sizes are the chain's ports'.
    """

    def __init__(self, chain, root_context=None):
        if root_context is None:
            root_context = chain.CreateDefaultContext()
            chain.initialize(root_context)
        self.chain = chain
        self.period = chain.period
        comp, tracker, detector = chain.compensator, chain.tracker, chain.detector
        self.n_joints = comp.n
        self.needs_temperature = comp.needs_temperature
        self.needs_imu = comp.needs_imu

        self._states = []  # (system, discrete state index, the step's array)

        def state(system, index):
            context = system.GetMyContextFromRoot(root_context)
            value = np.array(context.get_discrete_state(index).get_value(), dtype=float)
            self._states.append((system, index, value))
            return value

        self._comp = comp
        self._comp_state = [state(comp, i) for i in (comp._estimator, comp._internal,
                                                     comp._external, comp._std, comp._ood,
                                                     comp._fault)]
        self._imu_state = (state(comp, comp._imu_estimator),) if self.needs_imu else ()
        self._imu = np.zeros(6)
        self._no_acceleration = np.zeros(self.n_joints)
        self._wrench = np.zeros(6)
        self._joint_state = np.zeros(2 * self.n_joints)
        self._detector = detector
        self._flag, self._force, self._counter = (state(detector, i) for i in (
            detector._flag, detector._force, detector._counter))
        internal, external, std, ood, fault = self._comp_state[1:]
        self.outputs = {"wrench_internal": internal, "wrench_compensated": external,
                        "wrench_contact": external, "wrench_std": std, "out_of_domain": ood,
                        "fault": fault, "contact": self._flag, "contact_force": self._force}
        self._tracker = tracker
        self._gravity = chain.gravity
        self._monitor = chain.payload_monitor
        self._line = chain.delay_line
        self._line_state = (state(self._line, self._line._buffer)
                            if self._line is not None else None)
        self._delay_joint_state = self._line is not None and chain.wrench_delay_s > 0
        self._gap_s = None  # bridge_gap's, for the next update
        self._hold = False
        if tracker is not None:
            self._init_tracker(state)

    def _init_tracker(self, state) -> None:
        tracker, chain = self._tracker, self.chain
        self._flags = np.zeros(5)
        self._tracker_state = [state(tracker, tracker._x), state(tracker, tracker._corrected),
                               state(tracker, tracker._bias)]
        if tracker.track_payload:
            self._payload = state(tracker, tracker._payload)
            self._inertia = state(tracker, tracker._inertia)
        else:
            self._payload = self._inertia = np.zeros(tracker.n)  # scratch
        self._tracking = state(tracker, tracker._tracking)
        self._tracker_std = state(tracker, tracker._std)
        self._no_motion = np.zeros(6)
        self._g, self._motion = np.zeros(3), self._no_motion
        self._motion_used = bool(chain.config.bias_tracker.track_payload_motion)
        if self._gravity is not None:
            g = self._gravity
            self._g = state(g, g._gravity)
            self._gravity_estimator = state(g, g._estimator)
            self._motion = state(g, g._motion)
            self._gravity_args = (g._constants, g._gravity_W, *g.chain.kernel_args())
        _, corrected, bias = self._tracker_state
        self.outputs.update({"wrench_contact": corrected, "bias": bias,
                             "tracker_std": self._tracker_std})
        if tracker.track_payload:
            self.outputs["payload"] = self._payload
        if self._monitor is not None:
            m = self._monitor
            self._monitor_state = [state(m, i) for i in (m._window, m._flag, m._estimate,
                                                          m._state)]
            self.outputs["payload_change"] = self._monitor_state[1]
            self.outputs["payload_state"] = self._monitor_state[3]
            self._monitor_every = _whole_periods(m.period, self.period)
            self._monitor_due = 0  # updates until its next sample (0: this one)

    def write_state(self, root_context) -> None:
        """Writes the step's state (every discrete state of the chain's systems) into
        `root_context`, a context of the chain or of a diagram holding it: any port of the
        chain or of its systems (e.g. the tracker's ``payload_inertia``, not exported) then
        evaluates there as at the step's last update."""
        for system, index, value in self._states:
            system.GetMyMutableContextFromRoot(root_context).SetDiscreteState(index, value)

    def bridge_gap(self, gap_s: float) -> None:
        """The next update follows `gap_s` s (> one period) without updates (samples lost
        or dropped). Its q̈ estimates (the compensator's, the joint-state gravity's) then
        bridge the gap with q̈ taken as linear across it, instead of reading the jump of q̇
        across the gap as one period's acceleration: from the estimate before the gap a₀
        (q̈ half a period before that sample, as the backward difference gives it) and the
        mean acceleration over the gap ā = (q̇ after − q̇ before) / `gap_s` (q̈ at the gap's
        middle), the jerk is j = (ā − a₀) / ((`gap_s` + period) / 2) and the estimate after
        ā + j (`gap_s` − period) / 2, again half a period before its sample. The estimators
        keep their own jerk: j, carried on, would amplify the error of the estimate before
        the gap at every gap, and gaps that recur (a stream that loses every few samples)
        would make the estimate diverge (:func:`bridge_acceleration`; on the diagram, apply
        it to those systems' estimator states in the context)."""
        self._gap_s = float(gap_s)

    def restart_acceleration(self) -> None:
        """The streams' clock restarted (a looped bag, a restarted driver): the q̈ estimators
        (the compensator's, the joint-state gravity's, and α's for an IMU) start afresh at
        the next update, as at the first one (:func:`restart_acceleration`), and a pending
        bridge_gap is dropped: a jump of q̇ across a restart is no acceleration."""
        self._gap_s = None
        restart_acceleration(self._comp_state[0], self.n_joints)
        if self._tracker is not None and self._gravity is not None:
            restart_acceleration(self._gravity_estimator, self.n_joints)
        if self.needs_imu:
            restart_acceleration(self._imu_state[0], 3)

    def _bridge(self, v) -> None:
        """Puts the q̈ estimators across the gap (bridge_gap)."""
        gap, self._gap_s = self._gap_s, None
        bridge_acceleration(self._comp_state[0], v, gap, self.period)
        if self._tracker is not None and self._gravity is not None:
            bridge_acceleration(self._gravity_estimator, v, gap, self.period)

    def update(self, t: float, wrench_measured, joint_state, temperature=None, tared=0.0,
               payload_changed=0.0, gravity_S=None, motion_S=None, imu=None,
               hold=False) -> dict:
        """One update of the chain at time `t` (s, the chain's clock: the diagram's context
        time of that update; the detector is disarmed before ``detector.arm_after_s``).

        `wrench_measured` (6: N, N·m, in S or the sensor's own frame, as the chain's
        input), `joint_state` (2n: [q; v], rad, rad/s); `temperature` (°C; required when
        the model takes it, else not read); `tared`, `payload_changed` (> 0.5 for a signal;
        ignored where the chain has no such input); `gravity_S` (3, m/s², in S) and
        `motion_S` (6) only for a chain built with ``gravity="input"`` and payload tracking
        (motion_S with ``track_payload_motion``); `imu` (6: ``[f_S; ω_S]``, m/s², rad/s, in
        S; NaN when missing or stale) required when the model takes an IMU, else not read;
        `hold` (a live station's settle window after dropped samples): the tracker and the
        payload monitor learn nothing and the detector is held released. Returns
        :attr:`outputs`.
        """
        self._take_inputs(wrench_measured, joint_state, temperature, imu)
        wrench, x = self._wrench, self._joint_state
        if self._gap_s is not None:
            self._bridge(self._joint_state[self.n_joints:])
        self._hold = bool(hold)
        if self._line is not None:  # the stream that is ahead, delayed (direct feedthrough)
            if self._delay_joint_state:
                x = self._line.delayed(self._joint_state, self._line_state)
            else:
                wrench = self._line.delayed(self._wrench, self._line_state)
        if self._tracker is not None:
            self._update_tracker_side(t, tared, payload_changed, gravity_S, motion_S, x)
        elif self._hold:
            self._release()
        elif t >= self._detector.arm_after_s:
            self._detect(self.outputs["wrench_compensated"], None)
        self._compensate(wrench, x, temperature)
        if self._line is not None:
            self._line.remember(self._joint_state if self._delay_joint_state else self._wrench,
                                self._line_state)
        return self.outputs

    def _take_inputs(self, wrench_measured, joint_state, temperature, imu) -> None:
        """Copies the update's inputs into the step's arrays; a missing input the model needs
        is a ConfigError, a wrong size a ValueError."""
        if self.needs_temperature and temperature is None:
            raise ConfigError("ChainStep.update: the model was trained with the sensor "
                              "temperature (°C); pass temperature each update")
        if self.needs_imu:
            if imu is None:
                raise ConfigError("ChainStep.update: the model takes an IMU at the sensor; "
                                  "pass imu = [f_S; ω_S] (6) each update (NaN when missing)")
            self._imu[:] = imu
        try:
            self._wrench[:] = wrench_measured
            self._joint_state[:] = joint_state
        except ValueError as e:
            raise ValueError(f"ChainStep.update: wrench_measured needs 6 entries, joint_state "
                             f"{2 * self.n_joints} ([q; v]) ({e})") from None

    def _update_tracker_side(self, t, tared, payload_changed, gravity_S, motion_S, x) -> None:
        """The payload monitor, the detector, the tracker and the joint-state gravity, each
        from the state before this update (module docstring)."""
        flags = self._flags
        flags[0] = self._flag[0]  # the detector's flag before it updates
        g, motion = self._g, self._motion
        if self._tracker.track_payload and self._gravity is None:
            g, motion = self._gravity_inputs(gravity_S, motion_S)
        corrected = self._tracker_state[1]
        changed, decided = float(payload_changed), 0.0
        if self._monitor is not None:
            window, flag, estimate, payload_state = self._monitor_state
            # The monitor's flag and decision before it updates.
            changed, decided = max(changed, flag[0]), payload_state[0]
            if self._monitor_due == 0 and not self._hold:
                self._monitor.monitor(corrected, g, flags[0], window, flag, estimate,
                                      payload_state)
            self._monitor_due = (self._monitor_due + 1) % self._monitor_every
        if self._hold:
            self._release()
        elif t >= self._detector.arm_after_s:
            self._detect(corrected, self._tracker_std, decided)
        _, ood, fault = self._comp_state[3:6]
        flags[1], flags[2], flags[3] = ood[0], max(fault[0], float(self._hold)), float(tared)
        flags[4] = changed if self._tracker.track_payload else 0.0
        x_tracker, _, bias = self._tracker_state
        self._tracker.track(self.outputs["wrench_compensated"], g,
                            motion if self._motion_used else self._no_motion, flags,
                            x_tracker, corrected, bias, self._payload, self._inertia,
                            self._tracking, self._tracker_std)
        if self._gravity is not None:
            _apparent_gravity(x, self._gravity_estimator, self._g, self._motion,
                              *self._gravity_args)

    def _gravity_inputs(self, gravity_S, motion_S):
        if gravity_S is None or (self._motion_used and motion_S is None):
            raise ConfigError("ChainStep.update: this chain was built with gravity='input' "
                              "and payload tracking; pass gravity_S (and motion_S with "
                              "bias_tracker.track_payload_motion) each update")
        g = np.asarray(gravity_S, dtype=float)
        motion = np.asarray(motion_S, dtype=float) if self._motion_used else self._no_motion
        return g, motion

    def _release(self) -> None:
        """The detector released: no contact, its debounce counter restarted."""
        self._flag[0] = self._counter[0] = self._force[0] = 0.0

    def _detect(self, wrench_contact, tracker_std, payload_state=0.0) -> None:
        detector = self._detector
        std = self.outputs["wrench_std"] if detector.uses_std else None
        detector.detect(wrench_contact, std, tracker_std if std is not None else None,
                        self._flag, self._counter, self._force, payload_state)

    def _compensate(self, wrench, x, temperature) -> None:
        estimator, internal, external, std, ood, fault = self._comp_state
        self._comp.compensate(wrench, x, self._no_acceleration, False,
                              float(temperature) if self.needs_temperature else math.nan,
                              estimator, internal, external, std, ood, fault,
                              *((self._imu, *self._imu_state) if self.needs_imu else ()))


def bridge_acceleration(estimator, v, gap_s: float, period: float) -> None:
    """Puts a q̈ estimator's state (:func:`~ftdrake.signals.causal_acceleration_step`'s, n
    joints: q̇ before, q̈, jerk, primed; entries after those are left alone) across a gap of
    `gap_s` s before the sample of q̇ `v`, as :meth:`ChainStep.bridge_gap` says: as of one
    period before that sample, so that the sample's step gives the bridged estimate with no
    innovation; its jerk is left as it is. Nothing for an estimator not yet primed or a
    non-finite `v`."""
    n = len(v)
    if estimator[3 * n] == 0.0 or not np.all(np.isfinite(v)):
        return
    mean = (v - estimator[:n]) / gap_s
    jerk = (mean - estimator[n:2 * n]) / (0.5 * (gap_s + period))
    after = mean + jerk * 0.5 * (gap_s - period)
    # The filter keeps its own jerk: this gap's, carried on, would grow with every gap that
    # recurs (it amplifies the error of the estimate before the gap).
    estimator[n:2 * n] = after - period * estimator[2 * n:3 * n]  # the step predicts `after`
    estimator[:n] = v - period * after  # its difference: `after`, no innovation


def restart_acceleration(estimator, n: int) -> None:
    """Puts a q̈ estimator's state (:func:`~ftdrake.signals.causal_acceleration_step`'s, `n`
    signals: previous q̇, q̈, jerk, primed; entries after those are left alone) back to
    unprimed: its next step starts afresh (q̈ = 0 at that sample)."""
    estimator[3 * n] = 0.0


def _whole_periods(sample_period: float, period: float) -> int:
    """How many chain periods one of the payload monitor's samples spans; a ConfigError
    unless a whole number (the step samples it every that many updates, at the updates
    where the diagram samples it with the chain)."""
    ratio = sample_period / period
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-9 * ratio:
        raise ConfigError(
            f"ChainStep: bias_tracker.payload_change.sample_period_s ({sample_period} s) must "
            f"be a whole number of the chain's periods ({period} s) for the step to sample "
            "the payload monitor where the diagram does; set it to a whole multiple of the "
            "sensor's period (1 / rate_hz)")
    return every
