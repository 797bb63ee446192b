"""The hardware station: the runtime chain, driven by live LCM messages.

    joint state ──► StreamMonitor ──► joint_state ──┐
    (iiwa/panda/robot_state)  (checks, counts)      ▼
    F/T ──────────► StreamMonitor ──► wrench_measured ─► CompensationChain
                                                               │
                         lcmt_force_torque  ◄── wrench_compensated
                         lcmt_drake_signal  ◄── contact, contact_force, fault, out_of_domain

The diagram is :class:`~ftdrake.runtime.chain.CompensationChain`, the one
:func:`ftdrake.sim.station.build_station` puts in the loop, built from the same scenario
(``compensator``, ``bias_tracker``, ``detector``); with ``track_payload`` the tracker's
``gravity_S`` and ``motion_S`` come from the joint state through the scenario robot's chain
(:class:`~ftdrake.runtime.joint_gravity.JointStateGravity`). The same messages therefore give
the same numbers as in simulation (``tests/test_live_end_to_end.py`` checks it to 1e-9). This
module imports nothing of the simulation.

Why a loop and not a Simulator with LcmSubscriberSystems: a realtime Simulator samples the
subscribers' latest message at its own periodic times, so a message can be processed twice
(none arrived since the last tick) or skipped (two arrived); it also adds the Simulator's
sleep granularity to the latency. Here each message reaches a callback; every accepted,
fault-free F/T message triggers exactly one periodic update of the diagram: the k-th such
message advances a (non-realtime) Simulator to (k + ½)·period, so exactly the update at
k·period fires (diagram time is processed-message index × period, not the message's
timestamp; they agree while no message is rejected).

Published per F/T message: the compensated wrench (``lcmt_force_torque`` on
``external_wrench_channel``) only when the inputs are fault-free — a stale wrench is never
published as fresh — and the contact state (``lcmt_drake_signal`` on ``contact_channel``)
always, with its fault flag. Both carry the F/T message's timestamp. When a stream goes
silent (``spin_once`` checks the timeouts), one contact state with ``fault = 1`` is published
at once, stamped with the detection time on the stream's clock: the last F/T timestamp plus
the wall time elapsed since it arrived.

Fault episodes (the fault rising, its reason changing, the fault clearing) are kept in
``events`` and passed to `on_event` (``serve`` prints them); ``summary()`` counts everything.
"""

from __future__ import annotations

import collections
import dataclasses as dc
import functools
import struct
import time

import numpy as np
from pydrake.systems.analysis import Simulator

from ..config import ScenarioConfig
from ..errors import ConfigError
from ..runtime.chain import CompensationChain
from .config import HardwareConfig
from .live_inputs import RobotStatePairer, StreamMonitor
from .messages import (
    PAYLOAD_COORD,
    TARE_COORD,
    ContactState,
    decode_event,
    decode_joint_state,
    decode_temperature,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_wrench,
)
from .transport import open_lcm


@dc.dataclass
class _EventSignal:
    """An event input of the tracker fed by LCM messages (see HardwareConfig)."""

    coord: str
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


class HardwareStation:
    """Holds the diagram, its context, the monitor and the LCM subscriptions.

    `scenario` gives the compensator, bias-tracker, detector and sensor settings (the
    sensor's rate sets the update period; the tracker reads its drift). `lcm`: an LCM URL, an
    ``lcm.LCM``, a ``DrakeLcm`` or a transport (default: ``config.lcm_url``). `clock` gives
    arrival times in s (monotonic). `on_event(FaultEvent)` is called on every fault change.
    """

    def __init__(self, config: HardwareConfig, model, scenario: ScenarioConfig | None = None,
                 lcm=None, *, clock=time.monotonic, on_event=None, max_events: int = 10_000):
        self.config = config.validate()
        self.scenario = (scenario or ScenarioConfig()).validate()
        self.lcm = open_lcm(lcm if lcm is not None else config.lcm_url)
        self.period = 1.0 / self.scenario.sensor.spec().rate_hz
        self._build(model)
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.chain.initialize(self.context)
        self.simulator.Initialize()
        self._wrench_in = self.diagram.GetInputPort("wrench_measured").FixValue(
            self.context, np.zeros(6))
        self._state_in = self.diagram.GetInputPort("joint_state").FixValue(
            self.context, np.zeros(2 * config.n_joints))
        self._temperature_in = None
        if self.chain.needs_temperature:
            self._temperature_in = self.diagram.GetInputPort("temperature").FixValue(
                self.context, np.full(1, np.nan))
        # The tracker's event inputs (tared, payload_changed): high for the one update after
        # a message on their channel.
        self._signals = {name: _EventSignal(coord, self.diagram.GetInputPort(name).FixValue(
            self.context, [0.0])) for name, coord, channel in self._event_channels() if channel}
        self._out = {name: self.diagram.GetOutputPort(name) for name in (
            "wrench_compensated", "fault", "out_of_domain", "contact", "contact_force")}
        self.monitor = StreamMonitor(
            config.n_joints, config.sensor_timeout_s, config.joint_state_timeout_s,
            config.temperature_timeout_s if self._temperature_in is not None else None)
        self.clock = clock
        self.on_event = on_event
        self.started = clock()
        self.processed = 0  # F/T messages the diagram was updated with
        self.published = 0  # external wrenches published
        self.contact_published = 0
        self.latencies = collections.deque(maxlen=100_000)  # s, arrival → wrench publication
        self.events = collections.deque(maxlen=max_events)
        self.fault_episodes = collections.Counter()  # reason → times the fault rose with it
        self._state = (True, "no_data")
        self._pairer = None
        kind = config.joint_state_type
        if kind == "robot_state":
            self._pairer = RobotStatePairer()
            self.lcm.subscribe(config.joint_state_channel, lambda d: self._on_half("q", d))
            self.lcm.subscribe(config.velocity_channel, lambda d: self._on_half("v", d))
        else:
            self.lcm.subscribe(config.joint_state_channel, self._on_joint)
        self.lcm.subscribe(config.ft_channel, self._on_wrench)
        if self._temperature_in is not None:
            self.lcm.subscribe(config.temperature_channel, self._on_temperature)
        for name, _, channel in self._event_channels():
            if channel:
                self.lcm.subscribe(channel, functools.partial(self._on_event_signal, name))

    def _build(self, model) -> None:
        """The runtime chain, its joint-state gravity on the scenario robot's serial chain
        (there is no plant on hardware), checked against the hardware channels."""
        self.diagram = chain = CompensationChain(
            model, self.scenario, period=self.period, n_joints=self.config.n_joints,
            gravity="joint_state")
        chain.set_name("ftdrake_hardware")
        self.chain = chain
        self.compensator, self.tracker, self.detector = (chain.compensator, chain.tracker,
                                                         chain.detector)
        if self.config.tare_channel and not chain.HasInputPort("tared"):
            raise ConfigError("hardware.tare_channel: a re-tare goes to the bias tracker; "
                              "enable scenario.bias_tracker or leave the channel empty")
        if self.config.payload_channel and not chain.HasInputPort("payload_changed"):
            raise ConfigError("hardware.payload_channel: a grasp goes to the bias tracker's "
                              "payload estimate; set scenario.bias_tracker.enabled and "
                              "track_payload, or leave the channel empty")
        if chain.needs_temperature and not self.config.temperature_channel:
            raise ConfigError(
                "hardware.temperature_channel: the model was trained with the sensor "
                "temperature; name the LCM channel that carries it (lcmt_drake_signal, "
                "one value in °C)")

    # -- message callbacks ------------------------------------------------------------------
    def _on_joint(self, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_joint_state, self.config.joint_state_type, data)
        self.monitor.on_joint(sample, arrival)
        self._note(None)

    def _on_half(self, half: str, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_joint_state, "robot_state", data)
        if sample is None:
            self.monitor.on_joint(None, arrival)
            self._note(None)
            return
        joined = self._pairer.add(half, sample)
        for detail in self._pairer.dropped:
            self.monitor.count_unpaired(detail)
        self._pairer.dropped.clear()
        if joined is not None:
            self.monitor.on_joint(joined, arrival)
            self._note(None)

    def _on_temperature(self, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_temperature, data)
        self.monitor.on_temperature(sample, arrival)

    def _event_channels(self):
        c = self.config
        return (("tared", TARE_COORD, c.tare_channel),
                ("payload_changed", PAYLOAD_COORD, c.payload_channel))

    def _on_event_signal(self, name: str, data: bytes):
        signal = self._signals[name]
        if _decoded(decode_event, data, signal.coord) is None:
            signal.rejected += 1  # malformed: counted in summary(), not acted on
            return
        signal.received += 1
        signal.pending = True

    def _on_wrench(self, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_wrench, data)
        fresh = self.monitor.on_wrench(sample, arrival)
        t = sample.t if sample is not None and np.isfinite(sample.t) else self._stream_time()
        if fresh:
            self._wrench_in.GetMutableData().get_mutable_value().SetFromVector(self.monitor.wrench)
            self._state_in.GetMutableData().get_mutable_value().SetFromVector(self.monitor.joint_state)
            if self._temperature_in is not None:
                self._temperature_in.GetMutableData().get_mutable_value().SetFromVector(
                    [self.monitor.temperature])
            for signal in self._signals.values():  # high for one update after its message
                signal.fixed.GetMutableData().get_mutable_value().SetFromVector(
                    [1.0 if signal.pending else 0.0])
                signal.pending = False
            self.simulator.AdvanceTo((self.processed + 0.5) * self.period)
            self.processed += 1
            if self._out["fault"].Eval(self.context)[0] <= 0.5:
                external = self._out["wrench_compensated"].Eval(self.context)
                self.lcm.publish(self.config.external_wrench_channel,
                                 encode_wrench(t, external))
                self.latencies.append(self.clock() - arrival)
                self.published += 1
        self._publish_contact(t, self.monitor.fault)
        self._note(t)

    def _publish_contact(self, t: float, fault: bool) -> None:
        out = self._out
        state = ContactState(t, out["contact"].Eval(self.context)[0] > 0.5,
                             float(out["contact_force"].Eval(self.context)[0]), bool(fault),
                             out["out_of_domain"].Eval(self.context)[0] > 0.5)
        self.lcm.publish(self.config.contact_channel, encode_contact_state(state))
        self.contact_published += 1

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

    # -- running ------------------------------------------------------------------------------
    def spin_once(self, timeout_ms: int = 1) -> int:
        """Handles pending messages (waiting up to `timeout_ms` for one), then checks the
        timeouts, publishing the fault at once when a stream went silent. Returns the number
        of messages handled."""
        handled = self.lcm.handle(timeout_ms)
        was = self.monitor.fault
        now = self.clock()
        if self.monitor.check_timeouts(now) and not was:
            t = self._stream_time(now)
            self._publish_contact(t, True)
            self._note(t, now)
        return handled

    def latency_percentiles(self):
        """(p50, p99) in s of arrival → publication, over the last 100 000 publications."""
        lat = np.asarray(self.latencies)
        if not len(lat):
            return (np.nan, np.nan)
        return (float(np.percentile(lat, 50)), float(np.percentile(lat, 99)))

    def summary(self) -> dict:
        """Counts so far: messages received/accepted per stream, rejected per reason, F/T
        messages processed, wrenches and contact states published, fault episodes per reason,
        latency p50/p99 (ms), and the current fault."""
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
        }


def _decoded(decode, *args):
    """``decode(*args)``, or None for a message with a wrong fingerprint or truncated."""
    try:
        return decode(*args)
    except (ValueError, struct.error):
        return None


def build_hardware_station(config: HardwareConfig, model, scenario: ScenarioConfig | None = None,
                           lcm=None, **kwargs):
    """Returns (diagram, handles): handles["station"] is the HardwareStation to spin."""
    station = HardwareStation(config, model, scenario, lcm, **kwargs)
    return station.diagram, {"station": station, "monitor": station.monitor,
                             "context": station.context}


def measure_latency(model, scenario: ScenarioConfig | None = None, n_messages: int = 2000,
                    seed: int = 0, q_range=None):
    """In-process (memq://) latency of arrival → publication of the compensated wrench.

    Publishes `n_messages` joint + F/T pairs one at a time and spins the station after
    each; returns {"p50_s", "p99_s", "processed", "published"}. In-process, so it measures the
    station's own work (decode, checks, compensator, tracker, detector, encode, publish), not
    the network. Joint positions are drawn uniformly in `q_range` ((lo, hi) arrays; default
    ±1 rad), velocities small.
    """
    rng = np.random.default_rng(seed)
    n = int(model.n_joints_)
    lo, hi = q_range if q_range is not None else (-np.ones(n), np.ones(n))
    config = HardwareConfig(lcm_url="memq://", n_joints=n, sensor_timeout_s=1.0,
                            joint_state_timeout_s=1.0)
    station = HardwareStation(config, model, scenario, "memq://")
    for k in range(n_messages):
        t = station.period * (k + 1)
        station.lcm.publish(config.joint_state_channel, encode_joint_state(
            "iiwa_status", t, rng.uniform(lo, hi), rng.normal(scale=0.1, size=n)))
        station.lcm.publish(config.ft_channel, encode_wrench(t, rng.normal(size=6)))
        station.spin_once(0)
    p50, p99 = station.latency_percentiles()
    return {"p50_s": p50, "p99_s": p99, "processed": station.processed,
            "published": station.published}
