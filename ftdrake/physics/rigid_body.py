"""Kinematics of the sensor frame and the Newton–Euler wrench of a rigid tool.

Independent of the plant's reaction-forces port: this is what the tests check the sensor
against, and what the physics payload compensator is built on.

Notation (Drake monogram): S is the sensor frame, So its origin, Scm the tool's centre of mass.
Everything is expressed in S unless the name says otherwise.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable

from ..conventions import GRAVITY_W


@dc.dataclass
class SensorKinematics:
    """Motion of frame S at N samples, expressed in S (arrays of shape (N, 3) / (N, 3, 3))."""

    R_WS: np.ndarray  # (N, 3, 3)
    w_WS_S: np.ndarray  # angular velocity, rad/s
    alpha_WS_S: np.ndarray  # angular acceleration, rad/s²
    a_WSo_S: np.ndarray  # translational acceleration of So, m/s²
    g_S: np.ndarray  # gravity, m/s²


def sensor_kinematics(plant, context, frame_S, q, v, vdot, instance=None) -> SensorKinematics:
    """Evaluates S's motion for rows of (q, v, v̇) of `instance` (the arm) in `plant`.

    Uses S's Jacobian and bias acceleration (``A = J·v̇ + J̇·v``) with the given v̇, so it needs
    no forces and no dynamics.
    """
    q, v, vdot = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, v, vdot))
    n = len(q)
    out = {k: np.empty((n, 3)) for k in ("w", "alpha", "a", "g")}
    R = np.empty((n, 3, 3))
    W = plant.world_frame()
    full_vdot = np.zeros(plant.num_velocities())
    origin = np.zeros(3)
    for k in range(n):
        if instance is None:
            plant.SetPositions(context, q[k])
            plant.SetVelocities(context, v[k])
            full_vdot[:] = vdot[k]
        else:
            plant.SetPositions(context, instance, q[k])
            plant.SetVelocities(context, instance, v[k])
            plant.SetVelocitiesInArray(instance, vdot[k], full_vdot)
        J = plant.CalcJacobianSpatialVelocity(
            context, JacobianWrtVariable.kV, frame_S, origin, W, W)
        bias = plant.CalcBiasSpatialAcceleration(
            context, JacobianWrtVariable.kV, frame_S, origin, W, W)
        V_WS_W = J @ plant.GetVelocities(context)
        A_WS_W = J @ full_vdot + np.concatenate([bias.rotational(), bias.translational()])
        R_WS = frame_S.CalcPoseInWorld(context).rotation().matrix()
        R[k] = R_WS
        out["w"][k] = V_WS_W[:3] @ R_WS
        out["alpha"][k] = A_WS_W[:3] @ R_WS
        out["a"][k] = A_WS_W[3:] @ R_WS
        out["g"][k] = np.asarray(GRAVITY_W) @ R_WS
    return SensorKinematics(R, out["w"], out["alpha"], out["a"], out["g"])


def newton_euler_wrench(mass, p_SoScm_S, I_Scm_S, kin: SensorKinematics) -> np.ndarray:
    """The wrench (N × 6, ``[F; T]`` about So in S) a rigid tool applies to the sensor.

    It is the tool's weight minus its inertial force: ``F = m (g − a_Scm)``,
    ``T = p_SoScm × F − (I α + ω × I ω)``, with ``a_Scm = a_So + α × p + ω × (ω × p)``.
    """
    p = np.asarray(p_SoScm_S, dtype=float)
    I = np.asarray(I_Scm_S, dtype=float)
    w, alpha = kin.w_WS_S, kin.alpha_WS_S
    a_Scm = kin.a_WSo_S + np.cross(alpha, p) + np.cross(w, np.cross(w, p))
    force = mass * (kin.g_S - a_Scm)
    torque = np.cross(p, force) - (alpha @ I.T + np.cross(w, w @ I.T))
    return np.hstack([force, torque])


def tool_inertia(plant, context, frame_S, bodies) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, p_SoScm_S, I_Scm_S) of the rigid assembly `bodies`, from the plant's model."""
    M_SSo_S = plant.CalcSpatialInertia(context, frame_S, bodies)
    p = M_SSo_S.get_com()
    I_Scm = M_SSo_S.Shift(p).CalcRotationalInertia().CopyToFullMatrix3()
    return M_SSo_S.get_mass(), p, I_Scm


def skew(v):
    """[v]× for (..., 3) vectors: ``skew(v) @ u = v × u`` (..., 3, 3)."""
    v = np.asarray(v)
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def inertia_map(x):
    """L(x) (..., 3, 6) with I·x = L(x)·[Ixx, Ixy, Ixz, Iyy, Iyz, Izz] for a symmetric I."""
    x = np.asarray(x)
    L = np.zeros((*x.shape[:-1], 3, 6))
    L[..., 0, 0], L[..., 0, 1], L[..., 0, 2] = x[..., 0], x[..., 1], x[..., 2]
    L[..., 1, 1], L[..., 1, 3], L[..., 1, 4] = x[..., 0], x[..., 1], x[..., 2]
    L[..., 2, 2], L[..., 2, 4], L[..., 2, 5] = x[..., 0], x[..., 1], x[..., 2]
    return L
