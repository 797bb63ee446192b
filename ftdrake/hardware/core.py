"""StationCore: the runtime chain driven by live messages, whatever carries them.

A transport (LCM: :class:`~ftdrake.hardware.station.HardwareStation`; ROS 2:
:class:`~ftdrake.hardware.ros2.station.Ros2Station`) decodes its messages and hands the
samples to :meth:`StationCore.on_joint_sample`, :meth:`~StationCore.on_wrench_sample`,
:meth:`~StationCore.on_temperature_sample` and :meth:`~StationCore.on_event_signal`, and
publishes through two hooks it implements, ``_publish_wrench(t)`` and
``_publish_contact(t, fault)`` (returns whether it published). Everything between is here,
once: the
:class:`~ftdrake.hardware.live_inputs.StreamMonitor` checks, one diagram update per
accepted, fault-free F/T sample, the fault episodes, the counts and the latencies.

Why a loop and not a Simulator with subscriber systems: a realtime Simulator samples the
subscribers' latest message at its own periodic times, so a message can be processed twice
(none arrived since the last tick) or skipped (two arrived); it also adds the Simulator's
sleep granularity to the latency. Here each message reaches a callback; every accepted,
fault-free F/T message triggers exactly one periodic update of the diagram: the k-th such
message advances a (non-realtime) Simulator to (k + ½)·period, so exactly the update at
k·period fires (diagram time is processed-message index × period, not the message's
timestamp; they agree while no message is rejected). By default that update is made by a
:class:`~ftdrake.runtime.step.ChainStep` (the same systems' code on arrays, without the
Simulator's per-update overhead; its outputs equal the diagram's, tests/runtime/test_chain_step.py);
:meth:`StationCore.use_diagram` drives the diagram itself instead, for checking.

Per F/T sample the transport publishes the wrench (``_publish_wrench``) only when the inputs
are fault-free — a stale wrench is never published as fresh — and the contact state
(``_publish_contact``) always, with its fault flag; both carry the F/T sample's timestamp.
When a stream goes silent (:meth:`StationCore.check_timeouts`), one contact state with the
fault is published at once, stamped with the detection time on the stream's clock: the last
F/T timestamp plus the wall time elapsed since it arrived.

A stream whose clock restarts (its stamps going back :data:`~.live_inputs.CLOCK_RESTART_S`
or more: a looped bag, a restarted driver) is taken up again from its new time; the chain's
q̈ estimates restart and nothing is judged for :data:`SETTLE_AFTER_DROP_S`, as after a drop;
it is said through :meth:`StationCore.warn`.

Fault episodes (the fault rising, its reason changing, the fault clearing) are kept in
``events`` and passed to `on_event`; ``summary()`` counts everything.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import math
import time

import numpy as np
from pydrake.systems.analysis import Simulator

from ..config import ChainConfig
from ..offline.recorder import UpdateRecorder, chain_outputs
from ..runtime.chain import CompensationChain
from ..runtime.step import ChainStep, bridge_acceleration, restart_acceleration
from .live_checks import RateCheck, joint_bounds
from .live_imu import IMU_VALUES, ImuPairing
from .live_inputs import StreamMonitor
from .messages import ContactState
from .overload import LoadMonitor

#: After messages were dropped (overload), the chain runs this long (s of samples) on the
#: messages that follow before its results are published again: its velocity and
#: acceleration filters and the detector's window saw a gap (the contact state says fault
#: meanwhile; nothing is judged). Meanwhile the bias tracker and the payload monitor learn
#: nothing and the detector is held released (ChainStep's ``hold``), and the q̈ estimates
#: start across any gap of the F/T stamps from the mean acceleration over it
#: (``ChainStep.bridge_gap``), so that no transient of the gap outlasts the window.
SETTLE_AFTER_DROP_S = 0.1


@dc.dataclass
class EventSignal:
    """An event input of the tracker (``tared``, ``payload_changed``) fed by messages:
    high for the one update after a message arrived."""

    fixed: object  # the diagram input's FixedInputPortValue
    pending: bool = False
    received: int = 0
    rejected: int = 0


@dc.dataclass(frozen=True)
class FaultEvent:
    """A change of the station's fault: ``kind`` "fault" (raised or its reason changed) or
    "recovered"; ``t`` on the streams' clock (s; for a timeout, the detection time),
    ``wall`` s since the station started; ``reason`` (see live_inputs.REASONS) and
    ``detail`` in words."""

    kind: str
    reason: str
    t: float
    wall: float
    detail: str

    def __str__(self) -> str:
        if self.kind == "recovered":
            return f"recovered at t={self.t:.4f} s (wall {self.wall:.3f} s)"
        return (f"fault {self.reason} at t={self.t:.4f} s (wall {self.wall:.3f} s): "
                f"{self.detail}")


def _warm_up(chain, context) -> None:
    """Runs one update of a throwaway ChainStep (the chain's state copied from `context`,
    nothing written back), so that the systems' compiled kernels are compiled or loaded
    from their cache now, at start, and not on the first F/T message: that message would
    otherwise wait seconds, and the backlog behind it be dropped as an overload."""
    step = ChainStep(chain, context)
    n = chain.compensator.n
    step.update(max(0.0, chain.detector.arm_after_s), np.zeros(6), np.zeros(2 * n),
                20.0 if chain.needs_temperature else None,
                imu=np.zeros(IMU_VALUES) if step.needs_imu else None)


class StationCore:
    """Holds the diagram, its context, the monitor and the counts (see the module).

    `chain` (a :class:`~ftdrake.config.ChainConfig`; default ``ChainConfig()``) gives the
    compensator, bias-tracker, detector, sensor-stream and robot settings (the stream's rate
    sets the update period; joint-state gravity runs on ``chain.robot``, else the robot
    embedded in the model, never on ftdrake's simulated arm by default). `n_joints` and the
    timeouts (s) configure the StreamMonitor; `temperature_timeout_s` is used only when the
    model needs the temperature.
    `events`: the tracker event inputs fed by messages (``"tared"``, ``"payload_changed"``).
    `clock` gives arrival times in s (monotonic). `on_event(FaultEvent)` is called on every
    fault change, `on_warning(str)` on every warning (kept in ``warnings``: a driver's rate
    far from ``chain.sensor.rate_hz``, ...). `joint_names` label the joints in messages.
    Joint states radians cannot be (degrees?) fault the inputs
    (:func:`~ftdrake.hardware.live_checks.joint_bounds`). When the F/T stream outruns the
    processing by more than `max_backlog_s` (s), the oldest messages are dropped and the
    inputs faulted (``overload``, naming the input and the sustained rates;
    :class:`~ftdrake.hardware.overload.LoadMonitor`, ``load``). `pair_tolerance_s` > 0 pairs
    each F/T sample with a joint state by stamp (StreamMonitor). A subclass implements
    ``_check_sources(chain)`` (raise ConfigError when the chain needs a stream it has not
    configured), ``_publish_wrench(t)`` and ``_publish_contact(t, fault)``.
    """

    def __init__(self, model, chain: ChainConfig | None, *, n_joints: int,
                 sensor_timeout_s: float, joint_state_timeout_s: float,
                 temperature_timeout_s: float, events=(), clock=time.monotonic,
                 on_event=None, max_events: int = 10_000, on_warning=None, joint_names=None,
                 max_backlog_s: float = 0.5, pair_tolerance_s: float = 0.0,
                 imu_max_skew_s: float = 0.002):
        self.n_joints = int(n_joints)
        self._build(model, chain)
        self.period = self.chain.period
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.chain.initialize(self.context)
        self.simulator.Initialize()
        self._wrench_in = self.diagram.GetInputPort("wrench_measured").FixValue(
            self.context, np.zeros(6))
        self._state_in = self.diagram.GetInputPort("joint_state").FixValue(
            self.context, np.zeros(2 * self.n_joints))
        self._temperature_in = None
        if self.chain.needs_temperature:
            self._temperature_in = self.diagram.GetInputPort("temperature").FixValue(
                self.context, np.full(1, np.nan))
        # A model that takes an IMU: its samples paired with the F/T stamps (live_imu).
        self.imu = self._imu_in = None
        self._imu_values = np.full(IMU_VALUES, np.nan)
        if self.chain.needs_imu:
            self.imu = ImuPairing(imu_max_skew_s)
            self._imu_in = self.diagram.GetInputPort("imu").FixValue(self.context,
                                                                    self._imu_values)
        self._signals = {name: EventSignal(self.diagram.GetInputPort(name).FixValue(
            self.context, [0.0])) for name in events}
        self._out = {o.port: self.diagram.GetOutputPort(o.port) for o in chain_outputs(self.chain)}
        self.recorder = None  # an UpdateRecorder after start_recording()
        # Each F/T sample updates the chain by the step (use_diagram(): by the diagram); the
        # step keeps its own state, written into `context` by chain_context().
        self._step = ChainStep(self.chain, self.context)
        _warm_up(self.chain, self.context)
        self.joint_bounds = joint_bounds(model, self.n_joints, joint_names)
        self.monitor = StreamMonitor(
            self.n_joints, sensor_timeout_s, joint_state_timeout_s,
            temperature_timeout_s if self._temperature_in is not None else None,
            joint_check=self.joint_bounds.check, pair_tolerance_s=pair_tolerance_s)
        self.monitor.on_restart = self._on_clock_restart
        self.rate_check = RateCheck(1.0 / self.period)
        self._settling = 0  # updates left whose results are not published (after drops)
        self._last_t = None  # the stamp of the last F/T sample run through the chain
        self.load = LoadMonitor(self.period, max_backlog_s)
        self.warnings: list[str] = []
        self.on_warning = on_warning
        self.clock = clock
        self.on_event = on_event
        self.started = clock()
        self.processed = 0  # F/T messages the diagram was updated with
        self.published = 0  # wrenches published
        self.contact_published = 0
        self.latencies = collections.deque(maxlen=100_000)  # s, arrival → wrench publication
        self.events = collections.deque(maxlen=max_events)
        self.fault_episodes = collections.Counter()  # reason → times the fault rose with it
        self._state = (True, "no_data")

    def _build(self, model, config: ChainConfig | None) -> None:
        """The runtime chain, its joint-state gravity on the model's (or the configured)
        robot's serial chain (there is no plant on hardware), checked against the configured
        streams."""
        self.diagram = chain = CompensationChain(model, config, n_joints=self.n_joints,
                                                 gravity="joint_state")
        chain.set_name("ftdrake_hardware")
        self.chain = chain
        self.compensator, self.tracker, self.detector = (chain.compensator, chain.tracker,
                                                         chain.detector)
        self._check_sources(chain)

    def _check_sources(self, chain) -> None:
        raise NotImplementedError

    def _publish_wrench(self, t: float) -> None:
        raise NotImplementedError

    def _publish_contact(self, t: float, fault: bool) -> bool:
        raise NotImplementedError

    def output(self, name: str) -> np.ndarray:
        """The chain's output `name` now (see CompensationChain's ports), a copy: the
        ChainStep's, or the diagram's after use_diagram()."""
        return self.value(name).copy()

    def value(self, name: str) -> np.ndarray:
        """The chain's output `name` now, not copied (the step's array, overwritten by the
        next update): for reading at once, e.g. to encode a message."""
        if self._step is not None:
            return self._step.outputs[name]
        return self._out[name].Eval(self.context)

    def chain_context(self):
        """The diagram's context holding the chain's state now (the step's written into it
        first), to evaluate any port of the chain's systems, e.g. the tracker's
        ``payload_inertia``."""
        if self._step is not None:
            self._step.write_state(self.context)
        return self.context

    def has_output(self, name: str) -> bool:
        """Whether the chain has the output port `name` (``bias`` only with the tracker ...)."""
        return name in self._out

    def start_recording(self):
        """From now on keeps every update's inputs and the chain's outputs after it; returns
        the :class:`~ftdrake.offline.recorder.UpdateRecorder` (``recorder.to_frame()``: a log
        in the layout ``replay`` reads, with the chain's output columns, one row per
        processed F/T message, ``t`` its timestamp)."""
        self.recorder = UpdateRecorder(self.chain)
        return self.recorder

    def contact_state(self, t: float, fault: bool) -> ContactState:
        """The detector's state now, stamped `t`, with `fault` (the inputs' fault) or the
        chain's own ``fault`` output once it has been updated."""
        value = self._step.outputs.__getitem__ if self._step is not None else self.value
        changed = "payload_change" in self._out and value("payload_change")[0] > 0.5
        model_fault = self.processed > 0 and value("fault")[0] > 0.5
        return ContactState(t, bool(value("contact")[0] > 0.5),
                            float(value("contact_force")[0]), bool(fault or model_fault),
                            bool(value("out_of_domain")[0] > 0.5), bool(changed))

    # -- samples ------------------------------------------------------------------------------
    def on_joint_sample(self, sample, arrival: float, problem=None) -> None:
        """A joint-state sample (JointSample, None when it failed to decode; `problem`: the
        transport's (reason, detail) for it, see StreamMonitor.on_joint)."""
        self.monitor.on_joint(sample, arrival, problem)
        self._note(None)
        self.load.busy(self.clock() - arrival)

    def on_imu_sample(self, sample, arrival: float) -> None:  # noqa: ARG002 (by stamp)
        """An IMU sample ``(t s, [f_S; ω_S] (6,))`` (None when it failed to decode)."""
        if self.imu is not None:
            self.imu.on_imu(sample)

    def on_temperature_sample(self, sample, arrival: float) -> None:
        """A temperature sample ``(t s, °C)`` (None when it failed to decode)."""
        self.monitor.on_temperature(sample, arrival)

    def on_event_signal(self, name: str, ok: bool) -> None:
        """A message on the event input `name`; `ok` False for a malformed one (counted in
        summary(), not acted on)."""
        signal = self._signals[name]
        if not ok:
            signal.rejected += 1
            return
        signal.received += 1
        signal.pending = True

    def on_wrench_sample(self, sample, arrival: float, problem=None) -> None:
        """An F/T sample (WrenchSample, None when it failed to decode; `problem`: the
        transport's (reason, detail) for a message it refused): checks, one diagram update
        when fresh, the wrench published when fault-free, the contact state always."""
        accepted = self.monitor.accepted["ft"]
        timed = problem is None and sample is not None and math.isfinite(sample.t)
        if timed and self.load.on_ft(sample.t, arrival):  # too far behind: drop the oldest
            problem = ("overload", self.load.detail())
            # After the gap the chain's filters settle before anything is judged again.
            self._settling = max(1, round(SETTLE_AFTER_DROP_S / self.period))
        fresh = self.monitor.on_wrench(sample, arrival, problem)
        t = sample.t if sample is not None and math.isfinite(sample.t) else self._stream_time()
        if self.monitor.accepted["ft"] > accepted and self.rate_check.measured_hz is None:
            self.warn(self.rate_check.on_sample(t))
        if fresh and self.imu is not None:  # NaN when no IMU sample is close: a fault
            self._imu_values = self.imu.pair(sample.t)
            if self.imu.problem is not None:  # said as the inputs' fault (live_imu)
                self.monitor.flag(*self.imu.problem)
        settling = False
        if fresh:
            settling = self._settling > 0
            self._settling -= settling
            if self._step is not None:
                self._step_chain(t, settling)
            else:
                self._advance_diagram(t)
            self.processed += 1
            if self.recorder is not None:
                self.recorder.record_values(
                    {name: self.output(name) for name in self.recorder.ports}, t,
                    self.monitor.joint_state, self.monitor.wrench,
                    self.monitor.temperature if self._temperature_in is not None else None)
            if self.value("fault")[0] <= 0.5 and not settling:
                self._publish_wrench(t)
                self.latencies.append(self.clock() - arrival)
                self.published += 1
        self.contact_published += bool(self._publish_contact(t, self.monitor.fault or settling))
        self._note(t)
        self.load.busy(self.clock() - arrival)
        if fresh and (warning := self.load.processed()) is not None:
            self.warn(warning)

    def _step_chain(self, t: float, settling: bool) -> None:
        """One update of the chain by the ChainStep, from the monitor's held inputs, for the
        F/T sample stamped `t`: across a gap of the stamps (samples lost or dropped) its q̈
        estimates are bridged; while `settling` (after drops) it holds what learns or
        judges (SETTLE_AFTER_DROP_S)."""
        gap = self._gap(t)
        if gap is not None:
            self._step.bridge_gap(gap)
        m = self.monitor
        signals = {}
        for name, signal in self._signals.items():  # high for one update after its message
            signals[name] = 1.0 if signal.pending else 0.0
            signal.pending = False
        if self.imu is not None:
            signals["imu"] = self._imu_values
        self._step.update(self.processed * self.period, m.wrench, m.joint_state,
                          m.temperature, hold=settling, **signals)

    def _on_clock_restart(self, stream: str, detail: str, t: float, arrival: float) -> None:
        """A stream's clock restarted (StreamMonitor, at the message stamped `t`): said, the
        chain's q̈ estimates start again (no gap is bridged across it) and nothing is judged
        while the chain's filters settle; the F/T stream's rate and load are measured
        afresh from this message."""
        if stream == "ft":
            self.load.restart(t, arrival)
            if self.rate_check.measured_hz is None:
                self.rate_check = RateCheck(1.0 / self.period)
        self._last_t = None
        self._settling = max(1, round(SETTLE_AFTER_DROP_S / self.period))
        if self._step is not None:
            self._step.restart_acceleration()
        else:
            for state in self._acceleration_states():
                restart_acceleration(state, self.n_joints)
            if self.compensator.needs_imu:
                restart_acceleration(self.compensator.GetMyMutableContextFromRoot(
                    self.context).get_mutable_discrete_state(
                    self.compensator._imu_estimator).get_mutable_value(), 3)
        self.warn(f"{detail}; nothing is judged for {SETTLE_AFTER_DROP_S:g} s while the "
                  "chain's filters settle")

    def _acceleration_states(self) -> list:
        """The diagram's q̈ estimator states (the compensator's; the joint-state gravity's
        with the tracker), writable in the station's context."""
        systems = [self.compensator]
        if self.tracker is not None and self.chain.gravity is not None:
            systems.append(self.chain.gravity)
        return [system.GetMyMutableContextFromRoot(self.context).get_mutable_discrete_state(
            system._estimator).get_mutable_value() for system in systems]

    def _gap(self, t: float) -> float | None:
        """The gap (s) of the F/T stamps before sample `t` run through the chain, None for
        none (within 1.5 periods); remembers `t`."""
        last, self._last_t = self._last_t, t
        return t - last if last is not None and t - last > 1.5 * self.period else None

    def _advance_diagram(self, t: float) -> None:
        """One update of the chain by the Drake diagram: inputs fixed, the Simulator advanced
        past the next periodic update (the module docstring); across a gap of the stamps its
        q̈ estimators bridged as the step's (the settle window's hold is the step's only)."""
        gap = self._gap(t)
        if gap is not None:
            v = self.monitor.joint_state[self.n_joints:]
            for state in self._acceleration_states():
                bridge_acceleration(state, v, gap, self.period)
        self._wrench_in.GetMutableData().get_mutable_value().SetFromVector(self.monitor.wrench)
        self._state_in.GetMutableData().get_mutable_value().SetFromVector(self.monitor.joint_state)
        if self._temperature_in is not None:
            self._temperature_in.GetMutableData().get_mutable_value().SetFromVector(
                [self.monitor.temperature])
        if self._imu_in is not None:
            self._imu_in.GetMutableData().get_mutable_value().SetFromVector(self._imu_values)
        for signal in self._signals.values():  # high for one update after its message
            signal.fixed.GetMutableData().get_mutable_value().SetFromVector(
                [1.0 if signal.pending else 0.0])
            signal.pending = False
        self.simulator.AdvanceTo((self.processed + 0.5) * self.period)

    def use_diagram(self) -> None:
        """Updates the chain per F/T sample through the Drake diagram and its Simulator (the
        reference: what the ChainStep reproduces, at several times its cost) instead of the
        ChainStep; for checking. Only before the first processed sample."""
        if self.processed:
            raise RuntimeError("StationCore.use_diagram: the chain has already been updated "
                               f"{self.processed} times by the step; call it before the first "
                               "F/T sample")
        self._step = None

    def warn(self, warning: str | None) -> None:
        """Keeps `warning` (None: nothing) in ``warnings`` and passes it to `on_warning`."""
        if warning is None:
            return
        self.warnings.append(warning)
        if self.on_warning is not None:
            self.on_warning(warning)

    def flag_missing(self, stream: str, reason: str, detail: str) -> None:
        """Faults the inputs because `stream` ("ft", "joint") has no message yet for a cause
        a transport found outside any message (e.g. a publisher of another type on its
        topic); said until the stream's first accepted message."""
        m = self.monitor
        if m.last_time(stream) is not None or m.missing.get(stream) == (reason, detail):
            return
        flagged = {r for r, _ in m.missing.values()}
        m.missing[stream] = (reason, detail)
        if m.reason == "no_data" or m.reason in flagged:
            m.fault, m.reason, m.detail = True, reason, detail
            self._note(None)

    def check_timeouts(self) -> None:
        """Raises the fault when a stream went silent, publishing it at once."""
        was = self.monitor.fault
        now = self.clock()
        if self.monitor.check_timeouts(now) and not was:
            t = self._stream_time(now)
            self.contact_published += bool(self._publish_contact(t, True))
            self._note(t, now)

    def _stream_time(self, now: float | None = None) -> float:
        """Now on the streams' clock: the last F/T timestamp + wall time since it arrived."""
        t, arrival = self.monitor.last_time("ft"), self.monitor.last_arrival("ft")
        if t is None:
            return 0.0
        return t + ((self.clock() if now is None else now) - arrival)

    def _note(self, t: float | None, now: float | None = None) -> None:
        """Records a fault change (rise, reason change, recovery) as a FaultEvent."""
        m = self.monitor
        state = (m.fault, m.reason)
        if state == self._state:
            return
        was_fault = self._state[0]
        self._state = state
        if not m.fault and not was_fault:
            return
        now = self.clock() if now is None else now
        t = self._stream_time(now) if t is None else t
        if m.fault:
            self.fault_episodes[m.reason] += 1
            event = FaultEvent("fault", m.reason, t, now - self.started, m.detail)
        else:
            event = FaultEvent("recovered", "", t, now - self.started, "")
        self.events.append(event)
        if self.on_event is not None:
            self.on_event(event)

    # -- reporting ----------------------------------------------------------------------------
    def latency_percentiles(self):
        """(p50, p99) in s of arrival → publication, over the last 100 000 publications."""
        lat = np.asarray(self.latencies)
        if not len(lat):
            return (np.nan, np.nan)
        return (float(np.percentile(lat, 50)), float(np.percentile(lat, 99)))

    def summary(self) -> dict:
        """Counts so far: messages received/accepted per stream, rejected per reason, F/T
        messages processed, wrenches and contact states published, fault episodes per reason,
        latency p50/p99 (ms), the current fault and, with an IMU, its counts (``imu``:
        accepted, rejected per reason, F/T samples unpaired)."""
        m = self.monitor
        p50, p99 = self.latency_percentiles()
        return {
            "received": dict(m.received), "accepted": dict(m.accepted),
            "rejected": dict(m.rejected), "processed": self.processed,
            "published_wrench": self.published, "published_contact": self.contact_published,
            "fault_episodes": dict(self.fault_episodes),
            "signals": {name: {"received": signal.received, "rejected": signal.rejected}
                        for name, signal in self._signals.items()},
            "latency_ms": {"p50": p50 * 1e3, "p99": p99 * 1e3},
            "fault": bool(m.fault), "reason": m.reason,
            "rate_hz": {"configured": 1.0 / self.period, "measured": self.rate_check.measured_hz},
            "warnings": list(self.warnings),
            "clock_restarts": dict(m.restarts),
            "load": self.load.summary(),
            **({"imu": self.imu.counts()} if self.imu is not None else {}),
        }
