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
(:mod:`ftdrake.compensation.compiled.payload`; :meth:`row_predictor`, with the std).
``L(x)`` maps the 6 inertia entries ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` to ``I·x``.
``mode="static"`` sets ω = α = a = 0 (gravity only: mass, centre of mass and biases, 10
parameters), as the usual ROS gravity-compensation tools do; ``mode="dynamic"`` (default)
keeps the motion terms (16 parameters).

Identification is weighted least squares (``identification="least_squares"``) or the same fit
constrained to a physically possible body with an optional prior
(``identification="consistent"``, :mod:`ftdrake.compensation.identification.consistent`): each
wrench axis is weighted by the inverse RMS of its residual from an ordinary first pass (forces in N
and torques in N·m differ by orders of magnitude). Standard errors come from the weighted
residual variance and (AᵀWA)⁻¹. The condition number of the column-normalised regressor says
whether the data excites the parameters; a warning names the parameters the data cannot
determine (from the regressor's null directions and the standard errors).

A weight carried without inertia, optional (``weight_without_inertia=True``, 4 parameters more:
``[m_w, m_w·c_w (3)]``): a force along gravity that does not follow the tool's accelerations,

    F_w = m_w·g,    T_w = (m_w·c_w) × g,

the part of a cable or hose hanging from the tool whose weight the tool carries while its
other end, held elsewhere, does not accelerate with it. A rigid model takes such a weight for
tool mass and multiplies it by the tool's accelerations. Only motion separates the two: in
static poses the columns are those of m and m·c (refused with ``mode="static"``).

A cable tethered to the tool, optional (``tether``, 2 parameters more after the weight's,
which it needs: ``[k, k·ℓ0]``): the configuration-dependent pull of an elastic tether from a
point on the tool to a point on a link or the world, whose geometry is identified first
(nonlinear, :mod:`ftdrake.compensation.identification.tether`) and then held fixed.

Two more effects of a real sensor, optional: the rotation of the frame the sensor measures in
(``identify_mounting``) and a linear zero drift with the sensor's temperature (a temperature
column in X).
"""

from __future__ import annotations

import copy
import os
import warnings
from collections.abc import Mapping
from numbers import Real
from pathlib import Path
from typing import ClassVar

import numpy as np
from sklearn.utils._param_validation import Interval, StrOptions

from ...conventions import GRAVITY_W
from ...errors import ConfigError, RobotModelError, option_name
from ...physics.robot import RobotDescription, fixed_joint_values, ftdrake_arm, joint_names
from ..identification.consistent import DEFAULT_PRIOR_WEIGHT, PayloadPrior, is_possible
from ..identification.consistent import PARAMETER_NAMES as CONSISTENT_NAMES
from ..identification.consistent import STATIC_PARAMETERS as CONSISTENT_STATIC
from ..identification.payload_identification import (
    BIASES,
    full_layout,
    identify_payload,
    payload_regressor,
    weighted_least_squares,
)
from ..identification.payload_kinematics import kinematics_for
from ..identification.payload_report import (
    PARAMETER_UNITS,
    ExcitationWarning,
    identified_table,
    summary_text,
    warn_if_poorly_excited,
)
from ..identification.tether import candidate_frames, fit_tether_geometry, tether_columns
from .base import Compensator
from .physics_rows import PayloadRowKernels
from .robot_file import CarriesRobot

__all__ = [  # with the identification's names that callers take from here
    "BIASES", "IDENTIFICATIONS", "PARAMETER_NAMES", "PARAMETER_UNITS", "STATIC_PARAMETERS",
    "WEIGHT_PARAMETERS", "ExcitationWarning", "PhysicsPayloadCompensator", "payload_regressor",
    "weighted_least_squares"]

PARAMETER_NAMES = list(CONSISTENT_NAMES)
STATIC_PARAMETERS = list(CONSISTENT_STATIC)
#: The weight carried without inertia (``weight_without_inertia``): θ[16:20].
WEIGHT_PARAMETERS = [16, 17, 18, 19]
#: How the parameters are identified: weighted least squares, or constrained to a physically
#: possible body (pseudo-inertia ⪰ 0, m > 0; :mod:`..identification.consistent`), with a prior.
IDENTIFICATIONS = ("least_squares", "consistent")


class FixedJointsWarning(UserWarning):
    """Joints between the world and the sensor that the log does not hold were fixed at 0."""


class PhysicsPayloadCompensator(CarriesRobot, PayloadRowKernels, Compensator):
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
    joints : the joints of `robot` that X's position columns hold, in their order (names,
        or one comma-separated string), when the robot model has other joints (a torso, a
        head, fingers); None: X holds every joint of the model, in the model's order.
    fixed_joints : where the joints not in `joints` stand: a mapping name → value (rad for
        revolute, m for prismatic), ``"torso=0.2,finger=0.01"`` or a YAML file of such a
        mapping. A joint between the world and S given in neither stands at 0 (a
        :class:`FixedJointsWarning` names it). The model file keeps both.
    gravity : gravity in the world (base) frame, m/s².
    package_xmls : extra package.xml files for `robot`'s package:// URLs.
    identification : "least_squares" (weighted least squares, any 10 numbers) or "consistent"
        (the same fit constrained to a physically possible body — m > 0, pseudo-inertia ⪰ 0 —
        solved as a small SDP, :func:`~..identification.consistent.identify_consistent`; the
        unconstrained estimate is kept in ``identified()["least_squares"]``).
    prior : a :class:`PayloadPrior` (mass, CoM, inertia about the CoM, in S;
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
    identify_crosstalk : also identify the sensor calibration's cross-talk: the reading
        matrix becomes ``M = (I + E)·R_SmS`` with E off-diagonal (the gains are the
        calibration's: the payload absorbs a common scale), each entry given a prior of ±2 %
        (relative; ±0.4 N per N·m and ±1 mm, i.e. N·m per N, between force and torque axes),
        alternated with the linear fit
        (:func:`~..identification.payload_identification.fit_crosstalk`). Fitted:
        ``crosstalk_`` (E) and ``reading_matrix_`` (M), with which the model predicts the
        reading. A contact is still mapped into S by the mounting rotation alone
        (:meth:`reading_to_model_frame`). Needs ``mode="dynamic"``.
    tether : also identify a cable tethered to the tool (:mod:`..identification.tether`):
        ``"auto"`` finds the frame its other end is fixed in among every moving joint's frame
        and the world, a joint name (or ``"world"``) takes that frame; None (default): no
        tether. Needs ``weight_without_inertia`` (a cable's hanging weight) and
        ``mode="dynamic"``; θ then has 22 entries. Fitted: ``tether_frame_``,
        ``tether_anchor_`` (P in that frame, m), ``tether_attach_`` (Q in S, m) and
        ``tether_search_`` (per frame tried, the share of the weighted residual sum of squares
        left, against no tether).

    The sensor temperature (°C), given as X's last column (``[q, q̇, q̈, T]``), adds a linear
    zero drift per axis, ``k·(T − T_ref)`` (``temperature_coefficients_``, N/K and N·m/K in
    Sm; ``temperature_reference_`` the training mean, at which the biases hold).

    Fitted attributes: ``parameters_`` (16, 20 with ``weight_without_inertia``, 22 with a
    ``tether``),
    ``standard_errors_`` (same; ∞ where nothing determines a parameter), ``covariance_``,
    ``condition_number_``,
    ``residual_rms_`` (6), ``physically_consistent_``, ``identification_`` (the full
    :class:`ConsistentIdentification`). An :class:`ExcitationWarning` names the
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
    compiled kernel as the mean (one 6 × 16 by 16 × r product more).
    """

    #: The std of a new reading (noise included), not just of the prediction.
    provides_std = True
    std_includes_noise = True
    #: Models saved before the options existed have no such attributes.
    weight_without_inertia = False
    tether = None
    identify_crosstalk = False
    _parameter_constraints: ClassVar[dict] = {
        **Compensator._parameter_constraints,
        "mode": [StrOptions({"dynamic", "static"})],
        "robot": [str, os.PathLike, None],
        **{name: [str, None] for name in ("sensor_frame", "base_frame", "tether")},
        **{name: ["array-like"] for name in ("gravity", "package_xmls")},
        "identification": [StrOptions(set(IDENTIFICATIONS))],
        "prior": [PayloadPrior, Mapping, None],
        "prior_weight": [Interval(Real, 0, None, closed="neither")],
        **{name: ["boolean"] for name in ("identify_mounting", "weight_without_inertia",
                                          "identify_crosstalk")},
        "joints": [str, "array-like", None],
        "fixed_joints": [Mapping, str, "array-like", None],
    }

    def __init__(self, features="q,qd,qdd", mode="dynamic", robot=None, sensor_frame=None,
                 base_frame=None, gravity=GRAVITY_W, package_xmls=(),
                 identification="least_squares", prior=None,
                 prior_weight=DEFAULT_PRIOR_WEIGHT, identify_mounting=False,
                 weight_without_inertia=False, joints=None, fixed_joints=None, tether=None,
                 identify_crosstalk=False):
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
        self.joints = joints
        self.fixed_joints = fixed_joints
        self.tether = tether
        self.identify_crosstalk = identify_crosstalk

    @property
    def n_parameters(self) -> int:
        """16 (payload and biases), 20 with the weight carried without inertia, 22 with a
        tether."""
        if self.tether:
            return 22
        return 20 if self.weight_without_inertia else 16

    # -- the regressor ----------------------------------------------------------------------
    def regressor(self, X) -> np.ndarray:
        """The (N, 6, p) regressor A with reading = A·θ: p = 16, θ = [φ; b]; p = 20 with
        ``weight_without_inertia`` (θ = [φ; b; w]); p = 22 with a fitted tether (θ = [φ; b;
        w; k, k·ℓ0])."""
        X = np.asarray(X, dtype=float)
        n = X.shape[1] // 3
        kin = self._kinematics().evaluate(X[:, :n], X[:, n:2 * n], X[:, 2 * n:])
        if self.mode == "static":
            kin = kin.__class__(kin.R_WS, 0 * kin.w_WS_S, 0 * kin.alpha_WS_S,
                                0 * kin.a_WSo_S, kin.g_S)
        A = payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S,
                              kin.g_S if self.weight_without_inertia else None)
        if getattr(self, "tether_frame_", None) is None:
            return A
        return np.concatenate([A, self._tether_columns(X)], axis=2)

    def _tether_columns(self, X) -> np.ndarray:
        """(N, 6, 2): the fitted tether's columns for the full-layout rows X."""
        index = self.tether_frame_names().index(self.tether_frame_)
        X_SF = self._kinematics().anchor_frames_in_sensor(X)[:, index]
        return tether_columns(X_SF, self.tether_anchor_, self.tether_attach_)

    def tether_frame_names(self) -> list[str]:
        """The frames a tether's far end may be fixed in: each moving joint's child frame M
        (by the joint's name), from the base outwards, then ``"world"``."""
        return self._kinematics().anchor_frame_names()

    def _fit(self, Z, Y):
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
        if self.identify_crosstalk and self.mode != "dynamic":
            raise ConfigError("identify_crosstalk needs mode='dynamic': in static poses the "
                              "tool's wrench spans too few directions to separate the "
                              "cross-talk from the payload (calibrate the sensor's "
                              "correction on static poses with known loads instead: "
                              "calibrate_table(..., correction='full'))")
        if self.tether and not (self.weight_without_inertia and self.mode == "dynamic"):
            raise ConfigError("tether needs weight_without_inertia=True and mode='dynamic': "
                              "a cable's hanging weight is the weight carried without "
                              "inertia, which only motion separates from the tool's mass")
        Z, temperature = self._split_temperature(Z)
        X = full_layout(Z, self.n_joints_)
        self._embed_robot()
        self._check_robot_joints()
        self.tether_frame_ = None
        A = self.regressor(X)
        if self.tether:
            frames = candidate_frames(self.tether, self.tether_frame_names())
            with warnings.catch_warnings():  # the fit with the tether warns, if it must
                warnings.simplefilter("ignore", ExcitationWarning)
                # Without the cross-talk: E would take the cable's pull it does not model.
                self._identify(A, Y, prior, temperature, crosstalk=False)
            self._fit_tether_geometry(A, X, Y, temperature, frames)
            A = np.concatenate([A, self._tether_columns(X)], axis=2)
        self._identify(A, Y, prior, temperature)

    def _fit_tether_geometry(self, A, X, Y, temperature, frames) -> None:
        """The tether's geometry from the fit without it (module
        :mod:`..identification.tether`; A its regressor): readings and the model's columns in S,
        weighted by that fit's residual per axis."""
        block_S = np.linalg.inv(self.reading_matrix())
        reference = getattr(self, "temperature_reference_", None)
        if temperature is not None and reference is not None:
            Y = Y - np.outer(temperature - reference, self.temperature_coefficients_)
        Y_S = Y @ block_S.T
        A_S = A.copy()
        A_S[:, :, BIASES] = np.einsum("ij,njk->nik", block_S, A[:, :, BIASES])
        residual = Y - self._predict_from(A, temperature)
        weights = 1.0 / np.maximum(np.sqrt(np.mean(residual ** 2, axis=0)),
                                   1e-9 * (1 + np.abs(Y).max()))
        all_frames = self._kinematics().anchor_frames_in_sensor(X)
        names = self.tether_frame_names()
        search = fit_tether_geometry(all_frames[:, [names.index(f) for f in frames]], frames,
                                     A_S, Y_S, weights,
                                     refine_rotation=self.identify_mounting
                                     or self.identify_crosstalk)
        self.tether_frame_ = search.geometry.frame
        self.tether_anchor_ = np.array(search.geometry.p_FP)
        self.tether_attach_ = np.array(search.geometry.p_SQ)
        self.tether_search_ = {name: float(c) for name, c in search.relative_cost.items()}

    def _split_temperature(self, Z):
        if getattr(self, "temperature_in_", False):
            return Z[:, :-1], Z[:, -1]
        return Z, None

    def _identify(self, A, Y, prior, temperature=None, crosstalk=None):
        """Sets the fitted attributes from the (N, 6, p) regressor and the readings
        (:func:`~..identification.payload_identification.identify_payload`); `crosstalk`:
        whether to identify it (default: ``identify_crosstalk``)."""
        static = self.mode == "static"
        vars(self).update(identify_payload(
            A, Y, static=static, identification=self.identification, prior=prior,
            prior_weight=self.prior_weight, identify_mounting=self.identify_mounting,
            temperature=temperature,
            identify_crosstalk=self.identify_crosstalk if crosstalk is None else crosstalk))
        self.residual_rms_ = np.sqrt(np.mean((Y - self._predict_from(A, temperature)) ** 2,
                                             axis=0))
        # A possible payload: a body (a positive mass, static) and a weight without inertia
        # that weighs something or nothing.
        self.physically_consistent_ = is_possible(self.parameters_, static)
        warn_if_poorly_excited(self, stacklevel=3)

    def _predict_from(self, A, temperature=None):
        """Readings in Sm: ``R_SmS ⊗ (A_φ φ [+ A_w w]) + b + k·(T − T_ref)``."""
        wrench_S = A[:, :, :10] @ self.parameters_[:10]
        if A.shape[-1] > 16:  # a weight carried without inertia and a tether: in S
            wrench_S = wrench_S + A[:, :, 16:] @ self.parameters_[16:]
        out = wrench_S @ self.reading_matrix().T
        out = out + self.parameters_[BIASES]
        reference = getattr(self, "temperature_reference_", None)
        if temperature is not None and reference is not None:
            out = out + np.outer(temperature - reference, self.temperature_coefficients_)
        return out

    def _predict(self, Z):
        Z, temperature = self._split_temperature(Z)
        X = full_layout(Z, self.n_joints_)
        return self._predict_from(self.regressor(X), temperature)

    def _predict_std(self, Z):
        return np.sqrt(self._variance(Z, include_noise=True))

    def parameter_std(self, X) -> np.ndarray:
        """(N, 6) std of the predicted reading from the parameters' uncertainty alone (no
        noise term): what :class:`~.hybrid.HybridCompensator` adds to its residual's."""
        return np.sqrt(self._variance(self._validated_features(X), include_noise=False))

    def _variance(self, Z, include_noise):
        Z, temperature = self._split_temperature(Z)
        X = full_layout(Z, self.n_joints_)
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
        is ``M·W_ext,S`` (plus noise).

        A cross-talk identified in free motion (``identify_crosstalk``) predicts the reading
        but does not map a contact: T is then the mounting rotation's inverse alone. Free
        motion determines E only in the combinations of axes it excites, and E takes up
        what the model misses there; it is no calibration against known loads (``calibrate
        --correction``, :meth:`with_correction`, whose M maps contacts)."""
        matrix = self.reading_matrix()
        if getattr(self, "crosstalk_", None) is not None:
            matrix = np.kron(np.eye(2), self.mounting_rotation_).T
        if np.array_equal(matrix, np.eye(6)):
            return None
        return np.linalg.inv(matrix)

    def with_correction(self, correction) -> PhysicsPayloadCompensator:
        """A copy that predicts readings through a gain/cross-talk correction identified on
        static poses (:class:`CalibrationCorrection`):
        ``M·W_S(payload) + b + k·ΔT`` with the correction's M, bias, temperature coefficients
        and payload (it must have one payload for every row). The parameters' covariance stays
        the rigid fit's (an approximation: M's own uncertainty is not propagated). A weight
        carried without inertia is set to zero: the static poses' payload holds all the weight
        there is."""
        if correction.payload is None:
            raise ConfigError("the correction was fitted with a known payload per row: no "
                              "single payload to predict with")
        if getattr(self, "tether_frame_", None) is not None:
            raise ConfigError("this model has a tether, which the correction's static fit did "
                              "not model (its payload took the tether's pull in those poses): "
                              "fit the model without a tether to use the correction")
        model = copy.deepcopy(self)
        model.parameters_ = self.parameters_.copy()
        model.parameters_[:4] = correction.payload
        model.parameters_[BIASES] = correction.bias
        model.parameters_[16:] = 0.0
        model.mounting_rotation_ = np.eye(3)  # M holds the mounting too
        model.crosstalk_ = None  # the correction's M replaces a free-motion cross-talk
        model.reading_matrix_ = np.asarray(correction.sensor_matrix, dtype=float).copy()
        if correction.temperature_coefficients is not None:
            model.temperature_coefficients_ = np.asarray(correction.temperature_coefficients)
            model.temperature_std_errors_ = np.asarray(correction.temperature_std_errors)
            model.temperature_reference_ = correction.temperature_reference
        model.residual_rms_ = np.asarray(correction.residual_rms, dtype=float).copy()
        return model

    # -- reporting --------------------------------------------------------------------------
    def identified(self) -> dict:
        """Identified parameters with standard errors and units, plus derived CoM (m)
        (:func:`~..identification.payload_report.identified_table`)."""
        return identified_table(self)

    def summary(self) -> str:
        """The identified parameters with standard errors, as lines a user reads."""
        return summary_text(self)

    # -- kinematics -------------------------------------------------------------------------
    def _kinematics(self):
        return kinematics_for(self.robot_description(), tuple(self.gravity))

    def robot_description(self) -> RobotDescription:
        """The robot this model identifies its payload on."""
        if self.robot is None:
            if self.sensor_frame is not None or self.base_frame is not None:
                raise RobotModelError("sensor_frame and base_frame need a robot model (robot=...)")
            return ftdrake_arm()
        if not self.sensor_frame:
            raise RobotModelError(f"robot {self.robot!r} needs sensor_frame (the frame of the "
                                  "measured wrench)")
        model, package_xmls = self._robot_source()
        return RobotDescription(model, self.sensor_frame, self.base_frame, package_xmls,
                                self._joint_columns(), fixed_joint_values(self.fixed_joints),
                                name=Path(str(self.robot)).name)

    def _joint_columns(self) -> tuple[str, ...]:
        return joint_names(getattr(self, "joints", None))  # None in models saved before it

    def _build_robot(self) -> None:
        self._kinematics()

    def _check_robot_joints(self):
        kinematics = self._kinematics()
        if kinematics.num_joints != self.n_joints_:
            if self._joint_columns():
                raise RobotModelError(
                    f"the data has {self.n_joints_} joints but {option_name('joints')} names "
                    f"{kinematics.num_joints} ({', '.join(self._joint_columns())}): name one "
                    "joint per position column, in their order")
            raise RobotModelError(kinematics.count_message(self.n_joints_))
        if kinematics.defaulted:
            warnings.warn(
                f"joints {', '.join(kinematics.defaulted)} between the world and the sensor "
                "frame are not in the log: fixed at 0 (give their positions with "
                f"{option_name('fixed_joints')} NAME=VALUE,...)",
                FixedJointsWarning, stacklevel=4)

