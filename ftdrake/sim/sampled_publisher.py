"""The simulation as a robot on a wire, whatever the wire: per sensor sample, the arm's joint
state and the sensor's previous reading, handed to a transport's send methods.

:class:`SampledPublisher` is the simulator monitor both :mod:`~ftdrake.sim.lcm_publisher` and
:mod:`~ftdrake.sim.ros2_publisher` use (their module docstrings say what goes out and why the
F/T reading lags one sample); a subclass implements ``send_joint(t, q, v)``,
``send_wrench(t, w)``, ``send_temperature(t, celsius)`` and ``send_event(name, t)``.
:func:`simulate_publishing` runs a station with it like :func:`ftdrake.sim.simulate.simulate`
(same initial state, events and log).
"""

from __future__ import annotations

from pydrake.systems.framework import EventStatus

from ..errors import ConfigError
from .simulate import SimResult, simulate


class SampledPublisher:
    """The simulator monitor: per sample t_j = j·period, the joint state x(t_j), then the
    previous sample's reading w(t_{j-1}); the temperature with it (if `temperature`) and an
    event once when the simulated re-tare or grasp starts (`events`: "tare", "payload" to
    announce). `n_joints` must be the simulated arm's (`where` names the setting)."""

    def __init__(self, station, n_joints: int, where: str, *, temperature: bool = False,
                 events=()):
        self.period = station.period
        plant, arm = station.scene.plant, station.scene.arm
        self.n = plant.num_positions(arm)
        if self.n != n_joints:
            raise ConfigError(f"{where}: {n_joints}, but the simulated arm has {self.n} joints")
        self._state = plant.get_state_output_port(arm)
        self._reading = station.events.reading
        self._temperature = (station.noisy_sensor.get_output_port_temperature()
                             if temperature else None)
        self.next_j = 0
        self._pending = None  # (t, reading) to publish after the next joint state
        self.published = {"joint": 0, "ft": 0}
        if temperature:
            self.published["temperature"] = 0
        # (port, was high at the last sample) per announced event.
        ports = {"tare": station.events.tared, "payload": station.events.payload_changed}
        self._events = {name: [ports[name], False] for name in events
                        if ports[name] is not None}
        for name in self._events:
            self.published[name] = 0

    def send_joint(self, t: float, q, v) -> None:
        raise NotImplementedError

    def send_wrench(self, t: float, w) -> None:
        raise NotImplementedError

    def send_temperature(self, t: float, celsius: float) -> None:
        raise NotImplementedError

    def send_event(self, name: str, t: float) -> None:
        raise NotImplementedError

    def __call__(self, root_context) -> EventStatus:
        t = root_context.get_time()
        if t < self.next_j * self.period - 0.25 * self.period:
            return EventStatus.DidNothing()
        t_j = self.next_j * self.period
        x = self._state.Eval(self._state.get_system().GetMyContextFromRoot(root_context))
        w = self._reading.Eval(self._reading.get_system().GetMyContextFromRoot(root_context))
        if self._temperature is not None:
            # The sensor reports its temperature with its reading (°C, same stamp).
            celsius = self._temperature.Eval(
                self._temperature.get_system().GetMyContextFromRoot(root_context))[0]
            self.send_temperature(t_j, celsius)
            self.published["temperature"] += 1
        for name, event in self._events.items():
            port, was_high = event
            high = port.Eval(port.get_system().GetMyContextFromRoot(root_context))[0] > 0.5
            if high and not was_high:
                self.send_event(name, t_j)
                self.published[name] += 1
            event[1] = high
        self.send_joint(t_j, x[:self.n], x[self.n:])
        self.published["joint"] += 1
        if self._pending is not None:
            self.send_wrench(*self._pending)
            self.published["ft"] += 1
        self._pending = (t_j, w.copy())
        self.next_j += 1
        return EventStatus.Succeeded()


def simulate_publishing(station, publisher: SampledPublisher, *, realtime_rate: float = 0.0,
                        duration: float | None = None, progress: bool = True) -> SimResult:
    """Simulates `station` with `publisher` as the monitor. Returns simulate()'s SimResult;
    its ``timing`` also holds ``published`` (messages per stream)."""
    result = simulate(station, progress=progress, duration=duration,
                      realtime_rate=realtime_rate, monitor=publisher)
    result.timing["published"] = dict(publisher.published)
    return result
