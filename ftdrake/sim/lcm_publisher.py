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
simulation's ``wrench_compensated_*`` in the log row at t_{k+1} (and its contact flag the row's
``contact``). A run of K samples publishes K + 1 joint states (t_0 .. t_K) and K F/T
messages (t_0 .. t_{K-1}). Training tables built from these messages
(:mod:`~ftdrake.hardware.recording`) pair by timestamp, x(t_k) with w(t_k), like the log.

``realtime_rate`` = 1 paces the simulation to the wall clock (Drake's
``Simulator.set_target_realtime_rate``): the simulator sleeps when ahead; when it falls behind
it runs as fast as it can (messages then come in bursts, still in order).
"""

from __future__ import annotations

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
from .sampled_publisher import SampledPublisher, simulate_publishing
from .simulate import SimResult


class _Publisher(SampledPublisher):
    """Per sample, the joint state, then the previous sample's reading, as LCM messages."""

    def __init__(self, station, config: HardwareConfig, lcm):
        events = [name for name, channel in (("tare", config.tare_channel),
                                             ("payload", config.payload_channel)) if channel]
        super().__init__(station, config.n_joints, "hardware.n_joints",
                         temperature=bool(config.temperature_channel), events=events)
        self.config, self.lcm = config, lcm

    def send_joint(self, t, q, v) -> None:
        c = self.config
        if c.joint_state_type == "robot_state":
            self.lcm.publish(c.joint_state_channel, encode_joint_state("robot_state", t, q))
            self.lcm.publish(c.velocity_channel, encode_joint_state("robot_state", t, v))
        else:
            self.lcm.publish(c.joint_state_channel,
                             encode_joint_state(c.joint_state_type, t, q, v))

    def send_wrench(self, t, w) -> None:
        self.lcm.publish(self.config.ft_channel, encode_wrench(t, w))

    def send_temperature(self, t, celsius) -> None:
        self.lcm.publish(self.config.temperature_channel, encode_temperature(t, celsius))

    def send_event(self, name, t) -> None:
        channel, coord = ((self.config.tare_channel, TARE_COORD) if name == "tare"
                          else (self.config.payload_channel, PAYLOAD_COORD))
        self.lcm.publish(channel, encode_event(t, coord))


def simulate_on_lcm(station, config: HardwareConfig, lcm=None, *, realtime_rate: float = 0.0,
                    duration: float | None = None, progress: bool = True) -> SimResult:
    """Simulates `station` (built without or with a compensator) and publishes its joint
    state and sensor reading per sample on `lcm` (a URL, ``lcm.LCM``, DrakeLcm or transport;
    default ``config.lcm_url``). Returns simulate()'s SimResult; its ``timing`` also holds
    ``published`` = {"joint": K + 1, "ft": K} messages for K samples (see the module)."""
    config.validate()
    lcm = open_lcm(lcm if lcm is not None else config.lcm_url)
    return simulate_publishing(station, _Publisher(station, config, lcm),
                               realtime_rate=realtime_rate, duration=duration,
                               progress=progress)
