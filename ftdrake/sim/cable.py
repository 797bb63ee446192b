"""A cable/hose dragging on the tool: the configuration-dependent force rigid models miss.

Modelled with Drake's own (C++) elements so it costs nothing per step in Python:

* a ``LinearSpringDamper`` from a point on the forearm (`anchor_body`, `p_anchor`) to a
  point on the tool (`p_SAttach`, given in the sensor frame S): tension
  ``stiffness · (ℓ − rest_length)`` along the cable, depending on the arm's configuration;
* the hanging part of the cable's weight, ``weight_n`` pulling the attachment point straight
  down (a constant world-frame force, fed to the plant's applied-spatial-force port).

The sensor reads both (they act on the tool); a tool-only payload model cannot explain them.
The spring also pushes if compressed below its rest length, like a stiff hose.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.multibody.tree import LinearSpringDamper

from ..config import CableConfig

_DAMPING = 0.5  # N·s/m: a cable is not a perfect spring


def attach_point_in_body(sensor_frame, config: CableConfig) -> np.ndarray:
    """The cable's attachment point, given in S, measured in the tool body's frame."""
    return sensor_frame.GetFixedPoseInBodyFrame() @ np.asarray(config.p_SAttach, dtype=float)


def add_cable_spring(plant, arm, sensor_frame, config: CableConfig) -> LinearSpringDamper:
    """Adds the cable's spring to `plant` (before Finalize); `config` is taken as valid (it is
    checked with its scenario, where that is loaded)."""
    if not plant.HasBodyNamed(config.anchor_body, arm):
        raise ValueError(f"scenario.cable.anchor_body: no body {config.anchor_body!r} in the arm")
    anchor = plant.GetBodyByName(config.anchor_body, arm)
    return plant.AddForceElement(
        LinearSpringDamper(
            anchor, np.asarray(config.p_anchor, dtype=float),
            sensor_frame.body(), attach_point_in_body(sensor_frame, config),
            free_length=config.rest_length, stiffness=config.stiffness, damping=_DAMPING,
        )
    )


def cable_weight_forces(sensor_frame, config: CableConfig) -> list:
    """The cable's hanging weight on the tool, for the plant's applied-spatial-force port."""
    if not config.enabled or config.weight_n == 0:
        return []
    force = ExternallyAppliedSpatialForce()
    force.body_index = sensor_frame.body().index()
    force.p_BoBq_B = attach_point_in_body(sensor_frame, config)
    force.F_Bq_W = SpatialForce(tau=np.zeros(3), f=np.array([0.0, 0.0, -config.weight_n]))
    return [force]


def cable_force_W(plant, context, spring: LinearSpringDamper, config: CableConfig):
    """Total cable force on the tool (N, in W) and its application point (m, in W).

    Computed from kinematics and the spring law, independently of the plant's dynamics.
    """
    X_WA = plant.EvalBodyPoseInWorld(context, spring.bodyA())
    X_WB = plant.EvalBodyPoseInWorld(context, spring.bodyB())
    p_WP, p_WQ = X_WA @ spring.p_AP(), X_WB @ spring.p_BQ()
    V_WA = plant.EvalBodySpatialVelocityInWorld(context, spring.bodyA())
    V_WB = plant.EvalBodySpatialVelocityInWorld(context, spring.bodyB())
    v_WP = V_WA.Shift(p_WP - X_WA.translation()).translational()
    v_WQ = V_WB.Shift(p_WQ - X_WB.translation()).translational()
    d = p_WP - p_WQ
    length = np.linalg.norm(d)
    u = d / length
    tension = spring.stiffness() * (length - spring.free_length()) + spring.damping() * (
        (v_WP - v_WQ) @ u
    )
    return tension * u + np.array([0.0, 0.0, -config.weight_n]), p_WQ
