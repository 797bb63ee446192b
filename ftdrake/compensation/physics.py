"""Physics payload compensator: the tool's inertial parameters and the sensor's biases,
identified by least squares from the Newton–Euler wrench regressor.

The reading of a sensor carrying a rigid tool is linear in the tool's 10 inertial parameters
``φ = [m, m·c (3), I_So (6)]`` (mass, first moment, inertia about So; all in S) plus 6 biases:

    F = −m (a − g) − ([α]× + [ω]×[ω]×) m·c
    T = [a − g]× m·c − (L(α) + [ω]× L(ω)) I_So
    reading = [F; T] + b

with ω, α the angular velocity/acceleration of S, a the acceleration of So and g gravity, all
expressed in S and computed with Drake from (q, q̇, q̈). ``L(x)`` maps the 6 inertia entries
``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` to ``I·x``. ``mode="static"`` sets ω = α = a = 0 (gravity
only: mass, centre of mass and biases, 10 parameters), as the usual ROS gravity-compensation
tools do; ``mode="dynamic"`` (default) keeps the motion terms (16 parameters).

Identification is weighted least squares: each wrench axis is weighted by the inverse RMS of
its residual from an ordinary first pass (forces in N and torques in N·m differ by orders of
magnitude). Standard errors come from the weighted residual variance and (AᵀWA)⁻¹. The
condition number of the column-normalised regressor says whether the data excites the
parameters; a warning names the poorly determined ones.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

from ..errors import RobotModelError
from ..physics.rigid_body import sensor_kinematics
from ..physics.robot import RobotDescription, ftdrake_arm
from .base import Compensator

PARAMETER_NAMES = ["m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
                   "bFx", "bFy", "bFz", "bTx", "bTy", "bTz"]
PARAMETER_UNITS = ["kg", "kg*m", "kg*m", "kg*m"] + ["kg*m^2"] * 6 + ["N"] * 3 + ["N*m"] * 3
STATIC_PARAMETERS = [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]


class ExcitationWarning(UserWarning):
    """The data does not determine some payload parameters well."""


class PhysicsPayloadCompensator(Compensator):
    """Rigid-payload model of the internal wrench, identified from data.

    Parameters
    ----------
    features : the [q, q̇, q̈] blocks it may use; "q,qd,qdd" for ``mode="dynamic"``.
    mode : "dynamic" (10 inertial parameters + 6 biases) or "static" (mass, CoM, biases).
    robot : the robot the sensor is on (:class:`~ftdrake.physics.robot.RobotDescription`'s
        ``model``): a URDF/SDF/model-directives file or package:// URL, or model-directives
        text; None for ftdrake's simulated arm with its default models
        (:func:`~ftdrake.physics.robot.ftdrake_arm`; ``ftdrake.sim.scene.robot_description``
        describes any scenario's arm).
    sensor_frame : frame S in `robot` (``"model::frame"`` or a unique name); None with
        ``robot=None`` (the sensor weld's child frame).
    base_frame : frame of `robot` welded to the world, if the model does not weld it.
    gravity : gravity in the world (base) frame, m/s².
    package_xmls : extra package.xml files for `robot`'s package:// URLs.
    """

    def __init__(self, features="q,qd,qdd", mode="dynamic", robot=None, sensor_frame=None,
                 base_frame=None, gravity=(0.0, 0.0, -9.81), package_xmls=()):
        super().__init__(features=features)
        self.mode = mode
        self.robot = robot
        self.sensor_frame = sensor_frame
        self.base_frame = base_frame
        self.gravity = gravity
        self.package_xmls = package_xmls

    # -- the regressor ----------------------------------------------------------------------
    def regressor(self, X) -> np.ndarray:
        """The (N, 6, 16) regressor A with reading = A·[φ; b]."""
        X = np.asarray(X, dtype=float)
        n = X.shape[1] // 3
        kin = self._kinematics().evaluate(X[:, :n], X[:, n:2 * n], X[:, 2 * n:])
        if self.mode == "static":
            kin = kin.__class__(kin.R_WS, 0 * kin.w_WS_S, 0 * kin.alpha_WS_S,
                                0 * kin.a_WSo_S, kin.g_S)
        return payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S)

    def _fit(self, Z, Y):
        if self.mode not in ("dynamic", "static"):
            raise ValueError(f"mode must be 'dynamic' or 'static', got {self.mode!r}")
        if Y.shape[1] != 6:
            raise ValueError(f"the payload model predicts a wrench: 6 targets, got {Y.shape[1]}")
        if self.mode == "dynamic" and self.features != "q,qd,qdd":
            raise ValueError("mode='dynamic' needs features='q,qd,qdd' (it uses q̇ and q̈)")
        X = _full_layout(Z, self.n_joints_)
        self._check_robot_joints()
        A = self.regressor(X)
        cols = STATIC_PARAMETERS if self.mode == "static" else list(range(16))
        A = A[:, :, cols]
        theta, cov, axis_rms, cond = weighted_least_squares(A, Y)
        self.parameters_ = np.zeros(16)
        self.parameters_[cols] = theta
        self.standard_errors_ = np.full(16, np.nan)
        self.standard_errors_[cols] = np.sqrt(np.diag(cov))
        self.condition_number_ = float(cond)
        self.residual_rms_ = axis_rms
        self._warn_if_poorly_excited(cols)

    def _predict(self, Z):
        X = _full_layout(Z, self.n_joints_)
        return self.regressor(X) @ self.parameters_

    def predict_row(self, x) -> np.ndarray:
        """One full-layout row (3n,) → wrench (6,), without input validation (control loops)."""
        return self.regressor(np.asarray(x, dtype=float)[None, :])[0] @ self.parameters_

    def row_predictor(self):
        """``row → (wrench, zeros)`` through :meth:`predict_row` (the loop's path)."""
        zeros = np.zeros(6)
        return lambda row: (self.predict_row(row), zeros)

    # -- reporting --------------------------------------------------------------------------
    def identified(self) -> dict:
        """Identified parameters with standard errors and units, plus derived CoM (m)."""
        p, se = self.parameters_, self.standard_errors_
        table = {
            name: {"value": float(p[i]), "std_error": float(se[i]), "unit": PARAMETER_UNITS[i]}
            for i, name in enumerate(PARAMETER_NAMES)
            if self.mode == "dynamic" or i in STATIC_PARAMETERS
        }
        mass = p[0]
        table["com"] = {"value": (p[1:4] / mass).tolist() if mass else None, "unit": "m"}
        table["condition_number"] = self.condition_number_
        return table

    def _warn_if_poorly_excited(self, cols):
        # A standard error is compared with its parameter group's scale (mass, first moment,
        # inertia), not the value itself: a true product of inertia of 0 is no failure.
        p = np.abs(self.parameters_)
        scale = np.empty(16)
        for group in (slice(0, 1), slice(1, 4), slice(4, 10), slice(10, 16)):
            scale[group] = max(p[group].max(), 1e-9)
        rel = np.abs(self.standard_errors_[cols]) / scale[cols]
        poor = [PARAMETER_NAMES[c] for c, r in zip(cols, rel, strict=True) if r > 0.25 and c < 10]
        if self.condition_number_ > 1e4 or poor:
            warnings.warn(
                f"the data does not excite the payload parameters well (condition number "
                f"{self.condition_number_:.3g}; standard error > 25% of its group's scale: "
                f"{poor or 'none'}); "
                "use a richer trajectory (e.g. kind 'fourier' or 'z_rich')",
                ExcitationWarning, stacklevel=3,
            )

    # -- kinematics -------------------------------------------------------------------------
    def _kinematics(self):
        return _kinematics_for(self.robot_description(), tuple(self.gravity))

    def robot_description(self) -> RobotDescription:
        """The robot this model identifies its payload on."""
        if self.robot is None:
            if self.sensor_frame is not None or self.base_frame is not None:
                raise RobotModelError("sensor_frame and base_frame need a robot model (robot=...)")
            return ftdrake_arm()
        if not self.sensor_frame:
            raise RobotModelError(f"robot {self.robot!r} needs sensor_frame (the frame of the "
                                  "measured wrench)")
        return RobotDescription(str(self.robot), self.sensor_frame, self.base_frame,
                                tuple(self.package_xmls))

    def _check_robot_joints(self):
        n = self._kinematics().num_joints
        if n != self.n_joints_:
            raise ValueError(f"the data has {self.n_joints_} joints; the robot model has {n}")


def payload_regressor(w, alpha, a_minus_g) -> np.ndarray:
    """(N, 6, 16) regressor from ω, α, a − g (each N × 3, in S)."""
    N = len(w)
    A = np.zeros((N, 6, 16))
    A[:, :3, 0] = -a_minus_g
    A[:, :3, 1:4] = -(_skew(alpha) + _skew(w) @ _skew(w))
    A[:, 3:, 1:4] = _skew(a_minus_g)
    A[:, 3:, 4:10] = -(_inertia_map(alpha) + _skew(w) @ _inertia_map(w))
    A[:, :, 10:16] = np.eye(6)
    return A


def weighted_least_squares(A, Y):
    """Solves Y ≈ A θ over all samples and axes, each axis weighted by 1/residual RMS.

    Returns (θ, covariance of θ, per-axis residual RMS, condition number of the
    column-normalised weighted regressor).
    """
    p = A.shape[-1]
    theta = np.linalg.lstsq(A.reshape(-1, p), Y.reshape(-1), rcond=None)[0]
    rms = np.sqrt(np.mean((Y - A @ theta) ** 2, axis=0))
    weights = 1.0 / np.maximum(rms, 1e-9 * (1 + np.abs(Y).max()))
    Aw = (A * weights[None, :, None]).reshape(-1, p)
    yw = (Y * weights).reshape(-1)
    scale = np.linalg.norm(Aw, axis=0)
    scale[scale == 0] = 1.0
    theta_s, *_ = np.linalg.lstsq(Aw / scale, yw, rcond=None)
    theta = theta_s / scale
    residual = yw - Aw @ theta
    dof = max(1, Aw.shape[0] - p)
    sigma2 = residual @ residual / dof
    normal = (Aw / scale).T @ (Aw / scale)
    cov = sigma2 * np.linalg.pinv(normal) / np.outer(scale, scale)
    cond = np.linalg.cond(Aw / scale)
    rms = np.sqrt(np.mean((Y - A @ theta) ** 2, axis=0))
    return theta, cov, rms, cond


def _skew(v):
    v = np.asarray(v)
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _inertia_map(x):
    """L(x) with I·x = L(x)·[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]."""
    x = np.asarray(x)
    L = np.zeros((*x.shape[:-1], 3, 6))
    L[..., 0, 0], L[..., 0, 1], L[..., 0, 2] = x[..., 0], x[..., 1], x[..., 2]
    L[..., 1, 1], L[..., 1, 3], L[..., 1, 4] = x[..., 0], x[..., 1], x[..., 2]
    L[..., 2, 2], L[..., 2, 4], L[..., 2, 5] = x[..., 0], x[..., 1], x[..., 2]
    return L


def _full_layout(Z, n):
    """Pads selected features back to [q, q̇, q̈] with zeros (static models use only q)."""
    X = np.zeros((len(Z), 3 * n))
    X[:, : Z.shape[1]] = Z
    return X


# ----------------------------------------------------------------------------------------------
class _Kinematics:
    """A kinematics-only plant holding frame S; never stored on the estimator (not picklable)."""

    def __init__(self, plant, context, frame_S, instance, gravity):
        self.plant, self.context, self.frame_S, self.instance = plant, context, frame_S, instance
        self.num_joints = plant.num_positions(instance) if instance is not None else \
            plant.num_positions()
        self.gravity = np.asarray(gravity, dtype=float)

    def evaluate(self, q, v, vdot):
        kin = sensor_kinematics(self.plant, self.context, self.frame_S, q, v, vdot, self.instance)
        kin.g_S[:] = np.einsum("nji,j->ni", kin.R_WS, self.gravity)
        return kin


@functools.lru_cache(maxsize=8)
def _kinematics_for(description: RobotDescription, gravity: tuple) -> _Kinematics:
    plant, frame_S = description.build_plant()
    return _Kinematics(plant, plant.CreateDefaultContext(), frame_S, None, gravity)
