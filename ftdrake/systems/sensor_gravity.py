"""SensorGravity: the apparent gravity and rotation rates of the sensor frame S in simulation.

The payload tracker's regressor (``runtime.bias_tracker``) needs ``g_S − a_So`` and S's ω, α.
In simulation they come from the plant's body poses, velocities and accelerations, so this
works for any arm the plant holds; on a live robot
:class:`~ftdrake.runtime.joint_gravity.JointStateGravity` computes the same from joint states.
"""

from __future__ import annotations

import numba
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialAcceleration, SpatialVelocity
from pydrake.systems.framework import BasicVector, LeafSystem, ValueProducer


class SensorGravity(LeafSystem):
    """Gravity as the sensor's payload feels it, and the rotation of the sensor frame S.

    Without accelerations: g_S = R_SW·g_W. With ``include_acceleration`` (the default): the
    apparent gravity at the sensor origin, g_S − a_So_S (the specific force, m/s²; a_So from
    the body's spatial acceleration and velocity, shifted to So exactly), and the angular
    velocity and acceleration of S: with these a rigid payload's wrench is linear in its
    10 inertial parameters in motion too (the offset terms α×c + ω×(ω×c) and the rotational
    inertia; OnlineBiasTracker's model).

    Input ports:
      body_poses (abstract, list of RigidTransform): the plant's body poses (X_WB).
      body_spatial_velocities (abstract, list of SpatialVelocity; with
        ``include_acceleration``): the plant's port (V_WB, in W).
      body_spatial_accelerations (abstract, list of SpatialAcceleration; with
        ``include_acceleration``): the plant's port (A_WB, in W).
    Output ports:
      gravity_S (3): m/s², in S (≈ R_SW·[0, 0, −9.81] at rest). Pointing down in the world.
      motion_S (6): [ω_WS_S (rad/s); α_WS_S (rad/s²)], S's angular velocity and acceleration
        in W, expressed in S; zeros without ``include_acceleration`` (gravity alone).

    Both outputs come from one cached computation (the plant's ports are read once per
    context change).
    """

    def __init__(self, plant, sensor_frame, include_acceleration: bool = True):
        super().__init__()
        self._body = int(sensor_frame.body().index())
        self._X_BS = sensor_frame.GetFixedPoseInBodyFrame()
        self._R_BS = self._X_BS.rotation().matrix()
        self._p_BS = self._X_BS.translation()
        self._g_W = np.asarray(plant.gravity_field().gravity_vector(), dtype=float)
        self._acceleration = bool(include_acceleration)
        self._no_motion = np.zeros(6)
        self._poses_port = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        if self._acceleration:
            self._velocities_port = self.DeclareAbstractInputPort(
                "body_spatial_velocities",
                AbstractValue.Make([SpatialVelocity()] * plant.num_bodies()))
            self._accelerations_port = self.DeclareAbstractInputPort(
                "body_spatial_accelerations",
                AbstractValue.Make([SpatialAcceleration()] * plant.num_bodies()))
        # [g_S (3); ω_S (3); α_S (3)], computed once for both outputs.
        self._cache = self.DeclareCacheEntry(
            "apparent gravity and motion of S",
            ValueProducer(allocate=lambda: AbstractValue.Make(BasicVector(9)),
                          calc=self._calc),
            {self.all_input_ports_ticket()})
        self.DeclareVectorOutputPort("gravity_S", 3, self._calc_gravity,
                                     {self._cache.ticket()})
        self.DeclareVectorOutputPort("motion_S", 6, self._calc_motion, {self._cache.ticket()})

    def get_input_port_body_poses(self):
        return self.GetInputPort("body_poses")

    def get_input_port_body_spatial_velocities(self):
        return self.GetInputPort("body_spatial_velocities")

    def get_input_port_body_spatial_accelerations(self):
        return self.GetInputPort("body_spatial_accelerations")

    def get_output_port_gravity_S(self):
        return self.GetOutputPort("gravity_S")

    def get_output_port_motion_S(self):
        return self.GetOutputPort("motion_S")

    def _calc(self, context, value):
        # Runs at every sample the payload tracker takes: three port reads and one compiled
        # call (most of the time is the reads of the plant's abstract ports).
        X_WB = self._poses_port.Eval(context)[self._body]
        if self._acceleration:
            V_WB_W = self._velocities_port.Eval(context)[self._body].get_coeffs()
            A_WB_W = self._accelerations_port.Eval(context)[self._body].get_coeffs()
        else:
            V_WB_W = A_WB_W = self._no_motion
        _gravity_in_S(X_WB.rotation().matrix(), V_WB_W, A_WB_W, self._R_BS, self._p_BS,
                      self._g_W, value.get_mutable_value().get_mutable_value())

    def _calc_gravity(self, context, output: BasicVector):
        output.get_mutable_value()[:] = self._cache.Eval(context).value()[:3]

    def _calc_motion(self, context, output: BasicVector):
        output.get_mutable_value()[:] = self._cache.Eval(context).value()[3:]


@numba.njit(cache=True)
def _gravity_in_S(R_WB, V_WB_W, A_WB_W, R_BS, p_BS, g_W, out):
    """out = [g_S; ω_S; α_S] (9): g_S = R_SW·(g_W − a_So_W) with a_So_W = a_Bo + α × r +
    ω × (ω × r), r = R_WB·p_BS, and ω_S = R_SW·ω, α_S = R_SW·α, from V_WB_W = [ω; v_Bo] and
    A_WB_W = [α; a_Bo] (in W; zeros: gravity alone)."""
    p0 = R_WB[0, 0] * p_BS[0] + R_WB[0, 1] * p_BS[1] + R_WB[0, 2] * p_BS[2]
    p1 = R_WB[1, 0] * p_BS[0] + R_WB[1, 1] * p_BS[1] + R_WB[1, 2] * p_BS[2]
    p2 = R_WB[2, 0] * p_BS[0] + R_WB[2, 1] * p_BS[1] + R_WB[2, 2] * p_BS[2]
    w0, w1, w2 = V_WB_W[0], V_WB_W[1], V_WB_W[2]
    a0, a1, a2 = A_WB_W[0], A_WB_W[1], A_WB_W[2]
    # ω × r, then ω × (ω × r)
    c0, c1, c2 = w1 * p2 - w2 * p1, w2 * p0 - w0 * p2, w0 * p1 - w1 * p0
    cc0, cc1, cc2 = w1 * c2 - w2 * c1, w2 * c0 - w0 * c2, w0 * c1 - w1 * c0
    v = np.empty((3, 3))  # rows: g − a_So, ω, α in W
    v[0, 0] = g_W[0] - (A_WB_W[3] + (a1 * p2 - a2 * p1) + cc0)
    v[0, 1] = g_W[1] - (A_WB_W[4] + (a2 * p0 - a0 * p2) + cc1)
    v[0, 2] = g_W[2] - (A_WB_W[5] + (a0 * p1 - a1 * p0) + cc2)
    v[1, 0], v[1, 1], v[1, 2] = w0, w1, w2
    v[2, 0], v[2, 1], v[2, 2] = a0, a1, a2
    for k in range(3):
        # x_B = R_WBᵀ x_W, then x_S = R_BSᵀ x_B
        b0 = R_WB[0, 0] * v[k, 0] + R_WB[1, 0] * v[k, 1] + R_WB[2, 0] * v[k, 2]
        b1 = R_WB[0, 1] * v[k, 0] + R_WB[1, 1] * v[k, 1] + R_WB[2, 1] * v[k, 2]
        b2 = R_WB[0, 2] * v[k, 0] + R_WB[1, 2] * v[k, 1] + R_WB[2, 2] * v[k, 2]
        for j in range(3):
            out[3 * k + j] = R_BS[0, j] * b0 + R_BS[1, j] * b1 + R_BS[2, j] * b2
