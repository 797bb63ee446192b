"""PayloadFeedforward: the joint torques that carry a payload the controller's model lacks.

An adaptive computed-torque term: the bias tracker identifies a grasped payload (Δm and its
first moment Δ(m·c) about the sensor origin So, in S); this system turns that estimate into
the torque the arm needs for it, added to the inverse-dynamics controller's output, so the
arm follows the same path after a grasp as before it.

The payload is taken as a point mass Δm at p = h/Δm from So (h = Δ(m·c): the tracker's
gravity part identifies no rotational inertia about the centre of mass). By Newton's law for
that particle it pulls on the arm at So with (in W, about So)::

    F_W = Δm·(g_W − a_P),   a_P = a_So + α × p + ω × (ω × p)
    T_W = p × F_W

with a_So, α, ω the motion of S from the controller's own plant at the measured (q, v) and
the commanded acceleration; for Δm ≤ 1 g only the gravity part (h × (g_W − a_So)) is kept, as
p is then not defined. The generalized force that wrench exerts is J_Sᵀ·[T_W; F_W] (J_S: S's
spatial-velocity Jacobian at So, in W), so the term the controller adds is its negative::

    τ_payload = −J_Sᵀ·[T_W; F_W]
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import LeafSystem

from ..conventions import GRAVITY_W

__all__ = ["PayloadFeedforward"]

#: kg: below this the payload's first moment is applied without a point to put its mass at.
MIN_POINT_MASS_KG = 1e-3


class PayloadFeedforward(LeafSystem):
    """The joint torques that carry an identified payload (module docstring: the law).

    Input ports:
      estimated_state (2n): ``[q (rad), v (rad/s)]`` of the arm, in `plant`'s order.
      desired_acceleration (n): the commanded v̇ (rad/s²).
      payload (4, optional): ``[Δm (kg), Δ(m·c) (kg·m, about So, in S)]`` (the bias tracker's
        ``payload``); unconnected = no payload.
    Output ports:
      control (n): τ_payload, joint torques (N·m) to add to the controller's.

    `plant`: the controller's model of the arm (a finalized MultibodyPlant with the arm's
    joints only); `frame_S`: the sensor frame S in it (origin So).
    """

    def __init__(self, plant, frame_S):
        super().__init__()
        self._plant, self._frame_S = plant, frame_S
        self._plant_context = plant.CreateDefaultContext()
        n = plant.num_velocities()
        if plant.num_positions() != n:
            raise ValueError("PayloadFeedforward needs q and v of equal size")
        self._n = n
        self._g_W = np.asarray(GRAVITY_W, dtype=float)
        self._state_port = self.DeclareVectorInputPort("estimated_state", 2 * n)
        self._vdot_port = self.DeclareVectorInputPort("desired_acceleration", n)
        self._payload_port = self.DeclareVectorInputPort("payload", 4)
        self.DeclareVectorOutputPort("control", n, self._calc_control)

    def get_input_port_estimated_state(self):
        return self.GetInputPort("estimated_state")

    def get_input_port_desired_acceleration(self):
        return self.GetInputPort("desired_acceleration")

    def get_input_port_payload(self):
        return self.GetInputPort("payload")

    def get_output_port_control(self):
        return self.GetOutputPort("control")

    def _calc_control(self, context, output):
        payload = (self._payload_port.Eval(context) if self._payload_port.HasValue(context)
                   else None)
        if payload is None or not np.all(np.isfinite(payload)) or not np.any(payload):
            output.SetFromVector(np.zeros(self._n))  # nothing identified: nothing to carry
            return
        x = self._state_port.Eval(context)
        vdot = self._vdot_port.Eval(context)
        output.SetFromVector(self.torque(x[:self._n], x[self._n:], vdot, payload))

    def torque(self, q, v, vdot, payload) -> np.ndarray:
        """τ_payload (n, N·m) at (q, v) with the commanded v̇ for `payload` = [Δm, Δ(m·c)_S]."""
        plant, ctx, frame_S, world = (self._plant, self._plant_context, self._frame_S,
                                      self._plant.world_frame())
        plant.SetPositions(ctx, q)
        plant.SetVelocities(ctx, v)
        J = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kV, frame_S,
                                              np.zeros(3), world, world)
        bias = plant.CalcBiasSpatialAcceleration(ctx, JacobianWrtVariable.kV, frame_S,
                                                 np.zeros(3), world, world)
        A = J @ vdot + np.hstack([bias.rotational(), bias.translational()])
        omega, alpha, a_So = J[:3] @ v, A[:3], A[3:]
        h_W = frame_S.CalcPoseInWorld(ctx).rotation() @ np.asarray(payload[1:4])
        g = self._g_W - a_So
        force = payload[0] * g - np.cross(alpha, h_W) - np.cross(omega, np.cross(omega, h_W))
        if payload[0] > MIN_POINT_MASS_KG:
            torque = np.cross(h_W / payload[0], force)
        else:  # no point to put it at: its gravity part only
            torque = np.cross(h_W, g)
        return -J.T @ np.hstack([torque, force])
