"""The hole-cutting benchmark's path: a circle in a plane, entered along an arc lead-in.

:class:`HolePath` is the ideal tool-tip path (position, in-plane normal, which part is the hole)
as a function of time; :func:`hole_trajectory` turns it into the arm's joint trajectory by
inverse kinematics (tip on the path to 1 µm, tool axis normal to the plane), solved point by
point from the previous solution so the joint path is smooth.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.trajectories import PiecewisePolynomial

from ..config.contour import HoleConfig
from ..errors import TrajectoryError

IK_RATE_HZ = 100.0  # IK knots per second; the joint spline interpolates between them


def _smoothstep(s):
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


@dc.dataclass
class HolePath:
    """The ideal path of the tool tip for one hole, in W and in the plane frame P.

    Arc length s runs over: the lead-in, a half circle of radius r/2 from the centre that
    meets the hole at P's +x tangentially (length π r/2); the hole, one turn
    counter-clockwise about P's z (2π r); the lead-out, the first π r/2 of the hole again
    while slowing down. Speed: smooth ramp from 0 to ``speed`` over the lead-in, constant
    on the hole, ramp down over the lead-out; rests of ``rest_s`` before and after.
    """

    p_WC: np.ndarray  # the hole's centre (m)
    R_WP: np.ndarray  # the plane's frame: x, y in the plane, z its normal (up)
    radius: float
    speed: float
    rest_s: float

    @classmethod
    def from_config(cls, hole: HoleConfig, p_WHome: np.ndarray) -> HolePath:
        hole.validate()
        return cls(np.asarray(p_WHome, float) + np.asarray(hole.offset_m, float), np.eye(3),
                   0.5 * hole.diameter_m, hole.speed_m_s, hole.rest_s)

    @property
    def lead_length(self) -> float:
        return 0.5 * np.pi * self.radius

    @property
    def ramp_s(self) -> float:
        """Duration of the ramp up (and down): a smoothstep speed covers speed·T/2."""
        return 2.0 * self.lead_length / self.speed

    @property
    def hole_window(self) -> tuple[float, float]:
        """(start, end) times (s) of the hole's one full turn at constant speed."""
        start = self.rest_s + self.ramp_s
        return start, start + 2 * np.pi * self.radius / self.speed

    @property
    def duration(self) -> float:
        return self.hole_window[1] + self.ramp_s + self.rest_s

    def arc_length(self, t) -> np.ndarray:
        """s(t) (m) along the path."""
        t = np.asarray(t, dtype=float)
        T, v, t0 = self.ramp_s, self.speed, self.rest_s
        t2 = self.hole_window[1]
        # ∫ smoothstep(τ/T) dτ = T · (5/2 u⁴ − 3 u⁵ + u⁶) with u = τ/T, clipped.
        def ramp_integral(tau):
            u = np.clip(tau / T, 0.0, 1.0)
            return T * (2.5 * u**4 - 3 * u**5 + u**6) + np.maximum(tau - T, 0.0)
        up = v * ramp_integral(t - t0)
        down = v * (np.clip(t - t2, 0.0, T) - ramp_integral(np.clip(t - t2, 0.0, T)))
        return np.where(t < t2, up, self.lead_length + 2 * np.pi * self.radius + down)

    def point_P(self, s) -> np.ndarray:
        """In-plane positions (N, 2) at arc lengths s, relative to the centre."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        r, lead = self.radius, self.lead_length
        out = np.empty((len(s), 2))
        on_lead = s < lead
        phi = np.pi + s[on_lead] / (0.5 * r)  # lead-in half circle about (r/2, 0): π → 2π
        out[on_lead] = np.column_stack([0.5 * r + 0.5 * r * np.cos(phi), 0.5 * r * np.sin(phi)])
        theta = (s[~on_lead] - lead) / r
        out[~on_lead] = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
        return out

    def position_W(self, t) -> np.ndarray:
        """Tip positions p_WTip (N, 3) at times t."""
        p = self.point_P(self.arc_length(t))
        return self.p_WC + np.column_stack([p, np.zeros(len(p))]) @ self.R_WP.T

    def hole_mask(self, t) -> np.ndarray:
        """True at times on the hole's one full turn."""
        t = np.asarray(t, dtype=float)
        start, end = self.hole_window
        return (t >= start) & (t <= end)

    def radial_error(self, p_W) -> np.ndarray:
        """Distance from the hole's centre in the plane minus the radius (m), per row."""
        p = (np.asarray(p_W, float) - self.p_WC) @ self.R_WP
        return np.linalg.norm(p[:, :2], axis=1) - self.radius

    def to_plane(self, p_W) -> np.ndarray:
        """(N, 2) in-plane coordinates relative to the centre."""
        return ((np.asarray(p_W, float) - self.p_WC) @ self.R_WP)[:, :2]

    def ideal_contour(self, spacing: float = 0.2e-3) -> tuple[np.ndarray, np.ndarray]:
        """(points, outward normals), each (M, 2): the ideal hole every `spacing` m."""
        theta = np.arange(0.0, 2 * np.pi, spacing / self.radius)
        normal = np.column_stack([np.cos(theta), np.sin(theta)])
        return self.radius * normal, normal


def hole_trajectory(path: HolePath, geometry, q_start) -> PiecewisePolynomial:
    """The joint trajectory that puts the tool tip on `path`, the tool pointing down the
    plane's normal, by IK at IK_RATE_HZ knots from `q_start` onwards.

    Each knot is solved by Gauss–Newton from the previous one with least-norm steps
    (``lstsq``): the 7-joint arm has two redundant directions (five constraints: the tip's
    position and the tool axis), and least-norm steps move along them as little as
    possible, so the joint path is as smooth as the tool path. `geometry` is a
    :class:`~ftdrake.sim.trajectories.RobotGeometry`.
    """
    plant, arm = geometry.plant, geometry.arm
    context = plant.CreateDefaultContext()
    p_STip, z_Tip_S = geometry.tool_tip()
    sensor = geometry._scene.sensor_frame
    axis_W = -path.R_WP[:, 2]
    times = np.arange(0.0, path.duration + 1e-9, 1.0 / IK_RATE_HZ)
    points = path.position_W(times)
    q = np.asarray(q_start, dtype=float).copy()
    Q = np.empty((len(q), len(times)))
    for i, (t, p_W) in enumerate(zip(times, points, strict=True)):
        q = _solve_tip_ik(plant, arm, context, sensor, p_STip, z_Tip_S, p_W, axis_W, q, t)
        Q[:, i] = q
    zero = np.zeros((Q.shape[0], 1))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(times, Q, zero, zero)


def _solve_tip_ik(plant, arm, context, sensor, p_STip, z_Tip_S, p_WTip, axis_W, q, t,
                  tol: float = 1e-10, max_iterations: int = 50):
    project = np.eye(3) - np.outer(axis_W, axis_W)  # the spin about the tool axis is free
    world = plant.world_frame()
    for _ in range(max_iterations):
        plant.SetPositions(context, arm, q)
        X_WS = sensor.CalcPoseInWorld(context)
        error_p = p_WTip - X_WS @ p_STip
        z_W = X_WS.rotation() @ z_Tip_S
        error_o = project @ np.cross(z_W, axis_W)
        error = np.concatenate([error_p, error_o])
        if np.abs(error).max() < tol:
            return q
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kQDot, sensor,
                                              p_STip, world, world)
        J = plant.GetVelocitiesFromArray(arm, J.T).T if J.shape[1] != len(q) else J
        A = np.vstack([J[3:], project @ J[:3]])
        q = q + np.linalg.lstsq(A, error, rcond=1e-9)[0]
    raise TrajectoryError(f"hole path: no arm configuration puts the tool tip at "
                          f"{np.round(p_WTip, 4).tolist()} (t = {t:.2f} s) pointing down the "
                          f"plane's normal; move the hole (offset_m) or shrink it")


__all__ = ["HolePath", "hole_trajectory"]
