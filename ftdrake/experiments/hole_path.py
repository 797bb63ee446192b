"""The hole-cutting benchmark's path: a circle or a slot in a plane, entered along an arc lead-in.

:class:`HolePath` is the ideal tool-tip path (position, in-plane normal, which part is the hole)
as a function of time; :func:`hole_trajectory` turns it into the arm's joint trajectory by
inverse kinematics (tip on the path to 1 µm, tool axis along the path's, normal to the plane
unless the tool is tilted), solved point by point from the previous solution so the joint path
is smooth. The contour (:class:`Circle` or :class:`Slot`), its direction, the plane's normal,
a 3-D rise and the tool's tilt come from :class:`~ftdrake.config.contour.HoleConfig`.
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


@dc.dataclass(frozen=True)
class Circle:
    """A circle of `radius` about the origin, from (r, 0) counter-clockwise."""

    radius: float

    @property
    def start(self) -> float:
        """The contour's start (start, 0) on P's +x axis; its tangent there is +y."""
        return self.radius

    @property
    def length(self) -> float:
        return 2 * np.pi * self.radius

    def point(self, u) -> np.ndarray:
        """(N, 2) at arc lengths u (periodic) from the start."""
        theta = np.asarray(u, dtype=float) / self.radius
        return np.column_stack([self.radius * np.cos(theta), self.radius * np.sin(theta)])

    def normal(self, u) -> np.ndarray:
        """Outward unit normals (N, 2) at arc lengths u."""
        theta = np.asarray(u, dtype=float) / self.radius
        return np.column_stack([np.cos(theta), np.sin(theta)])

    def signed_distance(self, p) -> np.ndarray:
        """Distance of each row of p (N, 2) from the contour, > 0 outside."""
        return np.linalg.norm(p, axis=1) - self.radius


@dc.dataclass(frozen=True)
class Slot:
    """A rectangle of half sides (`half_x`, `half_y`) about the origin with corners rounded to
    `corner`, from (half_x, 0) counter-clockwise: eight pieces, straight sides and quarter
    circles."""

    half_x: float
    half_y: float
    corner: float

    @property
    def start(self) -> float:
        return self.half_x

    def _pieces(self):
        """(length, kind, data) per piece in order: ("line", (p0, direction)) or
        ("arc", (centre, angle0))."""
        a, b, rc = self.half_x - self.corner, self.half_y - self.corner, self.corner
        quarter = 0.5 * np.pi * rc
        return [(b, "line", ((self.half_x, 0.0), (0.0, 1.0))),
                (quarter, "arc", ((a, b), 0.0)),
                (2 * a, "line", ((a, self.half_y), (-1.0, 0.0))),
                (quarter, "arc", ((-a, b), 0.5 * np.pi)),
                (2 * b, "line", ((-self.half_x, b), (0.0, -1.0))),
                (quarter, "arc", ((-a, -b), np.pi)),
                (2 * a, "line", ((-a, -self.half_y), (1.0, 0.0))),
                (quarter, "arc", ((a, -b), 1.5 * np.pi)),
                (b, "line", ((self.half_x, -b), (0.0, 1.0)))]

    @property
    def length(self) -> float:
        return float(sum(piece[0] for piece in self._pieces()))

    def _evaluate(self, u):
        u = np.mod(np.atleast_1d(np.asarray(u, dtype=float)), self.length)
        point, normal = np.empty((len(u), 2)), np.empty((len(u), 2))
        begin = 0.0
        for length, kind, data in self._pieces():
            on = (u >= begin) & (u <= begin + length)
            v = u[on] - begin
            if kind == "line":
                (x0, y0), (dx, dy) = data
                point[on] = np.column_stack([x0 + v * dx, y0 + v * dy])
                normal[on] = [dy, -dx]  # the tangent turned clockwise: outwards
            else:
                (cx, cy), angle0 = data
                angle = angle0 + v / self.corner
                normal[on] = np.column_stack([np.cos(angle), np.sin(angle)])
                point[on] = [cx, cy] + self.corner * normal[on]
            begin += length
        return point, normal

    def point(self, u) -> np.ndarray:
        return self._evaluate(u)[0]

    def normal(self, u) -> np.ndarray:
        return self._evaluate(u)[1]

    def signed_distance(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        inner = np.array([self.half_x - self.corner, self.half_y - self.corner])
        q = np.abs(p) - inner
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0) - self.corner


def plane_frame(normal) -> np.ndarray:
    """R_WP for a plane of normal `normal` (in W): z along it, x the projection of W's x onto
    the plane (W's y when x is nearly normal to it), y = z × x. Exactly I for +z."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    if n[0] == 0.0 and n[1] == 0.0 and n[2] > 0:
        return np.eye(3)
    x = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(x) < 0.1:
        x = np.array([0.0, 1.0, 0.0]) - n[1] * n
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


@dc.dataclass
class HolePath:
    """The ideal path of the tool tip for one contour, in W and in the plane frame P.

    Arc length s runs over: the lead-in, a half circle of radius a/2 from the centre that
    meets the contour at P's (a, 0) tangentially (length π a/2; a = `radius`, the contour's
    distance from the centre there); the contour, one turn (``outline.length``)
    counter-clockwise about P's z, or clockwise when `direction` is −1 (the whole path
    mirrored in P's x axis); the lead-out, the first π a/2 of the contour again while slowing
    down. Speed: smooth ramp from 0 to ``speed`` over the lead-in, constant on the contour,
    ramp down over the lead-out; rests of ``rest_s`` before and after. `height`, `tilt`: the
    3-D rise out of the plane (m) and the tool's lean (rad), see
    :class:`~ftdrake.config.contour.HoleConfig`.
    """

    p_WC: np.ndarray  # the hole's centre (m)
    R_WP: np.ndarray  # the plane's frame: x, y in the plane, z its normal (up)
    radius: float
    speed: float
    rest_s: float
    outline: Circle | Slot | None = None  # None: a circle of `radius`
    direction: float = 1.0  # +1 counter-clockwise about P's z, −1 clockwise
    height: float = 0.0
    tilt: float = 0.0

    def __post_init__(self):
        if self.outline is None:
            self.outline = Circle(self.radius)

    @classmethod
    def from_config(cls, hole: HoleConfig, p_WHome: np.ndarray) -> HolePath:
        hole.validate()
        outline = (Slot(0.5 * hole.slot_m[0], 0.5 * hole.slot_m[1], hole.corner_radius_m)
                   if hole.slot_m else Circle(0.5 * hole.diameter_m))
        return cls(np.asarray(p_WHome, float) + np.asarray(hole.offset_m, float),
                   plane_frame(hole.normal), outline.start, hole.speed_m_s, hole.rest_s,
                   outline, 1.0 if hole.direction == "ccw" else -1.0, hole.height_m,
                   np.radians(hole.tool_tilt_deg))

    @property
    def lead_length(self) -> float:
        return 0.5 * np.pi * self.radius

    @property
    def ramp_s(self) -> float:
        """Duration of the ramp up (and down): a smoothstep speed covers speed·T/2."""
        return 2.0 * self.lead_length / self.speed

    @property
    def hole_window(self) -> tuple[float, float]:
        """(start, end) times (s) of the contour's one full turn at constant speed."""
        start = self.rest_s + self.ramp_s
        return start, start + self.outline.length / self.speed

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
        return np.where(t < t2, up, self.lead_length + self.outline.length + down)

    def _phase(self, s) -> np.ndarray:
        """sin²(2π u / L) along the contour (0 on the lead-in): the 3-D rise's and the tool
        tilt's profile."""
        u = np.maximum(np.asarray(s, dtype=float) - self.lead_length, 0.0)
        return np.sin(2 * np.pi * u / self.outline.length) ** 2

    def point_P(self, s) -> np.ndarray:
        """In-plane positions (N, 2) at arc lengths s, relative to the centre."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        r, lead = self.radius, self.lead_length
        out = np.empty((len(s), 2))
        on_lead = s < lead
        phi = np.pi + s[on_lead] / (0.5 * r)  # lead-in half circle about (r/2, 0): π → 2π
        out[on_lead] = np.column_stack([0.5 * r + 0.5 * r * np.cos(phi), 0.5 * r * np.sin(phi)])
        out[~on_lead] = self.outline.point(s[~on_lead] - lead)
        if self.direction != 1.0:
            out[:, 1] *= -1.0
        return out

    def normal_P(self, t) -> np.ndarray:
        """The contour's outward unit normals (N, 2) in P at times t (on the contour)."""
        u = np.atleast_1d(self.arc_length(t)) - self.lead_length
        normal = self.outline.normal(u)
        if self.direction != 1.0:
            normal[:, 1] *= -1.0
        return normal

    def position_W(self, t) -> np.ndarray:
        """Tip positions p_WTip (N, 3) at times t."""
        s = np.atleast_1d(self.arc_length(t))
        p = self.point_P(s)
        z = self.height * self._phase(s) if self.height > 0 else np.zeros(len(p))
        return self.p_WC + np.column_stack([p, z]) @ self.R_WP.T

    def tool_axis_W(self, t) -> np.ndarray:
        """The tool axis (unit, N × 3) in W at times t: down the plane's normal, leaning
        towards the contour's outward normal by ``tilt · sin²(2π u / L)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        down = np.tile(-self.R_WP[:, 2], (len(t), 1))
        if self.tilt == 0:
            return down
        s = self.arc_length(t)
        beta = self.tilt * self._phase(s)
        normal = self.normal_P(t)
        lean = np.column_stack([normal, np.zeros(len(t))]) @ self.R_WP.T
        return np.cos(beta)[:, None] * down + np.sin(beta)[:, None] * lean

    def hole_mask(self, t) -> np.ndarray:
        """True at times on the contour's one full turn."""
        t = np.asarray(t, dtype=float)
        start, end = self.hole_window
        return (t >= start) & (t <= end)

    def radial_error(self, p_W) -> np.ndarray:
        """Signed distance (m) of each row from the contour in the plane (P's xy; > 0
        outside); for a circle, the distance from the centre minus the radius."""
        p = ((np.asarray(p_W, float) - self.p_WC) @ self.R_WP)[:, :2]
        if self.direction != 1.0:
            p[:, 1] *= -1.0
        return self.outline.signed_distance(p)

    def to_plane(self, p_W) -> np.ndarray:
        """(N, 2) in-plane coordinates relative to the centre."""
        return ((np.asarray(p_W, float) - self.p_WC) @ self.R_WP)[:, :2]

    def ideal_contour(self, spacing: float = 0.2e-3) -> tuple[np.ndarray, np.ndarray]:
        """(points, outward normals), each (M, 2): the ideal contour every `spacing` m."""
        u = np.arange(0.0, self.outline.length, spacing)
        points, normal = self.outline.point(u), self.outline.normal(u)
        if self.direction != 1.0:
            points[:, 1] *= -1.0
            normal[:, 1] *= -1.0
        return points, normal


def hole_trajectory(path: HolePath, geometry, q_start) -> PiecewisePolynomial:
    """The joint trajectory that puts the tool tip on `path`, the tool along its
    ``tool_axis_W`` (down the plane's normal unless tilted), by IK at IK_RATE_HZ knots from
    `q_start` onwards.

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
    times = np.arange(0.0, path.duration + 1e-9, 1.0 / IK_RATE_HZ)
    points, axes = path.position_W(times), path.tool_axis_W(times)
    q = np.asarray(q_start, dtype=float).copy()
    Q = np.empty((len(q), len(times)))
    for i, (t, p_W, axis_W) in enumerate(zip(times, points, axes, strict=True)):
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


__all__ = ["Circle", "HolePath", "Slot", "hole_trajectory", "plane_frame"]
