"""Registering tool-side measurements to the robot: frames and clocks, with standard errors.

A laser tracker measures in its own frame T and stamps with its own clock; an inspection of a
cut part measures in the part's or the instrument's frame. Before a measured tool error means
anything, the measurement has to be put in the robot's base frame B (= W here) and, for a
timed one, on the controller's clock. This module estimates those transforms:

* :func:`rigid_fit`: ``p_B = R_BT p_T + p_BT`` from matched points (fiducials: points known
  in B, e.g. nests on the robot's base, measured by the tracker), by the SVD solution
  (Kabsch) in 2-D or 3-D;
* :func:`register_timed`: the tracker's pose X_BT *and* its clock,
  ``t_tracker = (1 + skew) · t_controller + offset``, from a timed path against the path the
  tool was modelled to follow (the commanded path, or the forward kinematics of the motor
  angles); or, with the pose fixed by fiducials, the clock alone;
* :func:`register_contour`: an untimed point list (a scan of the cut edge, 2-D or 3-D) to the
  commanded path by iterated closest points (point-to-point ICP, then Gauss–Newton on the
  distances along the closest points' normals).

Each estimate carries standard errors from the linearised least-squares problem,
``cov = σ̂² (JᵀJ)⁺`` with ``σ̂² = RSS / (m − p)``: they are right for independent noise and
too small when the residual is mostly the tool's own error (correlated along the path).
A direction the data barely determine shows as a large standard error (a circle's rotation
about its centre, for a scan of a round hole: it stays near the initial guess); one they do
not determine at all, as an infinite one.

What path registration cannot see: the rigid part of the tool's error. Registered to the
commanded path, a hole cut 1 mm off-centre looks centred; only its shape and size error
remain. Fiducials (or datum features of the part) keep the offset.

Units: metres, seconds, radians; rotations as rotation vectors (axis × angle) in reports.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..errors import LogError

#: Relative singular value below which a direction of the least-squares problem counts as
#: undetermined by the data (its standard error is reported as infinite).
UNDETERMINED = 1e-7
#: Gauss–Newton steps of :func:`register_contour` ignore directions whose singular value is
#: below this fraction of the largest (they are left at the initial guess).
STEP_RCOND = 1e-2


@dc.dataclass
class Registration:
    """A rigid transform ``p_B = R p_M + p`` (M: the measuring instrument's frame) and, for a
    timed measurement, a clock ``t_M = (1 + skew) · t_B + offset_s``.

    ``*_se`` are standard errors (rad for the rotation vector's components, m, s, 1);
    ``rms_m`` the residual's RMS after registration; ``n`` the points used.
    """

    R: np.ndarray  # (d, d)
    p: np.ndarray  # (d,)
    rotation_se: np.ndarray  # (3,) in 3-D, (1,) in 2-D (about the plane's normal)
    p_se: np.ndarray
    rms_m: float
    n: int
    offset_s: float = 0.0
    skew: float = 0.0
    offset_se: float = 0.0
    skew_se: float = 0.0

    def apply(self, points) -> np.ndarray:
        """Measured points (N, d) in the instrument's frame → (N, d) in B."""
        return np.asarray(points, dtype=float) @ self.R.T + self.p

    def to_controller_time(self, t_measured) -> np.ndarray:
        """Instrument stamps (N,) → controller times (N,)."""
        return (np.asarray(t_measured, dtype=float) - self.offset_s) / (1.0 + self.skew)

    def rotation_vector(self) -> np.ndarray:
        """R as a rotation vector (3,) in 3-D or its angle (1,) in 2-D (rad)."""
        if len(self.R) == 2:
            return np.array([np.arctan2(self.R[1, 0], self.R[0, 0])])
        return Rotation.from_matrix(self.R).as_rotvec()

    def report(self) -> dict:
        """A JSON-ready summary: the estimates with their standard errors."""
        return {"rotation_rad": self.rotation_vector().tolist(),
                "rotation_se_rad": self.rotation_se.tolist(),
                "offset_m": self.p.tolist(), "offset_se_m": self.p_se.tolist(),
                "clock_offset_s": float(self.offset_s), "clock_offset_se_s": float(self.offset_se),
                "clock_skew": float(self.skew), "clock_skew_se": float(self.skew_se),
                "rms_m": float(self.rms_m), "points": int(self.n)}


def _rotation(d: int, w) -> np.ndarray:
    """The rotation of small-angle parameters w (1 in 2-D, 3 in 3-D)."""
    if d == 2:
        c, s = np.cos(w[0]), np.sin(w[0])
        return np.array([[c, -s], [s, c]])
    return Rotation.from_rotvec(w).as_matrix()


def _n_rot(d: int) -> int:
    return 1 if d == 2 else 3


def _standard_errors(J: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Per parameter, ``sqrt(diag(σ̂² (JᵀJ)⁺))``; infinite along undetermined directions."""
    m, k = J.shape
    sigma2 = float(residual @ residual) / max(m - k, 1)
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    good = s > UNDETERMINED * s[0]
    cov = (Vt[good].T / s[good]**2) @ Vt[good] * sigma2
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if not good.all():  # a parameter with weight in the null space is not determined
        se[np.abs(Vt[~good]).max(axis=0) > 1e-3] = np.inf
    return se


def _check_points(points, name: str, least: int) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise LogError(f"{name}: need an (N, 2) or (N, 3) array of points, got shape "
                       f"{points.shape}")
    if len(points) < least:
        raise LogError(f"{name}: {len(points)} points are too few (need >= {least})")
    if not np.isfinite(points).all():
        raise LogError(f"{name}: holds NaN or infinity")
    return points


def rigid_fit(measured, known) -> Registration:
    """The rigid transform taking `measured` (N, d) points onto `known` (N, d) ones in B
    (row i of each is the same physical point; d = 2 or 3), least squares (Kabsch), with
    standard errors. Needs N >= d + 1 points not on one line."""
    measured = _check_points(measured, "fiducials (measured)", 3)
    known = _check_points(known, "fiducials (known)", 3)
    if measured.shape != known.shape:
        raise LogError(f"fiducials: {measured.shape} measured points but {known.shape} known "
                       "ones; list the same points in both")
    d = measured.shape[1]
    cm, ck = measured.mean(0), known.mean(0)
    H = (measured - cm).T @ (known - ck)
    U, s, Vt = np.linalg.svd(H)
    if s[min(1, d - 1)] < 1e-9 * max(s[0], 1e-300):
        raise LogError("fiducials: the points lie on one line; the rotation about it is not "
                       "determined (use >= 3 points not in a line)")
    D = np.eye(d)
    D[-1, -1] = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ D @ U.T
    p = ck - R @ cm
    residual = (measured @ R.T + p - known).ravel()
    J = _rigid_jacobian(measured @ R.T, d)
    se = _standard_errors(J, residual)
    k = _n_rot(d)
    return Registration(R, p, se[:k], se[k:], float(np.sqrt(np.mean(residual**2)) * np.sqrt(d)),
                        len(measured))


def _rigid_jacobian(rotated: np.ndarray, d: int) -> np.ndarray:
    """∂(R p_M + p)/∂(w, p) stacked per point (N·d, k + d), w a rotation increment in B."""
    n = len(rotated)
    if d == 2:
        rot = np.column_stack([-rotated[:, 1], rotated[:, 0]]).reshape(n * 2, 1)
    else:  # δ(R p) = w × (R p) = −[R p]× w
        x, y, z = rotated.T
        zero = np.zeros(n)
        rot = np.stack([np.stack([zero, z, -y], 1), np.stack([-z, zero, x], 1),
                        np.stack([y, -x, zero], 1)], 1).reshape(n * 3, 3)
    return np.hstack([rot, np.tile(np.eye(d), (n, 1))])


# -- timed: frame and clock ---------------------------------------------------------------
def _speed_offset(t_meas, p_meas, t_model, p_model, max_offset_s: float) -> float:
    """A first clock offset: the lag that best aligns the measured speed profile with the
    model's (speed does not depend on the frame), by cross-correlation on a common grid."""
    dt = float(np.median(np.diff(t_model)))
    grid = np.arange(t_model[0], t_model[-1], dt)
    model_speed = np.linalg.norm(np.gradient(
        np.column_stack([np.interp(grid, t_model, c) for c in p_model.T]), dt, axis=0), axis=1)
    g2 = np.arange(t_meas[0], t_meas[-1], dt)
    meas_speed = np.linalg.norm(np.gradient(
        np.column_stack([np.interp(g2, t_meas, c) for c in p_meas.T]), dt, axis=0), axis=1)
    best, best_cost = 0.0, np.inf
    for lag in np.arange(-max_offset_s, max_offset_s + 0.5 * dt, dt):
        model_at = np.interp(g2 - lag, grid, model_speed, left=0.0, right=0.0)
        cost = float(np.mean((meas_speed - model_at)**2))
        if cost < best_cost:
            best, best_cost = float(lag), cost
    return best


def register_timed(t_measured, p_measured, t_model, p_model, *, fiducials=None,
                   max_offset_s: float = 0.5, estimate_skew: bool = True) -> Registration:
    """The tracker's frame and clock from a timed path.

    `t_measured` (N,) the tracker's stamps (s, its clock), `p_measured` (N, 3) the tool tip in
    its frame (m); `t_model` (M,), `p_model` (M, 3): the path the tool was modelled to follow
    in B on the controller's clock (commanded, or the motor angles' forward kinematics).
    Minimises ``Σ |R p_i + p − p_model((t_i − offset) / (1 + skew))|²`` over R, p, offset and
    skew (Levenberg–Marquardt, started from the speed profiles' best lag and the Kabsch fit
    at it). With `fiducials` (a :class:`Registration` from :func:`rigid_fit`) the frame is
    kept and the clock is estimated beside a constant translation of the path (the rigid part
    of the tool's error, which is not the frame's). `max_offset_s` bounds the first lag
    search.
    """
    t_measured = np.asarray(t_measured, dtype=float)
    t_model = np.asarray(t_model, dtype=float)
    p_measured = _check_points(p_measured, "tracker log", 10)
    p_model = _check_points(p_model, "modelled path", 10)
    offset0 = _speed_offset(t_measured, p_measured, t_model, p_model, max_offset_s)

    def model_at(t):
        return np.column_stack([np.interp(t, t_model, c) for c in p_model.T])

    inside = (t_measured - offset0 >= t_model[0]) & (t_measured - offset0 <= t_model[-1])
    if inside.sum() < 10:
        raise LogError(f"tracker log: only {int(inside.sum())} samples overlap the modelled "
                       f"path's time span after the clock offset {offset0:.3f} s; is it the "
                       "same run?")
    t, p_m = t_measured[inside], p_measured[inside]
    if fiducials is None:
        start = rigid_fit(p_m, model_at(t - offset0))
        R0, p0 = start.R, start.p
    else:
        R0, p0 = fiducials.R, fiducials.p
    frame = fiducials is None
    t_ref = float(t[0])  # the skew acts about the first sample (better conditioned)
    # Parameters: [rotation increment (3), offset increment (3)] with the frame free, or a
    # nuisance translation (3) with the frame from fiducials (the rigid part of the tool's
    # own error, which a clock shift would otherwise try to explain); then the clock's
    # offset and skew.

    def unpack(x):
        R = _rotation(3, x[:3]) @ R0 if frame else R0
        p = p0 + x[3:6] if frame else p0 + x[:3]
        k = 6 if frame else 3
        skew = x[k + 1] if estimate_skew else 0.0
        return R, p, offset0 + x[k], skew

    def residual(x):
        R, p, offset, skew = unpack(x)
        t_c = t_ref + (t - t_ref - offset) / (1.0 + skew)
        return (p_m @ R.T + p - model_at(t_c)).ravel()

    k = 6 if frame else 3
    x_scale = np.array([1e-3] * k + [1e-3, 1e-5][:2 if estimate_skew else 1])
    fit = least_squares(residual, np.zeros(len(x_scale)), method="lm", x_scale=x_scale)
    R, p, offset, skew = unpack(fit.x)
    if not frame:
        p = p0  # the nuisance translation belongs to the tool, not to the frame
    se = _standard_errors(fit.jac, fit.fun)
    # The clock on the skew's reference: t_M = (1 + s) t_B + offset − s · t_ref.
    offset_at_zero = offset - skew * t_ref
    skew_se = float(se[k + 1]) if estimate_skew else 0.0
    offset_se = float(np.hypot(se[k], t_ref * skew_se))
    rotation_se = se[:3] if frame else fiducials.rotation_se
    p_se = se[3:6] if frame else fiducials.p_se
    rms = float(np.sqrt(np.mean(fit.fun**2) * 3))
    return Registration(R, p, rotation_se, p_se, rms, len(t), float(offset_at_zero), float(skew),
                        offset_se, skew_se)


# -- untimed: a point list to a path ------------------------------------------------------
def densify(path, spacing: float) -> np.ndarray:
    """The polyline `path` (N, d) with points at most `spacing` m apart."""
    path = np.asarray(path, dtype=float)
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = np.union1d(s, np.arange(0.0, s[-1], spacing))
    return np.column_stack([np.interp(at, s, c) for c in path.T])


def register_contour(points, path, *, spacing: float = 20e-6, iterations: int = 50,
                     initial: Registration | None = None, max_distance: float = np.inf
                     ) -> Registration:
    """An untimed point list `points` (N, d), m, in the instrument's frame, registered to the
    polyline `path` (M, d) in B (d = 2: the cutting plane's coordinates; 3: W).

    Starts from `initial` (default: the centroids matched, no rotation), runs point-to-point
    ICP against `path` densified every `spacing` m, then Gauss–Newton on the distances along
    the closest points' directions (point-to-line), ignoring points farther than
    `max_distance` from the path. A round contour's rotation about its centre is not
    determined: it stays near the initial value and its standard error is large.
    """
    points = _check_points(points, "contour points", 10)
    path = _check_points(path, "commanded path", 2)
    d = points.shape[1]
    if path.shape[1] != d:
        raise LogError(f"contour points are {d}-D but the commanded path is "
                       f"{path.shape[1]}-D; give both in the plane (2-D) or in W (3-D)")
    dense = densify(path, spacing)
    tree = cKDTree(dense)
    spread = float(np.sqrt(np.mean(np.sum((points - points.mean(0))**2, axis=1)))) or 1.0
    if initial is None:
        R, p = np.eye(d), dense.mean(0) - points.mean(0)
    else:
        R, p = initial.R.copy(), initial.p.copy()
    k = _n_rot(d)
    for _ in range(iterations):  # point-to-point ICP
        moved = points @ R.T + p
        _, index = tree.query(moved)
        step, R, p = _icp_step(moved, dense[index], R, p)
        if step < 1e-10:
            break
    for _ in range(iterations):  # point-to-line Gauss–Newton
        r, J, use = _line_problem(points @ R.T + p, dense, tree, max_distance)
        # Steps only along directions the data determine (the rotation's columns scaled to
        # metres at the points' spread): a round contour's spin stays where it is.
        J[:, :k] /= spread
        x = np.linalg.lstsq(J, -r, rcond=STEP_RCOND)[0]
        x[:k] /= spread
        R, p = _rotation(d, x[:k]) @ R, _rotation(d, x[:k]) @ p + x[k:]
        if np.abs(x).max() < 1e-12:
            break
    r, J, use = _line_problem(points @ R.T + p, dense, tree, max_distance)
    se = _standard_errors(J, r)
    return Registration(R, p, se[:k], se[k:], float(np.sqrt(np.mean(r**2) * d)),
                        int(use.sum()))


def _line_problem(moved, dense, tree, max_distance):
    """Residuals (n·d,) from each point to its foot on the polyline `dense` (the nearer of the
    two segments at the nearest vertex), the rigid Jacobian projected off the segment's
    tangent (point-to-line), and which points are used (within `max_distance`)."""
    d = moved.shape[1]
    _, index = tree.query(moved)
    foot = np.empty_like(moved)
    tangent = np.empty_like(moved)
    best = np.full(len(moved), np.inf)
    for a, b in ((index - 1, index), (index, index + 1)):
        a, b = np.clip(a, 0, len(dense) - 1), np.clip(b, 0, len(dense) - 1)
        seg = dense[b] - dense[a]
        length2 = np.einsum("ij,ij->i", seg, seg)
        ok = length2 > 0
        u = np.zeros(len(moved))
        u[ok] = np.clip(np.einsum("ij,ij->i", moved[ok] - dense[a][ok], seg[ok]) / length2[ok],
                        0.0, 1.0)
        at = dense[a] + u[:, None] * seg
        distance = np.where(ok, np.linalg.norm(moved - at, axis=1), np.inf)
        closer = distance < best
        foot[closer] = at[closer]
        tangent[closer] = seg[closer] / np.sqrt(length2[closer])[:, None]
        best = np.minimum(best, distance)
    use = best <= max_distance
    moved, foot, tangent = moved[use], foot[use], tangent[use]
    project = np.eye(d)[None] - tangent[:, :, None] * tangent[:, None, :]
    r = np.einsum("nij,nj->ni", project, moved - foot).ravel()
    J = np.einsum("nij,njk->nik", project,
                  _rigid_jacobian(moved, d).reshape(len(moved), d, -1)).reshape(r.size, -1)
    return r, J, use


def _icp_step(moved, matched, R, p):
    """One Kabsch update of (R, p) from matched pairs; returns (step size, R, p)."""
    d = moved.shape[1]
    cm, cc = moved.mean(0), matched.mean(0)
    U, _, Vt = np.linalg.svd((moved - cm).T @ (matched - cc))
    D = np.eye(d)
    D[-1, -1] = np.sign(np.linalg.det(Vt.T @ U.T))
    dR = Vt.T @ D @ U.T
    dp = cc - dR @ cm
    step = float(np.abs(dR - np.eye(d)).max() + np.abs(dp).max())
    return step, dR @ R, dR @ p + dp


__all__ = ["Registration", "densify", "register_contour", "register_timed", "rigid_fit"]
