"""A lean, message-driven hardware station: one compensator update per accepted F/T message.

Why a loop and not a Simulator with LcmSubscriberSystems: a realtime Simulator samples the
subscribers' latest message at its own periodic times, so a message can be processed twice
(none arrived since the last tick) or skipped (two arrived); it also adds the Simulator's
sleep granularity to the latency. Here `DrakeLcm.HandleSubscriptions` delivers each message
to a callback; every accepted F/T message triggers exactly one periodic update of the
unchanged ``CompensatorSystem`` + ``ContactDetector`` diagram: the k-th accepted message
advances a (non-realtime) Simulator to (k + ½)·period, so exactly the update at k·period
fires (diagram time is message index × period, not the message's timestamp; at 1 kHz they
agree when no message is rejected), and the result is published at once.

Published per F/T message: the external wrench (``lcmt_force_torque``, only when the inputs
are fault-free: a stale wrench is never published as fresh) and the contact state
(``lcmt_drake_signal``, always, with its fault flag).

Status: first cut; untested against latency goals (see ``measure_latency``).
"""

from __future__ import annotations

import struct
import time

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from ftdrake import CompensatorSystem, ContactDetector, DetectorConfig

from .config import HardwareConfig
from .live_inputs import StreamMonitor
from .messages import (
    ContactState,
    decode_joint_state,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_wrench,
)


class HardwareStation:
    """Holds the diagram, its context, the monitor and the LCM subscriptions."""

    def __init__(self, config: HardwareConfig, model, detector_config, lcm=None,
                 period: float = 0.001):
        self.config = config.validate()
        self.lcm = lcm if lcm is not None else DrakeLcm(config.lcm_url)
        builder = DiagramBuilder()
        self.compensator = builder.AddNamedSystem(
            "compensator", CompensatorSystem(model, period, n_joints=config.n_joints))
        self.detector = builder.AddNamedSystem("detector", ContactDetector(detector_config, period))
        builder.Connect(self.compensator.GetOutputPort("wrench_external"),
                        self.detector.GetInputPort("wrench_external"))
        builder.ExportInput(self.compensator.GetInputPort("wrench_measured"), "wrench_measured")
        builder.ExportInput(self.compensator.GetInputPort("joint_state"), "joint_state")
        for system, port in ((self.compensator, "wrench_external"), (self.compensator, "fault"),
                             (self.compensator, "out_of_domain"), (self.detector, "contact"),
                             (self.detector, "contact_force")):
            builder.ExportOutput(system.GetOutputPort(port), port)
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.period = float(period)
        self._wrench_in = self.diagram.GetInputPort("wrench_measured")
        self._state_in = self.diagram.GetInputPort("joint_state")
        self.monitor = StreamMonitor(config.n_joints, config.sensor_timeout_s,
                                     config.joint_state_timeout_s)
        self.processed = 0
        self.published = 0
        self.latencies = []  # s, arrival → wrench publication
        self.lcm.Subscribe(config.joint_state_channel, self._on_joint)
        self.lcm.Subscribe(config.ft_channel, self._on_wrench)

    def _on_joint(self, data: bytes):
        try:
            sample = decode_joint_state(self.config.joint_state_type, data)
        except (ValueError, struct.error):  # bad fingerprint or truncated message
            sample = None
        self.monitor.on_joint(sample, time.monotonic())

    def _on_wrench(self, data: bytes):
        arrival = time.monotonic()
        try:
            sample = decode_wrench(data)
        except (ValueError, struct.error):  # bad fingerprint or truncated message
            sample = None
        fresh = self.monitor.on_wrench(sample, arrival)
        t = sample.t if sample is not None else 0.0
        if fresh:
            self._wrench_in.FixValue(self.context, self.monitor.wrench)
            self._state_in.FixValue(self.context, self.monitor.joint_state)
            self.simulator.AdvanceTo((self.processed + 0.5) * self.period)
            self.processed += 1
            fault = self.diagram.GetOutputPort("fault").Eval(self.context)[0] > 0.5
            if not fault:
                external = self.diagram.GetOutputPort("wrench_external").Eval(self.context)
                self.lcm.Publish(self.config.external_wrench_channel, encode_wrench(t, external))
                self.latencies.append(time.monotonic() - arrival)
                self.published += 1
        self._publish_contact(t, self.monitor.fault)

    def _publish_contact(self, t, fault):
        contact = self.diagram.GetOutputPort("contact").Eval(self.context)[0] > 0.5
        force = self.diagram.GetOutputPort("contact_force").Eval(self.context)[0]
        ood = self.diagram.GetOutputPort("out_of_domain").Eval(self.context)[0] > 0.5
        self.lcm.Publish(self.config.contact_channel, encode_contact_state(
            ContactState(t, contact, float(force), bool(fault), ood)))

    def spin_once(self, timeout_ms: int = 1) -> int:
        """Handles pending messages, then checks the timeouts (publishing the fault when a
        stream went silent). Returns the number of messages handled."""
        handled = self.lcm.HandleSubscriptions(timeout_ms)
        was = self.monitor.fault
        if self.monitor.check_timeouts(time.monotonic()) and not was:
            self._publish_contact(0.0, True)
        return handled

    def latency_percentiles(self):
        """(p50, p99) in s of arrival → publication, over the messages published so far."""
        lat = np.asarray(self.latencies)
        if not len(lat):
            return (np.nan, np.nan)
        return (float(np.percentile(lat, 50)), float(np.percentile(lat, 99)))


def build_hardware_station(config: HardwareConfig, model, detector_config, lcm=None,
                           period: float = 0.001):
    """Returns (diagram, handles): handles["station"] is the HardwareStation to spin."""
    station = HardwareStation(config, model, detector_config, lcm, period)
    return station.diagram, {"station": station, "monitor": station.monitor,
                             "context": station.context}


def measure_latency(model, detector_config=None, n_messages: int = 2000, seed: int = 0):
    """In-process (memq://) latency of arrival → publication of the compensated wrench.

    Publishes `n_messages` joint + F/T pairs one at a time and spins the station after
    each; returns {"p50_s", "p99_s", "processed", "published"}. In-process, so it measures the
    station's own work (decode, checks, compensator, detector, encode, publish), not UDP.
    """
    rng = np.random.default_rng(seed)
    lcm = DrakeLcm("memq://")
    n = int(model.n_joints_)
    config = HardwareConfig(lcm_url="memq://", n_joints=n, sensor_timeout_s=1.0,
                            joint_state_timeout_s=1.0)
    station = HardwareStation(config, model, detector_config or DetectorConfig(), lcm)
    for k in range(n_messages):
        t = 0.001 * (k + 1)
        lcm.Publish(config.joint_state_channel,
                    encode_joint_state("iiwa_status", t, rng.uniform(-1, 1, n), np.zeros(n)))
        lcm.Publish(config.ft_channel, encode_wrench(t, rng.normal(size=6)))
        station.spin_once(0)
    p50, p99 = station.latency_percentiles()
    return {"p50_s": p50, "p99_s": p99, "processed": station.processed,
            "published": station.published}
