"""Physics payload compensator: the tool's inertial parameters and the sensor's biases,
identified by least squares from the Newton–Euler wrench regressor.

The reading of a sensor carrying a rigid tool is linear in the tool's 10 inertial parameters
``φ = [m, m·c (3), I_So (6)]`` (mass, first moment, inertia about So; all in S) plus 6 biases:

    F = −m (a − g) − ([α]× + [ω]×[ω]×) m·c
    T = [a − g]× m·c − (L(α) + [ω]× L(ω)) I_So
    reading = [F; T] + b

with ω, α the angular velocity/acceleration of S, a the acceleration of So and g gravity, all
expressed in S and computed from (q, q̇, q̈) by the compiled serial chain
(:class:`~ftdrake.physics.chain.SerialChain`, extracted once from the robot's Drake plant and
equal to Drake's own kinematics to round-off). One row — kinematics, the 6 × 16 regressor row
and its product with the parameters — is one fused numba kernel (:meth:`predict_row`, about a
microsecond). ``L(x)`` maps the 6 inertia entries
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
import weakref

import numba
import numpy as np

from ..errors import RobotModelError
from ..physics.chain import SerialChain, sensor_kinematics_row
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
        """One full-layout row (3n,) → wrench (6,), without input validation (control loops):
        one compiled kernel (kinematics, regressor row, product with the parameters)."""
        args = self._row_kernel_args()
        out = np.empty(6)
        _predict_row(np.asarray(x, dtype=float), *args, self.parameters_, out)
        return out

    def row_predictor(self):
        """``row → (wrench, zeros)``: the compiled row kernel with this model's chain and
        current parameters bound (refitting the model afterwards does not change it)."""
        args = (*self._row_kernel_args(), self.parameters_.copy())
        zeros = np.zeros(6)

        def predict(row):
            out = np.empty(6)
            _predict_row(row, *args, out)
            return out, zeros

        return predict

    def _row_kernel_args(self) -> tuple:
        # Looking the chain up through the robot description costs microseconds (building and
        # hashing the description); the row path remembers it per model and per parameters.
        key = (self.robot, self.sensor_frame, self.base_frame, tuple(self.gravity),
               tuple(self.package_xmls), self.mode)
        cached = _ROW_ARGS.get(self)
        if cached is None or cached[0] != key:
            kin = self._kinematics()
            cached = (key, (kin.n_joints, kin.gravity, *kin.chain.kernel_args(),
                            self.mode == "static"))
            _ROW_ARGS[self] = cached
        return cached[1]

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
    """The robot's serial chain to S and gravity; never stored on the estimator (the model
    file holds only the description)."""

    def __init__(self, chain: SerialChain, gravity):
        self.chain = chain
        self.num_joints = self.n_joints = chain.num_positions
        self.gravity = np.asarray(gravity, dtype=float)

    def evaluate(self, q, v, vdot):
        return self.chain.evaluate(q, v, vdot, self.gravity)


@functools.lru_cache(maxsize=8)
def _kinematics_for(description: RobotDescription, gravity: tuple) -> _Kinematics:
    plant, frame_S = description.build_plant()
    if plant.num_positions() != plant.num_velocities():
        raise RobotModelError(
            f"robot model {description.label} has {plant.num_positions()} positions but "
            f"{plant.num_velocities()} velocities (a floating body?): the [q, q̇, q̈] rows "
            "need one coordinate per joint")
    return _Kinematics(SerialChain.from_plant(plant, frame_S), gravity)


#: Row-kernel arguments per model (weak: a model's cache goes with it, never into its file).
_ROW_ARGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@numba.njit(cache=True)
def _predict_row(x, n, gravity_W, X_pre, kinds, axes, q_index, v_index, static, parameters,
                 out):
    """One full-layout row [q, q̇, q̈] (3n) → wrench (6) = A(row) · parameters."""
    R = np.empty((3, 3))
    kin = np.empty((4, 3))  # ω, α, a of S and g, in S
    sensor_kinematics_row(x[:n], x[n:2 * n], x[2 * n:3 * n], gravity_W, X_pre, kinds, axes,
                          q_index, v_index, R, kin)
    if static:
        kin[:3, :] = 0.0
    A = np.zeros((6, 16))
    _regressor_row(kin[0], kin[1], kin[2] - kin[3], A)
    for i in range(6):
        s = 0.0
        for j in range(16):
            s += A[i, j] * parameters[j]
        out[i] = s


@numba.njit(cache=True)
def _regressor_row(w, al, d, A):
    """The 6 × 16 regressor row of :func:`payload_regressor` (A zeroed on entry); d = a − g."""
    wx, wy, wz = w[0], w[1], w[2]
    ax, ay, az = al[0], al[1], al[2]
    # [ω]×[ω]× = ω ωᵀ − |ω|² I
    ww = wx * wx + wy * wy + wz * wz
    W2 = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            W2[i, j] = w[i] * w[j]
        W2[i, i] -= ww
    Sa = np.array([[0.0, -az, ay], [az, 0.0, -ax], [-ay, ax, 0.0]])
    Sd = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
    for i in range(3):
        A[i, 0] = -d[i]
        for j in range(3):
            A[i, 1 + j] = -(Sa[i, j] + W2[i, j])
            A[3 + i, 1 + j] = Sd[i, j]
    # −(L(α) + [ω]× L(ω)) over [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
    La = np.array([[ax, ay, az, 0.0, 0.0, 0.0], [0.0, ax, 0.0, ay, az, 0.0],
                   [0.0, 0.0, ax, 0.0, ay, az]])
    Lw = np.array([[wx, wy, wz, 0.0, 0.0, 0.0], [0.0, wx, 0.0, wy, wz, 0.0],
                   [0.0, 0.0, wx, 0.0, wy, wz]])
    Sw = np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])
    for i in range(3):
        for j in range(6):
            A[3 + i, 4 + j] = -(La[i, j] + Sw[i, 0] * Lw[0, j] + Sw[i, 1] * Lw[1, j]
                                + Sw[i, 2] * Lw[2, j])
    for i in range(6):
        A[i, 10 + i] = 1.0
