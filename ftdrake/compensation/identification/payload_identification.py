"""Identifying the payload model's parameters: the Newton–Euler regressor, weighted least
squares, the sensor's mounting rotation and its zero drift with temperature.

The reading of a sensor carrying a rigid tool is linear in ``θ = [φ; b]`` (and the weight
carried without inertia, when identified): ``reading = A·θ`` with A from
:func:`payload_regressor`. :func:`identify_payload` fits θ (least squares, or physically
consistent: :mod:`.consistent`) and returns the fitted attributes of
:class:`~..estimators.physics.PhysicsPayloadCompensator`.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...physics.rigid_body import inertia_map, skew
from .consistent import STATIC_PARAMETERS, identify_consistent, identify_least_squares
from .regression import correlated_variance_ratio, correlation_length

#: The columns that are a wrench in S (rotated into Sm by a mounting); the biases are in Sm.
BIASES = slice(10, 16)
#: The cross-talk's prior: each off-diagonal entry of E is ~ N(0, CROSSTALK_PRIOR²), relative;
#: between a force and a torque axis scaled by a length, the sensor's radius
#: (CROSSTALK_LENGTH_M: N per N·m ÷ L, N·m per N × L). It holds at zero what the data
#: cannot separate (in free motion the tool's torque is nearly a multiple of its weight, so
#: the force rows' torque entries are barely observable) and barely moves what it can.
CROSSTALK_PRIOR = 0.02
CROSSTALK_LENGTH_M = 0.05
#: Alternations of E and the linear fit (E is small: each round changes it less).
CROSSTALK_ROUNDS = 5


def identify_payload(A, Y, *, static: bool, identification: str, prior, prior_weight: float,
                     identify_mounting: bool, temperature=None, identify_crosstalk=False
                     ) -> dict:
    """The payload model's fitted attributes from the (N, 6, p) regressor and the readings
    (:class:`~..estimators.physics.PhysicsPayloadCompensator`'s, by name, but ``residual_rms_`` and
    ``physically_consistent_``, which need the model's prediction).

    With a temperature, its per-axis coefficient is eliminated first (Frisch–Waugh–Lovell:
    each axis's data projected orthogonal to T − T_ref), so that the linear and the
    consistent fit see the payload and biases only; the coefficients follow from the
    residual. With `identify_mounting` the rotation comes first (nonlinear,
    :func:`fit_mounting`), the readings are rotated back into S, and the linear fit runs
    there. With `identify_crosstalk` the reading matrix becomes ``M = (I + E)·R`` (E: the
    calibration's cross-talk, :func:`fit_crosstalk`), identified by alternating E and the
    linear fit (``CROSSTALK_ROUNDS``); the standard errors are those of the linear fit given
    M (M's own uncertainty is not propagated). `prior`: a :class:`~.consistent.PayloadPrior`
    or None.
    """
    p = 16 if static else A.shape[-1]
    cols = list(STATIC_PARAMETERS) if static else list(range(p))
    d = None
    fitted = {"temperature_reference_": None}
    if temperature is not None:
        fitted["temperature_reference_"] = float(np.mean(temperature))
        d = np.asarray(temperature, float) - fitted["temperature_reference_"]
        if not np.any(np.abs(d) > 1e-9):
            d = None  # a constant temperature: its coefficients are not observable
    rotation, rotation_std_deg = np.eye(3), np.zeros(3)
    if identify_mounting:
        rotation, rotation_std_deg = fit_mounting(A, Y, d, cols)
    fitted.update(mounting_rotation_=rotation, mounting_std_deg_=rotation_std_deg)
    M_mount = np.kron(np.eye(2), rotation).T  # reading = M·W_S + b
    A_fit = A if d is None else project_out(A, d)

    def linear_fit(M):
        Y_S = Y @ np.linalg.inv(M).T
        Y_fit = Y_S if d is None else project_out(Y_S, d)
        if identification == "consistent":
            return Y_S, Y_fit, identify_consistent(
                A_fit[:, :, cols], Y_fit, static=static,
                prior=None if prior is None else prior.phi(), prior_weight=prior_weight)
        return Y_S, Y_fit, identify_least_squares(A_fit[:, :, cols], Y_fit, static=static)

    M, crosstalk = M_mount, None
    Y_S, Y_fit, result = linear_fit(M)
    if identify_crosstalk:
        wrench = [c for c in cols if not 10 <= c < 16]
        Y_centred = Y if d is None else project_out(Y, d)
        for _ in range(CROSSTALK_ROUNDS):
            V = (A_fit[:, :, wrench] @ result.theta[wrench]) @ M_mount.T
            crosstalk = fit_crosstalk(V, Y_centred)
            M = (np.eye(6) + crosstalk) @ M_mount
            Y_S, Y_fit, result = linear_fit(M)
    fitted.update(crosstalk_=crosstalk, reading_matrix_=None if crosstalk is None else M)
    # Rows of a time series are not independent samples: widen the standard errors by how
    # much the residual's correlation widens them (1 for independent rows).
    factor = np.ones(p)
    ratio, window = correlated_variance_ratio(
        A_fit[:, :, cols] * result.weights[None, :, None],
        (Y_fit - A_fit[:, :, cols] @ result.theta[cols]) * result.weights)
    factor[cols] = np.sqrt(ratio)
    fitted.update(standard_error_factor_=factor, correlation_window_=window)
    rotation_std_deg = rotation_std_deg * float(np.median(factor[cols]))
    fitted.update(mounting_std_deg_=rotation_std_deg)
    theta = result.theta.copy()
    cov = result.covariance * np.outer(factor, factor)
    # Biases were identified in S; the sensor adds them in Sm.
    theta[BIASES] = M @ theta[BIASES]
    to_Sm = np.eye(p)
    to_Sm[BIASES, BIASES] = M  # θ with the biases in Sm = to_Sm · θ in S
    finite = np.isfinite(cov)
    cov = to_Sm @ np.where(finite, cov, 0.0) @ to_Sm.T
    cov[~finite] = np.nan  # parameters not identified (a static fit's inertia) stay NaN
    standard_errors = result.standard_errors * factor
    standard_errors[BIASES] = np.sqrt(np.maximum(np.diag(cov[BIASES, BIASES]), 0.0))
    coefficients, coefficient_errors = _temperature_coefficients(Y_S - A @ result.theta, d, M)
    fitted.update(identification_=result, parameters_=theta, covariance_=cov,
                  standard_errors_=standard_errors, temperature_coefficients_=coefficients,
                  temperature_std_errors_=coefficient_errors,
                  condition_number_=float(result.condition_number))
    return fitted


def _temperature_coefficients(residual_S, d, M):
    """Per axis, the zero drift per kelvin in the reading's frame and its standard error,
    from the residual in S of the fit without it (zeros and NaN without a temperature)."""
    if d is None:
        return np.zeros(6), np.full(6, np.nan)
    k_S = residual_S.T @ d / (d @ d)
    rms = np.sqrt(np.mean((residual_S - np.outer(d, k_S)) ** 2, axis=0))
    return M @ k_S, np.abs(M @ (rms / np.sqrt(d @ d)))


def fit_crosstalk(V, Y) -> np.ndarray:
    """E (6 × 6, zero diagonal: the gains stay those of the sensor's calibration, as the
    payload's mass would absorb them) with ``Y ≈ (I + E)·V + b``: V (N, 6) the predicted
    wrench in the reading's frame without the biases, Y (N, 6) the readings. Per axis i, a
    ridge regression of ``Y_i − V_i`` on the other axes' V (each centred: b is free), with
    the prior ``CROSSTALK_PRIOR`` weighed against the axis's residual variance per
    independent sample (the variance × the residual's correlation length in rows)."""
    prior = np.full((6, 6), CROSSTALK_PRIOR)
    prior[:3, 3:] /= CROSSTALK_LENGTH_M
    prior[3:, :3] *= CROSSTALK_LENGTH_M
    V = V - V.mean(axis=0)
    R = Y - Y.mean(axis=0) - V
    E = np.zeros((6, 6))
    for i in range(6):
        others = [j for j in range(6) if j != i]
        G = V[:, others]
        # The residual before E (an upper bound on the noise), per independent sample: a
        # model's error is correlated over many rows, which count as one.
        variance = float(np.mean(R[:, i] ** 2)) * correlation_length(R[:, i:i + 1])
        normal = G.T @ G + np.diag(variance / prior[i, others] ** 2)
        E[i, others] = np.linalg.solve(normal, G.T @ R[:, i])
    return E


def project_out(M, d):
    """Each axis's data orthogonal to the temperature deviation d (N,): M (N, 6[, p])."""
    coef = np.tensordot(d, M, axes=(0, 0)) / (d @ d)
    return M - np.multiply.outer(d, coef)


def fit_mounting(A, Y, d, cols):
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


def full_layout(Z, n):
    """Pads selected features back to [q, q̇, q̈] with zeros (static models use only q);
    columns after the 3n of the joint layout (an IMU's) are kept."""
    X = np.zeros((len(Z), max(3 * n, Z.shape[1])))
    X[:, : Z.shape[1]] = Z
    return X
