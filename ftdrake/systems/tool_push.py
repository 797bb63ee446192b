"""ToolPush: a slowly growing push on the tool tip (``scenario.events.push``), the load a bias
tracker must not take for drift. Reads the plant's body poses, so it works for any arm."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import BasicVector, LeafSystem


class ToolPush(LeafSystem):
    """A force on the tool tip that grows linearly, holds, then stops; plus what the scene
    already applies (the cable's weight), passed through.

    The force is ``f_W·clip((t − t0)/ramp, 0, 1)`` for t0 ≤ t < t0 + ramp + hold, else 0
    (N, world frame), applied at the tool-tip frame's origin Tp.

    Input ports:
      body_poses (abstract, list of RigidTransform): the plant's body poses (X_WB).
      applied_in (abstract, list of ExternallyAppliedSpatialForce): forces to pass through.
    Output ports:
      applied (abstract, list of ExternallyAppliedSpatialForce): applied_in + the push; to the
        plant's applied_spatial_force input.
      wrench_S (6): the push as the sensor sees it: ``[F_S; p_SoTp_S × F_S]`` (N, N·m, in S,
        about So) — what a contact of that force at the tip would add to the reading.
    """

    def __init__(self, plant, sensor_frame, tip_frame, t0: float, ramp_s: float,
                 hold_s: float, force_W):
        super().__init__()
        self._t0, self._ramp, self._end = float(t0), float(ramp_s), float(t0 + ramp_s + hold_s)
        self._f_W = np.asarray(force_W, dtype=float)
        self._tip_body = tip_frame.body().index()
        self._X_BT = tip_frame.GetFixedPoseInBodyFrame()
        self._s_body = int(sensor_frame.body().index())
        self._X_BS = sensor_frame.GetFixedPoseInBodyFrame()
        poses = AbstractValue.Make([RigidTransform()] * plant.num_bodies())
        self.DeclareAbstractInputPort("body_poses", poses)
        forces = AbstractValue.Make([ExternallyAppliedSpatialForce()])
        self.DeclareAbstractInputPort("applied_in", forces)
        self.DeclareAbstractOutputPort("applied", lambda: forces.Clone(), self._calc_applied)
        self.DeclareVectorOutputPort("wrench_S", 6, self._calc_wrench)

    def get_input_port_body_poses(self):
        return self.GetInputPort("body_poses")

    def get_input_port_applied_in(self):
        return self.GetInputPort("applied_in")

    def get_output_port_applied(self):
        return self.GetOutputPort("applied")

    def get_output_port_wrench_S(self):
        return self.GetOutputPort("wrench_S")

    def force_W(self, t: float) -> np.ndarray:
        """The push at time `t` (N, world frame)."""
        if t < self._t0 or t >= self._end:
            return np.zeros(3)
        return self._f_W * min(1.0, (t - self._t0) / self._ramp)

    def _calc_applied(self, context, output):
        forces = list(self.get_input_port_applied_in().Eval(context))
        f = self.force_W(context.get_time())
        if np.any(f):
            push = ExternallyAppliedSpatialForce()
            push.body_index = self._tip_body
            push.p_BoBq_B = self._X_BT.translation()
            push.F_Bq_W = SpatialForce(np.zeros(3), f)
            forces.append(push)
        output.set_value(forces)

    def _calc_wrench(self, context, output: BasicVector):
        f = self.force_W(context.get_time())
        if not np.any(f):
            output.SetFromVector(np.zeros(6))
            return
        poses = self.get_input_port_body_poses().Eval(context)
        X_WS = poses[self._s_body] @ self._X_BS
        X_WT = poses[int(self._tip_body)] @ self._X_BT
        R_SW = X_WS.rotation().inverse()
        F_S = R_SW @ f
        p_SoTp_S = R_SW @ (X_WT.translation() - X_WS.translation())
        output.SetFromVector(np.concatenate([F_S, np.cross(p_SoTp_S, F_S)]))
