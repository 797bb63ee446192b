"""JointEncoders: the joint angles the encoders report, with zero offsets and a gravity sag.

A real arm's encoders are zeroed by hand, a degree or two off, and sit on the motor side of a
gearbox whose compliance lets the link sag under gravity; a wrist F/T sensor turns with the
true link angles. Between the plant's joint state and everything that reads it, this system
adds both errors (:class:`~ftdrake.config.encoders.EncoderConfig`).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from ..config.encoders import EncoderConfig
from ..errors import ConfigError


class JointEncoders(LeafSystem):
    """The encoders' reading of the arm's joint state.

    ``q_measured = q + c ⊙ τ(q) − offsets``, ``v_measured = v``, with c the compliances
    (1/k, rad/(N·m); 0 on a rigid joint) and τ(q) the torque (N·m) that holds the arm
    against gravity at q (``−CalcGravityGeneralizedForces`` of the arm's plant, the tool
    included), computed in this system's own context of the plant.

    Input ports:
      state (2n): ``[q (rad), v (rad/s)]`` of the arm's links (a plant's state port), or its
        motors' with compliant transmissions.

    Output ports:
      measured_state (2n): ``[q_measured (rad), v (rad/s)]``, what the controller, the
        runtime chain and the logs read.
    """

    def __init__(self, config: EncoderConfig, plant, arm):
        super().__init__()
        n = plant.num_positions(arm)
        config.validate()
        config.check_joints(n)
        if plant.num_velocities(arm) != n:
            raise ConfigError("scenario.encoders: the arm needs one velocity per position")
        self.n = n
        self._offsets = np.asarray(config.offset_list(n), dtype=float)
        self._compliance = np.asarray(config.compliance(n), dtype=float)
        self._plant, self._arm = plant, arm
        self._context = plant.CreateDefaultContext() if self._compliance.any() else None
        self._state = self.DeclareVectorInputPort("state", 2 * n)
        self._measured = self.DeclareVectorOutputPort(
            "measured_state", BasicVector(2 * n), self._calc_measured)

    def get_input_port_state(self):
        return self._state

    def get_output_port_measured_state(self):
        return self._measured

    def holding_torque(self, q) -> np.ndarray:
        """τ(q) (n, N·m): the joint torques that hold the arm still against gravity at q."""
        context = self._context or self._plant.CreateDefaultContext()
        self._plant.SetPositions(context, self._arm, np.asarray(q, dtype=float))
        return -self._plant.GetVelocitiesFromArray(
            self._arm, self._plant.CalcGravityGeneralizedForces(context))

    def measured_q(self, q) -> np.ndarray:
        """q_measured (n, rad) for the links' q (rad)."""
        q = np.asarray(q, dtype=float)
        out = q - self._offsets
        if self._context is not None:
            out = out + self._compliance * self.holding_torque(q)
        return out

    def _calc_measured(self, context, output):
        x = self._state.Eval(context)
        output.SetFromVector(np.concatenate([self.measured_q(x[:self.n]), x[self.n:]]))
