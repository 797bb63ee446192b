"""JointStateGravity: the apparent gravity at the sensor and the sensor frame's angular velocity
and acceleration, from the joint state alone.

The simulation's :class:`~ftdrake.systems.sensor_gravity.SensorGravity` reads the plant's
body poses, velocities and accelerations. A live robot has no plant, only its joint state,
so this system computes the same quantities from ``[q; v]`` through the robot's compiled
serial chain (:class:`~ftdrake.physics.chain.SerialChain`), with q̈ estimated the way
``CompensatorSystem`` estimates it (:func:`ftdrake.signals.causal_acceleration` at
``acceleration_cutoff_hz``). It feeds the bias tracker's payload estimate on hardware. α (and
a_So) inherit that estimate's filter.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem

from ..conventions import GRAVITY_W
from ..physics.chain import SerialChain, sensor_kinematics_row
from ..signals import (
    DEFAULT_ACCELERATION_CUTOFF_HZ,
    acceleration_filter_gains,
    causal_acceleration_step,
    estimator_size,
)


class JointStateGravity(LeafSystem):
    """Apparent gravity at the sensor origin So, ``g_S − a_So_S`` (the specific force, m/s²,
    in S), and S's angular velocity and acceleration, from the joint state, updated every
    `period` s.

    Input ports:
      joint_state (2n): ``[q; v]`` in rad (or m), rad/s, in the chain's joint order.
    Output ports:
      gravity_S (3): m/s², in S (≈ R_SW·[0, 0, −9.81] at rest).
      motion_S (6): [ω_WS_S (rad/s); α_WS_S (rad/s²)], in S (α from the estimated q̈).
      Both are held between updates and zeros before the first. A non-finite joint state
      leaves them unchanged (the compensator raises the fault for the same sample).

    With ``include_acceleration=False``, a_So is not subtracted and motion_S is zero (gravity
    alone: a payload is then only identified right while the arm moves slowly).
    """

    def __init__(self, chain: SerialChain, period: float, *,
                 acceleration_cutoff_hz: float = DEFAULT_ACCELERATION_CUTOFF_HZ,
                 gravity_W=GRAVITY_W, include_acceleration: bool = True):
        super().__init__()
        if not (period > 0 and math.isfinite(period)):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        if chain.num_positions != chain.num_velocities:
            raise ValueError("JointStateGravity needs one velocity per position (no quaternions)")
        self.chain = chain
        n = self.n = chain.num_positions
        self._constants = np.array([*acceleration_filter_gains(acceleration_cutoff_hz, period),
                                    float(period), float(bool(include_acceleration))])
        self._gravity_W = np.asarray(gravity_W, dtype=float)
        self._state_port = self.DeclareVectorInputPort("joint_state", 2 * n)
        self._estimator = self.DeclareDiscreteState(estimator_size(n))  # the q̈ estimator's
        self._gravity = self.DeclareDiscreteState(3)
        self._motion = self.DeclareDiscreteState(6)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareStateOutputPort("gravity_S", self._gravity)
        self.DeclareStateOutputPort("motion_S", self._motion)

    def get_input_port_joint_state(self):
        return self.GetInputPort("joint_state")

    def get_output_port_gravity_S(self):
        return self.GetOutputPort("gravity_S")

    def get_output_port_motion_S(self):
        return self.GetOutputPort("motion_S")

    def _update(self, context, state):
        _apparent_gravity(self._state_port.Eval(context), state.get_mutable_value(self._estimator),
                          state.get_mutable_value(self._gravity),
                          state.get_mutable_value(self._motion), self._constants,
                          self._gravity_W, *self.chain.kernel_args())


@numba.njit(cache=True)
def _apparent_gravity(x, estimator, g_S, motion, constants, gravity_W, X_pre, kinds, axes,
                      q_index, v_index):
    n = len(x) // 2
    for i in range(2 * n):
        if not math.isfinite(x[i]):
            return
    q, v = x[:n], x[n:]
    vdot = np.empty(n)
    causal_acceleration_step(v, estimator, constants[0], constants[1], constants[2], vdot)
    with_acceleration = constants[3]
    R = np.empty((3, 3))
    out = np.empty((4, 3))
    sensor_kinematics_row(q, v, vdot, gravity_W, X_pre, kinds, axes, q_index, v_index, R, out)
    for j in range(3):
        g_S[j] = out[3, j] - with_acceleration * out[2, j]
        motion[j] = with_acceleration * out[0, j]
        motion[3 + j] = with_acceleration * out[1, j]
