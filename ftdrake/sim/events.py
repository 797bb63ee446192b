"""Scenario events in the diagram: a re-tare, a grasp, a slow push (``scenario.events``).

- The **re-tare** is modelled where it happens on a real robot, in the sensor driver: a zero
  offset (a held signal) is added to the noisy sensor's reading, so the compensator, the log's
  ``meas_*`` and everything downstream read the shifted wrench. The ``tared`` signal is high
  for ``events.signal_s`` from the event (the tracker re-initialises its bias while it is).
- The **grasp** changes the tool body's spatial inertia in the plant's context at the event
  time (:func:`apply_grasp`, called by ``simulate``): the plant's dynamics change, nothing else
  knows. ``payload_changed`` is high for ``events.signal_s`` like ``tared``: the tracker
  re-initialises the payload while the controller catches the new weight.
- The **push** is :class:`~ftdrake.systems.tool_push.ToolPush` between the scene's cable-weight
  source and the plant's applied-force port.

Signals are Drake primitives (zero-order-hold trajectory sources, an adder): no Python runs per
step for them.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.tree import RotationalInertia, SpatialInertia
from pydrake.systems.primitives import Adder, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ..config import EventsConfig
from ..systems.tool_push import ToolPush


@dc.dataclass
class EventSignals:
    """Output ports (and systems) the station wires to the tracker, loggers and plant."""

    reading: object  # OutputPort: the sensor reading after the driver's offset (6)
    offset: object | None = None  # OutputPort: the driver's offset (6), with a re-tare
    tared: object | None = None  # OutputPort (1)
    payload_changed: object | None = None  # OutputPort (1)
    push: ToolPush | None = None


def add_sensor_events(builder, events: EventsConfig, scene, reading_port) -> EventSignals:
    """Adds the events' sources; returns the reading the rest of the diagram must use."""
    signals = EventSignals(reading=reading_port)
    if events.retare_at_s is not None:
        offset = builder.AddNamedSystem(
            "retare_offset", TrajectorySource(_step(events.retare_at_s, events.retare_offset)))
        adder = builder.AddNamedSystem("sensor_driver", Adder(2, 6))
        builder.Connect(reading_port, adder.get_input_port(0))
        builder.Connect(offset.get_output_port(), adder.get_input_port(1))
        signals.reading = adder.get_output_port()
        signals.offset = offset.get_output_port()
        if events.retare_signalled:
            signals.tared = _pulse(builder, "tared", events.retare_at_s, events.signal_s)
    if events.grasp_at_s is not None and events.grasp_signalled:
        signals.payload_changed = _pulse(builder, "payload_changed", events.grasp_at_s,
                                         events.signal_s)
    if events.push_at_s is not None:
        signals.push = _add_push(builder, events, scene)
    return signals


def apply_grasp(events: EventsConfig, scene, plant_context) -> None:
    """Adds the grasped point mass to the tool body that carries the sensor frame S."""
    frame_S = scene.sensor_frame
    body = frame_S.body()
    p_BP = frame_S.GetFixedPoseInBodyFrame() @ np.asarray(events.grasp_p_SP, dtype=float)
    body.SetSpatialInertiaInBodyFrame(
        plant_context, with_point_mass(body.CalcSpatialInertiaInBodyFrame(plant_context),
                                       events.grasp_mass_kg, p_BP))


def with_point_mass(M_BBo_B: SpatialInertia, mass: float, p_BP) -> SpatialInertia:
    """The spatial inertia (about Bo, in B) of body B plus a point mass at P."""
    m0, c0 = M_BBo_B.get_mass(), M_BBo_B.get_com()
    p = np.asarray(p_BP, dtype=float)
    I_Bo = M_BBo_B.CalcRotationalInertia().CopyToFullMatrix3()
    I_Bo = I_Bo + mass * (p @ p * np.eye(3) - np.outer(p, p))
    m = m0 + mass
    c = (m0 * c0 + mass * p) / m
    I_cm = I_Bo - m * (c @ c * np.eye(3) - np.outer(c, c))
    central = RotationalInertia(I_cm[0, 0], I_cm[1, 1], I_cm[2, 2],
                                I_cm[0, 1], I_cm[0, 2], I_cm[1, 2])
    return SpatialInertia.MakeFromCentralInertia(m, c, central)


def _step(t: float, value) -> PiecewisePolynomial:
    value = np.asarray(value, dtype=float).reshape(-1, 1)
    zero = np.zeros_like(value)
    return PiecewisePolynomial.ZeroOrderHold([0.0, t, t + 1.0] if t > 0 else [0.0, 1.0],
                                             np.hstack([zero, value, value] if t > 0
                                                       else [value, value]))


def _pulse(builder, name: str, t: float, width: float):
    breaks = [0.0, t, t + width, t + width + 1.0] if t > 0 else [0.0, width, width + 1.0]
    values = [0.0, 1.0, 0.0, 0.0] if t > 0 else [1.0, 0.0, 0.0]
    source = builder.AddNamedSystem(
        name, TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks, [values])))
    return source.get_output_port()


def _add_push(builder, events: EventsConfig, scene) -> ToolPush:
    plant = scene.plant
    port = plant.get_applied_spatial_force_input_port()
    cable_weight = builder.GetSubsystemByName("cable_weight").get_output_port()
    push = builder.AddNamedSystem("tool_push", ToolPush(
        plant, scene.sensor_frame, scene.tool_tip_frame(), events.push_at_s, events.push_ramp_s,
        events.push_hold_s, events.push_force_W))
    builder.Disconnect(cable_weight, port)
    builder.Connect(cable_weight, push.get_input_port_applied_in())
    builder.Connect(plant.get_body_poses_output_port(), push.get_input_port_body_poses())
    builder.Connect(push.get_output_port_applied(), port)
    return push
