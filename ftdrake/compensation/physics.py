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
and its product with the parameters — is one fused numba kernel
(:mod:`ftdrake.compensation.compiled.payload`; :meth:`row_predictor`, with the std, about
1.5 µs of work per row on ftdrake's arm). ``L(x)`` maps the 6 inertia entries
``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` to ``I·x``. ``mode="static"`` sets ω = α = a = 0 (gravity
only: mass, centre of mass and biases, 10 parameters), as the usual ROS gravity-compensation
tools do; ``mode="dynamic"`` (default) keeps the motion terms (16 parameters).

Identification is weighted least squares (``identification="least_squares"``) or the same fit
constrained to a physically possible body with an optional prior
(``identification="consistent"``, :mod:`ftdrake.compensation.consistent`): each wrench
axis is weighted by the inverse RMS of its residual from an ordinary first pass (forces in N
and torques in N·m differ by orders of magnitude). Standard errors come from the weighted
residual variance and (AᵀWA)⁻¹. The condition number of the column-normalised regressor says
whether the data excites the parameters; a warning names the parameters the data cannot
determine (from the regressor's null directions and the standard errors).

A weight carried without inertia, optional (``weight_without_inertia=True``, 4 parameters more:
``[m_w, m_w·c_w (3)]``): a force along gravity that does not follow the tool's accelerations,

    F_w = m_w·g,    T_w = (m_w·c_w) × g,

the part of a cable or hose hanging from the tool whose weight the tool carries while its
other end, held elsewhere, does not accelerate with it. A rigid model takes such a weight for
tool mass and multiplies it by the tool's accelerations (measured on the default scene: the
cable's 1.2 N identified as 0.13 kg of payload). Only motion separates the two: in static poses
the columns are those of m and m·c (refused with ``mode="static"``).

Two more effects of a real sensor, optional: the rotation of the frame the sensor measures in
(``identify_mounting``) and a linear zero drift with the sensor's temperature (a temperature
column in X).
"""

from __future__ import annotations

import copy
import functools
import warnings
import weakref

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..conventions import GRAVITY_W
from ..errors import ConfigError, RobotModelError
from ..physics.chain import SerialChain
from ..physics.rigid_body import inertia_map, skew
from ..physics.robot import RobotDescription, ftdrake_arm
from .base import Compensator
from .compiled.payload import pack_payload_row, payload_mean_std, payload_predict
from .consistent import (
    DEFAULT_PRIOR_WEIGHT,
    PayloadPrior,
    identify_consistent,
    identify_least_squares,
    is_physically_consistent,
)
from .consistent import PARAMETER_NAMES as CONSISTENT_NAMES
from .consistent import STATIC_PARAMETERS as CONSISTENT_STATIC

PARAMETER_NAMES = list(CONSISTENT_NAMES)
PARAMETER_UNITS = (["kg", "kg*m", "kg*m", "kg*m"] + ["kg*m^2"] * 6 + ["N"] * 3 + ["N*m"] * 3
                   + ["kg", "kg*m", "kg*m", "kg*m"])
STATIC_PARAMETERS = list(CONSISTENT_STATIC)
#: The weight carried without inertia (``weight_without_inertia``): θ[16:20].
WEIGHT_PARAMETERS = [16, 17, 18, 19]
#: The columns that are a wrench in S (rotated into Sm by a mounting); the biases are in Sm.
BIASES = slice(10, 16)
#: How the parameters are identified: plain weighted least squares, or constrained to a
#: physically possible body (pseudo-inertia ⪰ 0, m > 0; :mod:`.consistent`) with a prior.
IDENTIFICATIONS = ("least_squares", "consistent")


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
        (:func:`~ftdrake.physics.robot.ftdrake_arm`;
        :func:`~ftdrake.physics.scenario_robot.robot_description` describes any scenario's arm).
    sensor_frame : frame S in `robot` (``"model::frame"`` or a unique name); None with
        ``robot=None`` (the sensor weld's child frame).
    base_frame : frame of `robot` welded to the world, if the model does not weld it.
    gravity : gravity in the world (base) frame, m/s².
    package_xmls : extra package.xml files for `robot`'s package:// URLs.
    identification : "least_squares" (weighted least squares, any 10 numbers) or "consistent"
        (the same fit constrained to a physically possible body — m > 0, pseudo-inertia ⪰ 0 —
        solved as a small SDP, :func:`~.consistent.identify_consistent`; the unconstrained
        estimate is kept in ``identified()["least_squares"]``).
    prior : a :class:`~.consistent.PayloadPrior` (mass, CoM, inertia about the CoM, in S;
        e.g. CAD values) or a mapping of its fields, for ``identification="consistent"``: it
        decides the directions the data do not excite; ``identified()`` says by how much.
    prior_weight : the prior's precision (default 100: it counts as ±10 %, 1σ).
    weight_without_inertia : also identify a weight the tool carries without its inertia
        (``m_w``, ``m_w·c_w``: a hanging cable; see the module docstring). Needs motion data
        (``mode="dynamic"``); θ then has 20 entries.
    identify_mounting : also identify the rotation R_SSm of the frame Sm the sensor really
        measures in (a mounting error; the biases are then in Sm): nonlinear least squares
        (``scipy.optimize.least_squares``, soft-L1 robust loss) over the rotation, payload and
        biases, then the linear (or consistent) fit with that rotation fixed.

    The sensor temperature (°C), given as X's last column (``[q, q̇, q̈, T]``), adds a linear
    zero drift per axis, ``k·(T − T_ref)`` (``temperature_coefficients_``, N/K and N·m/K in
    Sm; ``temperature_reference_`` the training mean, at which the biases hold).

    Fitted attributes: ``parameters_`` (16, or 20 with ``weight_without_inertia``),
    ``standard_errors_`` (same; ∞ where nothing determines a parameter), ``covariance_``,
    ``condition_number_``,
    ``residual_rms_`` (6), ``physically_consistent_``, ``identification_`` (the full
    :class:`~.consistent.ConsistentIdentification`). An :class:`ExcitationWarning` names the
    parameters the data cannot determine.

    Predictive standard deviation (``predict_std``, the loop's ``wrench_std``): the std of a
    new reading around the prediction, per axis,

        std_i² = ‖B_i(x) F‖² + σ_i² + (s_k,i · (T − T_ref))²

    with ``B(x)`` the 6 × 16 map from ``θ = [φ; b]`` to the reading (the regressor row, rotated
    into Sm), ``F Fᵀ = covariance_`` (a square-root factor precomputed once: eigenvectors
    scaled by the square roots of the non-negative eigenvalues, so a singular covariance is
    fine), ``σ_i`` the per-axis residual RMS of the fit (sensor noise plus what the rigid
    model misses: cable, cross-talk, drift) and ``s_k`` the temperature coefficients' standard
    errors. The first term is the parameter uncertainty: small where the data excite the
    parameters, growing with accelerations and poses the data did not cover. It treats the
    estimate as unconstrained (the linearised covariance; an active constraint of the
    consistent fit is ignored) and adds nothing for directions neither the data nor a prior
    determine (their covariance is the pseudo-inverse's 0). The loop computes it in the same
    compiled kernel as the mean (one 6 × 16 by 16 × r product more: ~0.5 µs per row).
    """

    #: The std of a new reading (noise included), not just of the prediction.
    provides_std = True
    std_includes_noise = True
    #: Models saved before the option existed have no such attribute.
    weight_without_inertia = False

    def __init__(self, features="q,qd,qdd", mode="dynamic", robot=None, sensor_frame=None,
                 base_frame=None, gravity=GRAVITY_W, package_xmls=(),
                 identification="least_squares", prior=None,
                 prior_weight=DEFAULT_PRIOR_WEIGHT, identify_mounting=False,
                 weight_without_inertia=False):
        super().__init__(features=features)
        self.mode = mode
        self.robot = robot
        self.sensor_frame = sensor_frame
        self.base_frame = base_frame
        self.gravity = gravity
        self.package_xmls = package_xmls
        self.identification = identification
        self.prior = prior
        self.prior_weight = prior_weight
        self.identify_mounting = identify_mounting
        self.weight_without_inertia = weight_without_inertia

    @property
    def n_parameters(self) -> int:
        """16 (payload and biases), or 20 with the weight carried without inertia."""
        return 20 if self.weight_without_inertia else 16

    # -- the regressor ----------------------------------------------------------------------
    def regressor(self, X) -> np.ndarray:
        """The (N, 6, 16) regressor A with reading = A·[φ; b] (N, 6, 20 and θ = [φ; b; w] with
        ``weight_without_inertia``)."""
        X = np.asarray(X, dtype=float)
        n = X.shape[1] // 3
        kin = self._kinematics().evaluate(X[:, :n], X[:, n:2 * n], X[:, 2 * n:])
        if self.mode == "static":
            kin = kin.__class__(kin.R_WS, 0 * kin.w_WS_S, 0 * kin.alpha_WS_S,
                                0 * kin.a_WSo_S, kin.g_S)
        return payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S,
                                 kin.g_S if self.weight_without_inertia else None)

    def _fit(self, Z, Y):
        if self.mode not in ("dynamic", "static"):
            raise ValueError(f"mode must be 'dynamic' or 'static', got {self.mode!r}")
        if self.identification not in IDENTIFICATIONS:
            raise ConfigError(f"identification must be one of {list(IDENTIFICATIONS)}, got "
                              f"{self.identification!r}")
        prior = PayloadPrior.coerce(self.prior)
        if prior is not None and self.identification != "consistent":
            raise ConfigError("prior needs identification='consistent' (least squares has no "
                              "prior)")
        if Y.shape[1] != 6:
            raise ValueError(f"the payload model predicts a wrench: 6 targets, got {Y.shape[1]}")
        if self.weight_without_inertia and self.mode != "dynamic":
            raise ConfigError("weight_without_inertia needs mode='dynamic': in static poses a "
                              "weight without inertia and the payload's mass are the same "
                              "columns (only accelerations separate them)")
        if self.mode == "dynamic" and self.features != "q,qd,qdd":
            raise ValueError("mode='dynamic' needs features='q,qd,qdd' (it uses q̇ and q̈)")
        Z, temperature = self._split_temperature(Z)
        X = _full_layout(Z, self.n_joints_)
        self._check_robot_joints()
        A = self.regressor(X)
        self._identify(A, Y, prior, temperature)

    def _split_temperature(self, Z):
        if getattr(self, "temperature_in_", False):
            return Z[:, :-1], Z[:, -1]
        return Z, None

    def _identify(self, A, Y, prior, temperature=None):
        """Sets the fitted attributes from the (N, 6, 16) regressor and the readings.

        With a temperature, its per-axis coefficient is eliminated first (Frisch–Waugh–Lovell:
        each axis's data projected orthogonal to T − T_ref), so that the linear and the
        consistent fit see the payload and biases only; the coefficients follow from the
        residual. With ``identify_mounting`` the rotation comes first (nonlinear), the
        readings are rotated back into S, and the linear fit runs there.
        """
        static = self.mode == "static"
        p = 16 if static else A.shape[-1]
        cols = STATIC_PARAMETERS if static else list(range(p))
        d = None
        self.temperature_reference_ = None
        if temperature is not None:
            self.temperature_reference_ = float(np.mean(temperature))
            d = np.asarray(temperature, float) - self.temperature_reference_
            if not np.any(np.abs(d) > 1e-9):
                d = None  # a constant temperature: its coefficients are not observable
        self.mounting_rotation_ = np.eye(3)
        self.mounting_std_deg_ = np.zeros(3)
        if self.identify_mounting:
            self.mounting_rotation_, self.mounting_std_deg_ = _fit_mounting(
                A, Y, d, cols)
        block = np.kron(np.eye(2), self.mounting_rotation_)  # y_S = block · y_Sm
        Y_S = Y @ block.T
        A_fit, Y_fit = (A, Y_S) if d is None else (_project_out(A, d), _project_out(Y_S, d))
        if self.identification == "consistent":
            result = identify_consistent(
                A_fit[:, :, cols], Y_fit, static=static,
                prior=None if prior is None else prior.phi(), prior_weight=self.prior_weight)
        else:
            result = identify_least_squares(A_fit[:, :, cols], Y_fit, static=static)
        self.identification_ = result
        theta = result.theta.copy()
        cov = result.covariance.copy()
        # Biases were identified in S; the sensor adds them in Sm.
        theta[BIASES] = block.T @ theta[BIASES]
        to_Sm = np.eye(p)
        to_Sm[BIASES, BIASES] = block.T  # θ with the biases in Sm = to_Sm · θ in S
        finite = np.isfinite(cov)
        cov = to_Sm @ np.where(finite, cov, 0.0) @ to_Sm.T
        cov[~finite] = np.nan  # parameters not identified (a static fit's inertia) stay NaN
        self.parameters_ = theta
        self.covariance_ = cov
        self.standard_errors_ = result.standard_errors.copy()
        self.standard_errors_[BIASES] = np.sqrt(np.maximum(np.diag(cov[BIASES, BIASES]), 0.0))
        self.temperature_coefficients_ = np.zeros(6)
        self.temperature_std_errors_ = np.full(6, np.nan)
        if d is not None:
            residual_S = Y_S - A @ result.theta
            k_S = residual_S.T @ d / (d @ d)
            self.temperature_coefficients_ = block.T @ k_S
            rms = np.sqrt(np.mean((residual_S - np.outer(d, k_S)) ** 2, axis=0))
            self.temperature_std_errors_ = block.T @ (rms / np.sqrt(d @ d))
            self.temperature_std_errors_ = np.abs(self.temperature_std_errors_)
        self.condition_number_ = float(result.condition_number)
        self.residual_rms_ = np.sqrt(np.mean((Y - self._predict_from(A, temperature)) ** 2,
                                             axis=0))
        self.physically_consistent_ = (is_physically_consistent(self.parameters_[:10])
                                       if not static else bool(self.parameters_[0] > 0))
        self._warn_if_poorly_excited()

    def _predict_from(self, A, temperature=None):
        """Readings in Sm: ``R_SmS ⊗ (A_φ φ [+ A_w w]) + b + k·(T − T_ref)``."""
        wrench_S = A[:, :, :10] @ self.parameters_[:10]
        if A.shape[-1] == 20:
            wrench_S = wrench_S + A[:, :, 16:] @ self.parameters_[16:]
        out = wrench_S @ self.reading_matrix().T
        out = out + self.parameters_[BIASES]
        reference = getattr(self, "temperature_reference_", None)
        if temperature is not None and reference is not None:
            out = out + np.outer(temperature - reference, self.temperature_coefficients_)
        return out

    def _predict(self, Z):
        Z, temperature = self._split_temperature(Z)
        X = _full_layout(Z, self.n_joints_)
        return self._predict_from(self.regressor(X), temperature)

    def _predict_std(self, Z):
        return np.sqrt(self._variance(Z, include_noise=True))

    def parameter_std(self, X) -> np.ndarray:
        """(N, 6) std of the predicted reading from the parameters' uncertainty alone (no
        noise term): what :class:`~.hybrid.HybridCompensator` adds to its residual's."""
        return np.sqrt(self._variance(self._validated_features(X), include_noise=False))

    def _variance(self, Z, include_noise):
        Z, temperature = self._split_temperature(Z)
        X = _full_layout(Z, self.n_joints_)
        factor, noise_var, block_T = self._std_terms()
        A = self.regressor(X)
        B = A.copy()
        B[:, :, :10] = np.einsum("ij,njk->nik", block_T, A[:, :, :10])
        B[:, :, 16:] = np.einsum("ij,njk->nik", block_T, A[:, :, 16:])
        var = np.einsum("nij,jr->nir", B, factor)
        var = np.einsum("nir,nir->ni", var, var)
        if include_noise:
            var = var + noise_var
        reference = getattr(self, "temperature_reference_", None)
        if temperature is not None and reference is not None:
            se = np.nan_to_num(self.temperature_std_errors_)
            var = var + np.outer(temperature - reference, se) ** 2
        return var

    def _std_terms(self):
        """(F (p × p) with F Fᵀ = covariance_ (NaN entries: 0), σ² per axis (6,),
        block_T (6 × 6) rotating a wrench from S into Sm)."""
        # A model whose parameters were set by hand (no fit) has no uncertainty: std 0.
        p = len(self.parameters_)
        cov = np.asarray(getattr(self, "covariance_", np.zeros((p, p))), dtype=float)
        cov = np.where(np.isfinite(cov), cov, 0.0)
        lam, V = np.linalg.eigh(0.5 * (cov + cov.T))
        factor = np.ascontiguousarray(V * np.sqrt(np.maximum(lam, 0.0)))
        noise_var = np.asarray(getattr(self, "residual_rms_", np.zeros(6)), dtype=float) ** 2
        return factor, noise_var, np.ascontiguousarray(self.reading_matrix())

    def reading_matrix(self) -> np.ndarray:
        """(6, 6) M with reading = M·W_S + b (+ k·ΔT): the sensor's gain/cross-talk matrix
        when one was set (``reading_matrix_``, from ``calibrate --correction``), else the
        mounting rotation ``R_SmS`` on forces and torques (identity without one)."""
        matrix = getattr(self, "reading_matrix_", None)
        if matrix is not None:
            return np.asarray(matrix, dtype=float)
        return np.kron(np.eye(2), getattr(self, "mounting_rotation_", np.eye(3))).T

    def reading_to_model_frame(self):
        """T = M⁻¹ (M: :meth:`reading_matrix`), so that ``T·(measured − predicted)`` is the
        external wrench in S; None when M is the identity (no mounting rotation and no
        correction identified). The predicted reading is ``M·W_S + b``, so the difference
        is ``M·W_ext,S`` (plus noise)."""
        matrix = self.reading_matrix()
        if np.array_equal(matrix, np.eye(6)):
            return None
        return np.linalg.inv(matrix)

    def with_correction(self, correction) -> PhysicsPayloadCompensator:
        """A copy that predicts readings through a gain/cross-talk correction identified on
        static poses (:class:`~ftdrake.compensation.calibration.CalibrationCorrection`):
        ``M·W_S(payload) + b + k·ΔT`` with the correction's M, bias, temperature coefficients
        and payload (it must have one payload for every row). The parameters' covariance stays
        the rigid fit's (an approximation: M's own uncertainty is not propagated). A weight
        carried without inertia is set to zero: the static poses' payload holds all the weight
        there is."""
        if correction.payload is None:
            raise ConfigError("the correction was fitted with a known payload per row: no "
                              "single payload to predict with")
        model = copy.deepcopy(self)
        model.parameters_ = self.parameters_.copy()
        model.parameters_[:4] = correction.payload
        model.parameters_[BIASES] = correction.bias
        model.parameters_[16:] = 0.0
        model.mounting_rotation_ = np.eye(3)  # M holds the mounting too
        model.reading_matrix_ = np.asarray(correction.sensor_matrix, dtype=float).copy()
        if correction.temperature_coefficients is not None:
            model.temperature_coefficients_ = np.asarray(correction.temperature_coefficients)
            model.temperature_std_errors_ = np.asarray(correction.temperature_std_errors)
            model.temperature_reference_ = correction.temperature_reference
        model.residual_rms_ = np.asarray(correction.residual_rms, dtype=float).copy()
        return model

    def predict_row(self, x) -> np.ndarray:
        """One full-layout row (3n,) → wrench (6,), without input validation (control loops):
        one compiled kernel (kinematics, regressor row, product with the parameters)."""
        x = np.asarray(x, dtype=float)
        if getattr(self, "temperature_in_", False) or not np.array_equal(
                self.reading_matrix(), np.eye(6)):
            return self.row_predictor()(x)[0]
        out = np.empty(6)
        payload_predict(x, *self._row_kernel_args(), self.parameters_, out)
        return out

    def row_predictor(self, include_noise: bool = True):
        """``row → (wrench, std)``: one compiled kernel with this model's chain, current
        parameters and covariance factor bound (refitting the model afterwards does not
        change it): kinematics, regressor row, mean ``B·θ`` and std (see the class
        docstring), mounting rotation included; the temperature term (row's last entry) is
        added after it. ``include_noise=False``: the parameters' uncertainty only."""
        reals, ints = self.packed_row(None if include_noise else np.zeros(6))
        reference = getattr(self, "temperature_reference_", None)
        if not (getattr(self, "temperature_in_", False) and reference is not None):
            def predict(row):
                mean, std = np.empty(6), np.empty(6)
                payload_mean_std(row, reals, ints, mean, std)
                return mean, std

            return predict
        k = np.asarray(getattr(self, "temperature_coefficients_", np.zeros(6)), dtype=float)
        k_se = np.nan_to_num(np.asarray(getattr(self, "temperature_std_errors_", np.zeros(6)),
                                        dtype=float))

        def predict_with_temperature(row):
            mean, std = np.empty(6), np.empty(6)
            payload_mean_std(row, reals, ints, mean, std)
            dt = row[-1] - reference
            mean += k * dt
            std[:] = np.sqrt(std * std + (k_se * dt) ** 2)
            return mean, std

        return predict_with_temperature

    def packed_row(self, noise_var=None) -> tuple[np.ndarray, np.ndarray]:
        """This model's row kernel data, packed for
        :func:`~ftdrake.compensation.compiled.payload.payload_mean_var` (a copy: refitting
        the model afterwards does not change it): the chain, gravity, the mounting rotation,
        the current parameters, the covariance factor and the variance σ² added per axis
        (default: the residual RMS², the model's own noise term). No temperature term."""
        n, gravity, X_pre, kinds, axes, q_index, v_index, static = self._row_kernel_args()
        factor, own_noise_var, block_T = self._std_terms()
        return pack_payload_row((X_pre, kinds, axes, q_index, v_index), n, gravity, static,
                                block_T, self.parameters_, factor,
                                own_noise_var if noise_var is None else noise_var)

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
        """Identified parameters with standard errors and units, plus derived CoM (m).

        Each parameter: ``value``, ``std_error`` (∞ where the data leave it free and no prior
        decides it), ``unit`` and ``prior_share`` (how much the prior decided it, 0–1; 0
        without a prior). Also ``com`` (``p_SoScm_S``, m, with standard errors by the delta
        method), ``condition_number``, ``identification``, ``physically_consistent``,
        ``not_determined`` (parameters the data cannot determine) and, for the consistent
        fit, ``least_squares`` (the unconstrained estimate and whether it is a body).
        """
        p, se = self.parameters_, self.standard_errors_
        result = getattr(self, "identification_", None)
        share = result.prior_share if result is not None else np.zeros(len(p))
        table = {
            name: {"value": float(p[i]), "std_error": float(se[i]), "unit": PARAMETER_UNITS[i],
                   "prior_share": float(np.nan_to_num(share[i]))}
            for i, name in enumerate(PARAMETER_NAMES[:len(p)])
            if self.mode == "dynamic" or i in STATIC_PARAMETERS
        }
        mass = p[0]
        com_se = None
        cov = getattr(self, "covariance_", None)
        if mass and cov is not None and np.all(np.isfinite(cov[:4, :4])):
            # c = h / m: Jacobian [−h/m², I/m] on (m, h).
            J = np.hstack([-p[1:4, None] / mass ** 2, np.eye(3) / mass])
            com_se = np.sqrt(np.maximum(np.diag(J @ cov[:4, :4] @ J.T), 0.0)).tolist()
        table["com"] = {"value": (p[1:4] / mass).tolist() if mass else None,
                        "std_error": com_se, "unit": "m"}
        rotation = getattr(self, "mounting_rotation_", None)
        if rotation is not None and self.identify_mounting:
            table["mounting_rpy_deg"] = {
                "value": np.degrees(RollPitchYaw(RotationMatrix(rotation)).vector()).tolist(),
                "std_error": self.mounting_std_deg_.tolist(), "unit": "deg",
                "frame": "R_SSm: the frame the sensor measures in, in S (roll, pitch, yaw)"}
        if getattr(self, "temperature_reference_", None) is not None:
            table["temperature"] = {
                "coefficients": self.temperature_coefficients_.tolist(),
                "std_error": self.temperature_std_errors_.tolist(),
                "unit": "N/K (forces), N*m/K (torques)",
                "reference_c": self.temperature_reference_}
        table["condition_number"] = self.condition_number_
        table["identification"] = getattr(self, "identification", "least_squares")
        table["physically_consistent"] = bool(getattr(self, "physically_consistent_", True))
        table["not_determined"] = list(result.poorly_determined) if result is not None else []
        if result is not None and self.identification == "consistent":
            cols = STATIC_PARAMETERS if self.mode == "static" else list(range(len(p)))
            table["least_squares"] = {
                "values": {PARAMETER_NAMES[i]: float(result.theta_least_squares[i])
                           for i in cols},
                "physically_consistent": bool(result.least_squares_consistent)}
            table["active_constraints"] = list(result.active_constraints)
        return table

    def summary(self) -> str:
        """The identified parameters with standard errors, as lines a user reads."""
        t = self.identified()
        how = {"least_squares": "weighted least squares",
               "consistent": "least squares over physically possible bodies (SDP)"}
        lines = [(f"payload identified by {how.get(t['identification'], t['identification'])} "
                  f"({self.mode} model; condition number {t['condition_number']:.3g})"),
                 f"  {'':5s} {'value':>12s} {'std error':>10s} {'unit':<7s} prior share"]
        for name in PARAMETER_NAMES:
            if name in t and isinstance(t[name], dict) and "prior_share" in t[name]:
                row = t[name]
                lines.append(f"  {name:5s} {row['value']:12.5g} {row['std_error']:10.3g} "
                             f"{row['unit']:<7s} {row['prior_share']:.2f}")
        com = t["com"]
        if com["value"] is not None:
            se = com["std_error"] or [np.nan] * 3
            lines.append("  centre of mass p_SoScm_S: "
                         + ", ".join(f"{1e3 * v:.2f} ± {1e3 * e:.2f}"
                                     for v, e in zip(com["value"], se, strict=True)) + " mm")
        if "mounting_rpy_deg" in t:
            m = t["mounting_rpy_deg"]
            lines.append("  sensor mounting R_SSm roll, pitch, yaw: " + ", ".join(
                f"{v:.3f} ± {e:.3f}" for v, e in zip(m["value"], m["std_error"], strict=True))
                + " deg")
        if "temperature" in t:
            k = t["temperature"]
            lines.append(f"  zero drift per K (Fx..Tz, about {k['reference_c']:.2f} °C): "
                         + ", ".join(
                f"{v:.4g} ± {e:.2g}" for v, e in zip(k["coefficients"], k["std_error"],
                                                      strict=True)))
        lines.append(f"  physically possible body: {'yes' if t['physically_consistent'] else 'NO'}"
                     + ("" if "least_squares" not in t else
                        f" (plain least squares: "
                        f"{'yes' if t['least_squares']['physically_consistent'] else 'no'})"))
        lines.append(f"  not determined by the data: {', '.join(t['not_determined']) or 'none'}")
        return "\n".join(lines)

    def _warn_if_poorly_excited(self):
        result = self.identification_
        # Only the inertial parameters can be "poorly excited"; a bias named here is one the
        # data determine only in a combination with the mass (a constant gravity direction).
        poor = list(result.poorly_determined)
        if self.condition_number_ <= 1e4 and not poor:
            return
        share = result.prior_share
        if self.prior is not None and self.identification == "consistent":
            decided = ", ".join(f"{n} {share[PARAMETER_NAMES.index(n)]:.0%}" for n in poor
                                if n in PARAMETER_NAMES[:10])
            how = f"the prior decided (share of each estimate): {decided or 'none'}"
        else:
            how = ("give a prior (identification='consistent', prior=PayloadPrior(...)) or "
                   "use a richer trajectory (e.g. kind 'fourier' or 'z_rich')")
        warnings.warn(
            f"the data does not excite the payload parameters well (condition number "
            f"{self.condition_number_:.3g}); not determined by the data (a null direction of "
            f"the regressor, or standard error > 25% of its group's scale): "
            f"{', '.join(poor) or 'none'}; {how}",
            ExcitationWarning, stacklevel=4,
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


def _project_out(M, d):
    """Each axis's data orthogonal to the temperature deviation d (N,): M (N, 6[, p])."""
    coef = np.tensordot(d, M, axes=(0, 0)) / (d @ d)
    return M - np.multiply.outer(d, coef)


def _fit_mounting(A, Y, d, cols):
    """(R_SSm, its 1σ angles about S's axes in degrees) by robust nonlinear least squares.

    Unknowns: the rotation vector of R_SSm, the inertial parameters in `cols` (all 10, or
    mass and first moment), the biases in Sm and, with a temperature deviation `d`, its
    coefficients. Residuals are weighted per axis by 1 / RMS of a linear first fit; the loss
    is soft-L1 with a 3σ knee, so a few outliers (a bump, a glitch) do not rotate the frame.
    """
    phys = [c for c in cols if not 10 <= c < 16]  # a wrench in S: rotated
    A_phys = A[:, :, phys]
    first = np.linalg.lstsq(A[:, :, cols].reshape(-1, len(cols)), Y.reshape(-1), rcond=None)[0]
    theta0 = np.zeros(A.shape[-1])
    theta0[cols] = first
    weights = 1.0 / np.maximum(np.sqrt(np.mean((Y - A @ theta0) ** 2, axis=0)),
                               1e-9 * (1 + np.abs(Y).max()))
    n_phys = len(phys)
    x0 = np.concatenate([np.zeros(3), theta0[phys], theta0[BIASES],
                         np.zeros(6) if d is not None else []])

    def residuals(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix()
        wrench = A_phys @ x[3:3 + n_phys]
        pred = wrench @ np.kron(np.eye(2), R) + x[3 + n_phys:9 + n_phys]
        if d is not None:
            pred = pred + np.outer(d, x[9 + n_phys:])
        return ((Y - pred) * weights).ravel()

    fit = least_squares(residuals, x0, loss="soft_l1", f_scale=3.0, x_scale="jac")
    dof = max(1, fit.fun.size - fit.x.size)
    sigma2 = float(fit.fun @ fit.fun / dof)
    cov = sigma2 * np.linalg.pinv(fit.jac.T @ fit.jac)
    return (Rotation.from_rotvec(fit.x[:3]).as_matrix(),
            np.degrees(np.sqrt(np.maximum(np.diag(cov)[:3], 0.0))))


def payload_regressor(w, alpha, a_minus_g, gravity_S=None) -> np.ndarray:
    """(N, 6, 16) regressor from ω, α, a − g (each N × 3, in S); (N, 6, 20) with `gravity_S`
    (N × 3, g in S): the columns of a weight carried without inertia, [m_w·g; (m_w·c_w) × g]."""
    N = len(w)
    A = np.zeros((N, 6, 16 if gravity_S is None else 20))
    if gravity_S is not None:
        A[:, :3, 16] = gravity_S
        A[:, 3:, 17:20] = -skew(gravity_S)
    A[:, :3, 0] = -a_minus_g
    A[:, :3, 1:4] = -(skew(alpha) + skew(w) @ skew(w))
    A[:, 3:, 1:4] = skew(a_minus_g)
    A[:, 3:, 4:10] = -(inertia_map(alpha) + skew(w) @ inertia_map(w))
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
