"""The hardware station: the runtime chain, driven by live LCM messages.

    joint state ──► StreamMonitor ──► joint_state ──┐
    (iiwa/panda/robot_state)  (checks, counts)      ▼
    F/T ──────────► StreamMonitor ──► wrench_measured ─► CompensationChain
                                                               │
    FT_WRENCH_CONTACT      lcmt_force_torque ◄── wrench_contact
    FT_WRENCH_COMPENSATED  lcmt_force_torque ◄── wrench_compensated
    FT_BIAS                lcmt_force_torque ◄── bias (with the tracker)
    FT_PAYLOAD             lcmt_drake_signal ◄── payload (with track_payload)
    FT_CONTACT_STATE       lcmt_drake_signal ◄── contact, contact_force, fault, out_of_domain,
                                                  payload_change

The diagram is :class:`~ftdrake.runtime.chain.CompensationChain`, the one
:func:`ftdrake.sim.station.build_station` puts in the loop, built from a
:class:`~ftdrake.config.ChainConfig` (``compensator``, ``bias_tracker``, ``detector``,
``sensor``, ``robot``); with ``track_payload`` the tracker's ``gravity_S`` and ``motion_S``
come from the joint state through the serial chain of the robot embedded in the model (or of
``chain.robot``; :class:`~ftdrake.runtime.joint_gravity.JointStateGravity`). The same
messages therefore give the same numbers as in simulation
(``tests/hardware/test_live_end_to_end.py`` checks it to 1e-9). This module imports nothing of
the simulation.

The message-driven loop, its checks, fault episodes and counts are
:class:`~ftdrake.hardware.core.StationCore`'s (shared with the ROS 2 station); this class adds
the LCM side. Published per F/T message (the outputs :data:`ftdrake.conventions.PUBLISHED`,
the ROS 2 station's, on the channels :meth:`HardwareConfig.output_channel` names): the
wrenches and the payload only when the inputs are fault-free — a stale wrench is never
published as fresh — and the contact state always, with its fault flag. All carry the F/T
message's timestamp. When a stream goes silent (``spin_once`` checks the timeouts), one
contact state with ``fault = 1`` is published at once, stamped with the detection time on the
stream's clock.

Per message the work is done by a compiled loop whenever the station is in its ordinary
state (:class:`~ftdrake.hardware.lcm.fast.path.CompiledPath`: liblcm's wait and publish,
the messages' bytes, the checks, the chain's update and the outputs in one call without the
GIL), and by the Python callbacks above otherwise; anything unusual in a message goes to
them, so the two publish and count the same (``lcm.compiled_path``;
``summary()["compiled_path"]`` says whether it runs and why not).

Fault episodes are kept in ``events`` and passed to `on_event` (``serve`` prints them);
``summary()`` counts everything.
"""

from __future__ import annotations

import functools
import struct
import time

import numpy as np

from ..config import ChainConfig
from ..conventions import OUTPUTS, PUBLISHED
from ..errors import ConfigError
from .config import JOINT_STATE_TYPES, HardwareConfig, rate_levers
from .core import FaultEvent, StationCore  # noqa: F401 (FaultEvent: its home before core)
from .lcm.fast.liblcm import LiblcmTransport
from .lcm.fast.path import BUDGET_S, CompiledPath
from .live_checks import check_joint_count, lcm_decode_problem, lcm_type_found
from .live_inputs import REASONS, RobotStatePairer
from .messages import (
    CONTACT_COORDS,
    PAYLOAD_COORD,
    TARE_COORD,
    decode_event,
    decode_imu,
    decode_joint_state,
    decode_temperature,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_payload,
    encode_status,
    encode_wrench,
)
from .overload import CpuMeter
from .threads import NewThreads, pin_process
from .transport import open_lcm


class HardwareStation(StationCore):
    """The LCM station: StationCore fed by the LCM subscriptions of `config`.

    `chain` (a :class:`~ftdrake.config.ChainConfig`) gives the compensator, bias-tracker,
    detector, sensor-stream and robot settings (the stream's rate sets the update period;
    the tracker reads its drift). `lcm`: an LCM URL, an
    ``lcm.LCM``, a ``DrakeLcm`` or a transport (default: ``config.lcm_url``). `clock` gives
    arrival times in s (monotonic). `on_event(FaultEvent)` is called on every fault change,
    `on_warning(str)` on every warning. A message that does not decode as the configured type
    faults the inputs with ``wrong_type``, naming the channel, the type found and the one
    expected; ``config.n_joints`` other than the model's is a ConfigError naming the key.
    With ``config.cpu_affinity`` set, building the station keeps every thread of this
    process on those CPUs (:func:`~ftdrake.hardware.threads.pin_process`).
    """

    def __init__(self, config: HardwareConfig, model, chain: ChainConfig | None = None,
                 lcm=None, *, clock=time.monotonic, on_event=None, max_events: int = 10_000,
                 on_warning=None):
        self.config = config.validate()
        check_joint_count(model, config.n_joints, "lcm.n_joints",
                          "the robot's joint count (the model's joints, in its order)")
        # URLs opened by liblcm, for the compiled path (which runs on the real clock only).
        native = config.compiled_path and clock is time.monotonic
        self.lcm = open_lcm(lcm if lcm is not None else config.lcm_url, native=native)
        # The compiled path reads only a liblcm connection no other station reads (opened
        # here from a URL, or by serve for this station).
        self.owns_lcm = getattr(self.lcm, "owner", False) is None
        if self.owns_lcm:
            self.lcm.owner = self
        # The outputs' connection: publish-only, so it never receives (config.output_url).
        self._sender = (open_lcm(config.output_url, "hardware.output_url", native=native)
                        if config.output_url and config.output_url != config.lcm_url
                        else self.lcm)
        self._coords = {name: coord for name, coord, channel in self._event_channels()
                        if channel}
        super().__init__(model, chain, n_joints=config.n_joints,
                         sensor_timeout_s=config.sensor_timeout_s,
                         joint_state_timeout_s=config.joint_state_timeout_s,
                         temperature_timeout_s=config.temperature_timeout_s,
                         events=tuple(self._coords), clock=clock,
                         on_event=self._on_fault_change, max_events=max_events,
                         on_warning=on_warning, max_backlog_s=config.max_backlog_s,
                         pair_tolerance_s=config.pair_tolerance_s,
                         imu_max_skew_s=config.imu_max_skew_s)
        self.load.levers = rate_levers(config, "lcm")  # its warnings name the keys to change
        self.monitor.pair_key = "lcm.pair_tolerance_s"  # its stamp gaps name the key
        if self.imu is not None:  # its faults name the keys to change
            self.imu.source = f"lcm.imu_channel {config.imu_channel!r}"
            self.imu.skew_key = "lcm.imu_max_skew_s"
        self._user_on_event = on_event
        self.status_published = 0
        self._last_status = self.clock()
        # The process's CPU between two periodic statuses (status()'s cpu_* values).
        self.cpu_meter = CpuMeter(self._last_status, self.processed)
        # The published outputs (conventions.PUBLISHED) with an LCM message of their own; the
        # others are values of the contact state (_publish_contact).
        # Only those listed in config.outputs.
        self._own_channel = [(port, config.output_channel(port)) for port in PUBLISHED
                             if self.has_output(port) and OUTPUTS[port].lcm_field is None
                             and port in config.outputs]
        self._contact_out = any(port in config.outputs for port in CONTACT_COORDS)
        self._contact_channel = config.output_channel("contact")
        self._pairer = None
        with NewThreads() as receivers:  # LCM's receive thread starts on the first subscription
            self._subscribe(config)
        if config.yield_io_threads:
            receivers.yield_to_caller()
        if config.cpu_affinity:
            pin_process(config.cpu_affinity)
        if self.owns_lcm:  # liblcm's: a message cut short is said
            self.lcm.on_warning = self.warn
        self.compiled = CompiledPath(self, 0.0 if config.batch_period_s > 0 else BUDGET_S)

    def _subscribe(self, config: HardwareConfig) -> None:
        """The station's subscriptions, its receive thread started (udpm://)."""
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
        if self.imu is not None:
            self.lcm.subscribe(config.imu_channel, self._on_imu)
        for name in self._coords:
            self.lcm.subscribe(getattr(config, _EVENT_FIELDS[name]),
                               functools.partial(self._on_event_signal, name))
        self.lcm.start_receiving()

    def _check_sources(self, chain) -> None:
        if self.config.tare_channel and not chain.HasInputPort("tared"):
            raise ConfigError("hardware.tare_channel: a re-tare goes to the bias tracker; "
                              "enable chain.bias_tracker or leave the channel empty")
        if self.config.payload_channel and not chain.HasInputPort("payload_changed"):
            raise ConfigError("hardware.payload_channel: a grasp goes to the bias tracker's "
                              "payload estimate; set chain.bias_tracker.enabled and "
                              "track_payload, or leave the channel empty")
        if chain.needs_imu and not self.config.imu_channel:
            raise ConfigError(
                "hardware.imu_channel: the model takes an IMU at the sensor; name the LCM "
                "channel that carries it (lcmt_drake_signal, messages.encode_imu: f_S in "
                "m/s² and ω_S in rad/s, in S)")
        if chain.needs_temperature and not self.config.temperature_channel:
            raise ConfigError(
                "hardware.temperature_channel: the model was trained with the sensor "
                "temperature; name the LCM channel that carries it (lcmt_drake_signal, "
                "one value in °C)")

    # -- message callbacks ------------------------------------------------------------------
    def _on_joint(self, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_joint_state, self.config.joint_state_type, data)
        self.on_joint_sample(sample, arrival, None if sample is not None else self._joint_problem(
            self.config.joint_state_channel, "joint_state_channel", data))

    def _joint_problem(self, channel: str, key: str, data: bytes):
        """(reason, detail) of a joint-state message that did not decode (see live_checks);
        another joint-state type than the configured one names lcm.joint_state_type."""
        kind = self.config.joint_state_type
        reason, detail = lcm_decode_problem("joint-state", channel, f"drake.lcmt_{kind}",
                                            f"lcm.{key}", data)
        found = lcm_type_found(data)
        other = found[len("drake.lcmt_"):] if found else None
        if reason == "wrong_type" and other in JOINT_STATE_TYPES:
            detail += f" (or, if it is this robot's, set lcm.joint_state_type: {other})"
        return reason, detail

    def _on_half(self, half: str, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_joint_state, "robot_state", data)
        if sample is None:
            key = "joint_state_channel" if half == "q" else "velocity_channel"
            self.on_joint_sample(None, arrival, self._joint_problem(
                getattr(self.config, key), key, data))
            return
        joined = self._pairer.add(half, sample)
        for detail in self._pairer.dropped:
            self.monitor.count_unpaired(detail)
        self._pairer.dropped.clear()
        if joined is not None:
            self.on_joint_sample(joined, arrival)

    def _on_imu(self, data: bytes):
        self.on_imu_sample(_decoded(decode_imu, data), self.clock())

    def _on_temperature(self, data: bytes):
        arrival = self.clock()
        self.on_temperature_sample(_decoded(decode_temperature, data), arrival)

    def _event_channels(self):
        c = self.config
        return (("tared", TARE_COORD, c.tare_channel),
                ("payload_changed", PAYLOAD_COORD, c.payload_channel))

    def _on_event_signal(self, name: str, data: bytes):
        self.on_event_signal(name, _decoded(decode_event, data, self._coords[name]) is not None)

    def _on_wrench(self, data: bytes):
        arrival = self.clock()
        sample = _decoded(decode_wrench, data)
        if sample is None:
            self.on_wrench_sample(None, arrival, lcm_decode_problem(
                "F/T", self.config.ft_channel, "drake.lcmt_force_torque", "lcm.ft_channel",
                data))
            return
        self.on_wrench_sample(sample, arrival)

    def _publish_wrench(self, t: float) -> None:
        """The published outputs of their own channel (wrenches, the payload) the chain has."""
        for port, channel in self._own_channel:
            data = (encode_payload(t, self.value(port)) if port == "payload"
                    else encode_wrench(t, self.value(port)))
            self._sender.publish(channel, data)

    def _publish_contact(self, t: float, fault: bool) -> bool:
        if not self._contact_out:
            return False
        self._sender.publish(self._contact_channel,
                             encode_contact_state(self.contact_state(t, fault)))
        return True

    def _on_fault_change(self, event) -> None:
        self.publish_status()
        if self._user_on_event is not None:
            self._user_on_event(event)

    def status(self) -> dict:
        """The values of the status message now (messages.STATUS_COORDS)."""
        m, load = self.monitor, self.load
        reason = (0 if not m.fault else -1 if m.reason not in REASONS
                  else REASONS.index(m.reason) + 1)
        return {"fault": m.fault, "reason": reason, "overload": load.overloaded,
                "input_hz": load.input_hz, "sustained_hz": load.sustained_hz,
                "backlog_ms": load.backlog_s * 1e3, "lost_ft": load.lost,
                "dropped_ft": load.dropped, "processed": self.processed,
                "published": self.published,
                **{f"cpu_{k}": v for k, v in self.cpu_meter.latest.items()}}

    def summary(self) -> dict:
        """StationCore's counts, with ``compiled_path``: whether the compiled loop runs, why
        not, and what it handled (:meth:`CompiledPathBase.summary
        <ftdrake.hardware.fast.path.CompiledPathBase.summary>`)."""
        return {**super().summary(), "compiled_path": self.compiled.summary()}

    def close(self) -> None:
        """Stops a compile of the compiled loop still running, and closes the station's
        own liblcm connections (not one given to it by another station)."""
        self.compiled.close()
        if self.owns_lcm:
            self.lcm.close()
        if self._sender is not self.lcm and isinstance(self._sender, LiblcmTransport):
            self._sender.close()  # opened here, from output_url

    def publish_status(self) -> None:
        """Publishes the status message now, stamped on the streams' clock."""
        self._sender.publish(self.config.status_channel,
                         encode_status(self._stream_time(), self.status()))
        self.status_published += 1

    # -- running ------------------------------------------------------------------------------
    def spin_once(self, timeout_ms: int = 1) -> int:
        """Handles pending messages (waiting up to `timeout_ms` for one; by the compiled
        loop for up to its budget when it may run), then checks the timeouts, publishing the
        fault at once when a stream went silent, and publishes the periodic status. Returns
        the number of messages handled."""
        if self.compiled.why_not is None and self.compiled.ready():
            handled = self.compiled.spin(timeout_ms)
        else:
            handled = self.lcm.handle(timeout_ms)
        self.check_timeouts()
        now = self.clock()
        if now - self._last_status >= self.config.status_period_s:
            self._last_status = now
            self.cpu_meter.reading(now, self.processed)
            self.publish_status()
        return handled


_EVENT_FIELDS = {"tared": "tare_channel", "payload_changed": "payload_channel"}


def _decoded(decode, *args):
    """``decode(*args)``, or None for a message with a wrong fingerprint or truncated."""
    try:
        return decode(*args)
    except (ValueError, struct.error):
        return None


def build_hardware_station(config: HardwareConfig, model, chain: ChainConfig | None = None,
                           lcm=None, **kwargs):
    """Returns (diagram, handles): handles["station"] is the HardwareStation to spin."""
    station = HardwareStation(config, model, chain, lcm, **kwargs)
    return station.diagram, {"station": station, "monitor": station.monitor,
                             "context": station.context}


def measure_latency(model, chain: ChainConfig | None = None, n_messages: int = 2000,
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
    station = HardwareStation(config, model, chain, "memq://")
    for k in range(n_messages):
        t = station.period * (k + 1)
        station.lcm.publish(config.joint_state_channel, encode_joint_state(
            "iiwa_status", t, rng.uniform(lo, hi), rng.normal(scale=0.1, size=n)))
        station.lcm.publish(config.ft_channel, encode_wrench(t, rng.normal(size=6)))
        station.spin_once(0)
    p50, p99 = station.latency_percentiles()
    return {"p50_s": p50, "p99_s": p99, "processed": station.processed,
            "published": station.published}
