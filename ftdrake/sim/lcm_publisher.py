"""A simulated robot on the wire: the simulation publishes what a real arm and sensor publish.

:func:`simulate_on_lcm` runs a built :class:`~ftdrake.sim.station.Station` like
:func:`ftdrake.sim.simulate.simulate` (same initial state, events and log) and publishes on the
channels of a :class:`~ftdrake.hardware.config.HardwareConfig`, at every sensor sample time
t_j = j·period (a Drake simulator monitor, called after each step):

* the arm's joint state x(t_j) stamped t_j (``joint_state_type``: iiwa/panda status with q,
  v; robot_state with q on ``joint_state_channel`` and v on ``velocity_channel``), then
* the sensor's reading of the previous sample, w(t_{j-1}), stamped t_{j-1}
  (``lcmt_force_torque`` on ``ft_channel``): the reading arrives one sample late, as from a
  sensor with one sample of transport latency.

Timestamps are the simulation's (``utime = round(t · 1e6)``); x(t) and w(t) are the values the
simulation logs at t (the ``q_i``, ``qd_i`` and ``meas_*`` columns of the row at t).

Why the F/T message lags: this is exactly what the in-simulation ``CompensatorSystem`` reads.
Drake's discrete MultibodyPlant steps (x(t_k) → x(t_{k+1})) before the other systems' discrete
updates at t_k run, so the compensator's update at t_k reads x(t_{k+1}) with the reading
w(t_k). A :class:`~ftdrake.hardware.station.HardwareStation` pairs each F/T message with the
latest joint state that arrived before it, x(t_{k+1}), so it runs the same updates on the same
inputs in the same order: its published wrench for the F/T message stamped t_k equals the
simulation's ``comp_external_*`` in the log row at t_{k+1} (and its contact flag the row's
``detected``). A run of K samples publishes K + 1 joint states (t_0 .. t_K) and K F/T
messages (t_0 .. t_{K-1}). Training tables built from these messages
(:mod:`~ftdrake.hardware.recording`) pair by timestamp, x(t_k) with w(t_k), like the log.

``realtime_rate`` = 1 paces the simulation to the wall clock (Drake's
``Simulator.set_target_realtime_rate``): the simulator sleeps when ahead; when it falls behind
it runs as fast as it can (messages then come in bursts, still in order).
"""

from __future__ import annotations

import time

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus
from tqdm.auto import tqdm

from ..errors import ConfigError
from ..hardware.config import HardwareConfig
from ..hardware.messages import (
    PAYLOAD_COORD,
    TARE_COORD,
    encode_event,
    encode_joint_state,
    encode_temperature,
    encode_wrench,
)
from ..hardware.transport import open_lcm
from .events import apply_grasp
from .simulate import SimResult, assemble_log, set_initial_state


class _Publisher:
    """The simulator monitor: per sample, the joint state, then the previous sample's reading."""

    def __init__(self, station, config: HardwareConfig, lcm):
        self.config, self.lcm = config, lcm
        self.period = station.period
        plant, arm = station.scene.plant, station.scene.arm
        self.n = plant.num_positions(arm)
        if self.n != config.n_joints:
            raise ConfigError(f"hardware.n_joints: {config.n_joints}, but the simulated arm "
                              f"has {self.n} joints")
        self._state = plant.get_state_output_port(arm)
        self._reading = station.events.reading
        self._temperature = station.noisy_sensor.get_output_port_temperature()
        self.next_j = 0
        self._pending = None  # (t, reading) to publish after the next joint state
        self.published = {"joint": 0, "ft": 0}
        if config.temperature_channel:
            self.published["temperature"] = 0
        # The driver announces a re-tare, the gripper a grasp, once, when the simulated event
        # starts: (port, channel, coordinate, was high at the last sample).
        self._events = {
            name: [port, channel, coord, False]
            for name, port, channel, coord in (
                ("tare", station.events.tared, config.tare_channel, TARE_COORD),
                ("payload", station.events.payload_changed, config.payload_channel,
                 PAYLOAD_COORD))
            if channel and port is not None}
        for name in self._events:
            self.published[name] = 0

    def __call__(self, root_context) -> EventStatus:
        t = root_context.get_time()
        if t < self.next_j * self.period - 0.25 * self.period:
            return EventStatus.DidNothing()
        t_j = self.next_j * self.period
        x = self._state.Eval(self._state.get_system().GetMyContextFromRoot(root_context))
        w = self._reading.Eval(self._reading.get_system().GetMyContextFromRoot(root_context))
        if c_temperature := self.config.temperature_channel:
            # The sensor reports its temperature with its reading (°C, same stamp).
            celsius = self._temperature.Eval(
                self._temperature.get_system().GetMyContextFromRoot(root_context))[0]
            self.lcm.publish(c_temperature, encode_temperature(t_j, celsius))
            self.published["temperature"] += 1
        for name, event in self._events.items():
            port, channel, coord, was_high = event
            high = port.Eval(port.get_system().GetMyContextFromRoot(root_context))[0] > 0.5
            if high and not was_high:
                self.lcm.publish(channel, encode_event(t_j, coord))
                self.published[name] += 1
            event[3] = high
        c, n = self.config, self.n
        if c.joint_state_type == "robot_state":
            self.lcm.publish(c.joint_state_channel, encode_joint_state("robot_state", t_j, x[:n]))
            self.lcm.publish(c.velocity_channel, encode_joint_state("robot_state", t_j, x[n:]))
        else:
            self.lcm.publish(c.joint_state_channel,
                             encode_joint_state(c.joint_state_type, t_j, x[:n], x[n:]))
        self.published["joint"] += 1
        if self._pending is not None:
            self.lcm.publish(c.ft_channel, encode_wrench(*self._pending))
            self.published["ft"] += 1
        self._pending = (t_j, w.copy())
        self.next_j += 1
        return EventStatus.Succeeded()


def simulate_on_lcm(station, config: HardwareConfig, lcm=None, *, realtime_rate: float = 0.0,
                    duration: float | None = None, progress: bool = True) -> SimResult:
    """Simulates `station` (built without or with a compensator) and publishes its joint
    state and sensor reading per sample on `lcm` (a URL, ``lcm.LCM``, DrakeLcm or transport;
    default ``config.lcm_url``). Returns simulate()'s SimResult; its ``timing`` also holds
    ``published`` = {"joint": K + 1, "ft": K} messages for K samples (see the module)."""
    config.validate()
    lcm = open_lcm(lcm if lcm is not None else config.lcm_url)
    publisher = _Publisher(station, config, lcm)
    duration = station.trajectory.end_time() if duration is None else float(duration)
    simulator = Simulator(station.diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    set_initial_state(station, simulator.get_mutable_context())
    simulator.set_monitor(publisher)
    simulator.Initialize()
    grasp_at = station.config.events.grasp_at_s
    chunk = 0.25
    start = time.perf_counter()
    with tqdm(total=round(duration, 3), unit="sim s", disable=not progress,
              desc="simulating (publishing)", leave=False) as bar:
        t = 0.0
        while t < duration - 1e-9:
            t = min(duration, t + chunk)
            if grasp_at is not None and simulator.get_context().get_time() < grasp_at <= t:
                simulator.AdvanceTo(grasp_at)
                plant = station.scene.plant
                apply_grasp(station.config.events, station.scene,
                            plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()))
            simulator.AdvanceTo(t)
            bar.update(round(t - bar.n, 3))
    wall = time.perf_counter() - start
    context = simulator.get_context()
    log = assemble_log(station, context)
    timing = {"duration_s": duration, "wall_time_s": wall,
              "real_time_factor": duration / wall if wall > 0 else float("inf"),
              "samples": len(log), "published": dict(publisher.published)}
    return SimResult(log, timing, context)
