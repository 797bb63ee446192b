"""Physically consistent identification of a rigid payload on a wrist F/T sensor.

The sensor's reading is linear in ``θ = [φ; b]``: the payload's 10 inertial parameters
``φ = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (mass, first moment ``h = m·c``,
inertia matrix entries about the sensor origin So; all expressed in S) and 6 biases — the
model and regressor of :mod:`ftdrake.compensation.estimators.physics` (``reading = A·θ``, ``A`` of
shape (N, 6, 16); (N, 6, 20) with a weight carried without inertia, whose 4 parameters are
unconstrained like the biases). Plain least squares does not know that ``φ`` describes a
body: with poor excitation it returns a negative mass or an inertia no body has. Here the fit
is constrained to the set of bodies that exist: those whose pseudo-inertia is positive
semidefinite (:mod:`.inertial`).

What is here:

* :func:`identify_consistent` – weighted least squares subject to ``J ⪰ 0`` and
  ``m ≥ min_mass``, optionally pulled toward a prior (:class:`PayloadPrior`, e.g. CAD
  values), solved as a convex program (:mod:`.consistent_program`); returns a
  :class:`ConsistentIdentification` holding the estimate, the unconstrained least-squares
  estimate for comparison, standard errors, the condition number, the active constraints,
  how much the prior decided each parameter and which parameters the data alone cannot
  determine.
* :func:`identify_least_squares` – the same weights and diagnostics without constraints.
* The body checks of :mod:`.inertial` (:func:`pseudo_inertia`, :func:`physical_violations`,
  :func:`is_physically_consistent`), importable from here too.

Model files name :class:`PayloadPrior` and :class:`ConsistentIdentification` by this module's
path. This module imports nothing from :mod:`ftdrake.compensation.estimators.physics` (which calls
it).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.optimize import lsq_linear

from ...errors import ConfigError
from .consistent_program import (
    WEIGHT_MASS,
    IdentificationError,
    active_constraints,
    check_prior,
    onto_constraints,
    prior_precision,
    reference_scale,
    solve_program,
)
from .inertial import (
    as_phi,
    from_pseudo_inertia,
    inertia_matrix,
    is_physically_consistent,
    physical_violations,
    pseudo_inertia,
)
from .regression import axis_weights, column_scale, pinv_normal, poorly_determined, reduce_rows

__all__ = [  # the names model code and files use from here, wherever they are defined
    "DEFAULT_MIN_MASS", "DEFAULT_PRIOR_WEIGHT", "PARAMETER_NAMES", "STATIC_PARAMETERS",
    "ConsistentIdentification", "IdentificationError", "PayloadPrior", "as_phi", "axis_weights",
    "from_pseudo_inertia", "identify_consistent", "identify_least_squares", "inertia_matrix",
    "is_physically_consistent", "is_possible", "physical_violations", "pseudo_inertia",
]

#: θ's entries: payload φ (10), biases (6) and, with a weight carried without inertia, its
#: mass and first moment (4; :mod:`ftdrake.compensation.estimators.physics`), then a tether's
#: stiffness and stiffness × rest length (2; :mod:`ftdrake.compensation.identification.tether`).
PARAMETER_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
                   "bFx", "bFy", "bFz", "bTx", "bTy", "bTz", "mw", "mwcx", "mwcy", "mwcz",
                   "k", "kl0")
#: θ's entries a static (gravity-only) model identifies: mass, first moment, biases.
STATIC_PARAMETERS = (0, 1, 2, 3, 10, 11, 12, 13, 14, 15)

#: Default weight of a prior: it counts as a measurement of the body to about ±10 % (1σ).
DEFAULT_PRIOR_WEIGHT = 100.0
#: Default lower bound on the mass, kg (the constraint is m ≥ min_mass > 0).
DEFAULT_MIN_MASS = 1e-3


# -- a prior -------------------------------------------------------------------------------
@dc.dataclass(frozen=True)
class PayloadPrior:
    """What one believes about the tool before the data (e.g. its CAD model), in S.

    Attributes
    ----------
    mass : kg, > 0.
    com : ``p_SoScm_S``, the centre of mass from the sensor origin So, expressed in S, m.
    inertia : the inertia about the centre of mass, expressed in S, kg·m², as
        ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (the order of :data:`PARAMETER_NAMES`); the default
        0 is a point mass (its spread is floored at 1 mm in the prior's metric).

    Raises :class:`~ftdrake.errors.ConfigError` naming the field for a mass that is not
    positive, a wrong length or a body no mass distribution has (triangle inequality).
    """

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[float, ...] = (0.0,) * 6

    def __post_init__(self):
        mass = float(np.asarray(self.mass, dtype=float))
        if not (np.isfinite(mass) and mass > 0):
            raise ConfigError(f"prior.mass: {self.mass!r} kg is not a positive mass")
        for name, n in (("com", 3), ("inertia", 6)):
            value = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if value.shape != (n,) or not np.all(np.isfinite(value)):
                raise ConfigError(f"prior.{name}: expected {n} finite numbers, got "
                                  f"{getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        object.__setattr__(self, "mass", mass)
        problems = physical_violations(self.phi())
        if problems:
            raise ConfigError("prior: not a physically possible body: " + "; ".join(problems))

    def phi(self) -> np.ndarray:
        """The 10 inertial parameters ``[m, m·c, I_So]`` (inertia moved to So by the
        parallel-axis theorem)."""
        c = np.asarray(self.com)
        I_c = inertia_matrix(np.r_[0, 0, 0, 0, self.inertia])
        I_So = I_c + self.mass * (c @ c * np.eye(3) - np.outer(c, c))
        return np.array([self.mass, *(self.mass * c), I_So[0, 0], I_So[0, 1], I_So[0, 2],
                         I_So[1, 1], I_So[1, 2], I_So[2, 2]])

    @classmethod
    def coerce(cls, prior) -> PayloadPrior | None:
        """A PayloadPrior from itself, a mapping of its fields (YAML), or None."""
        if prior is None or isinstance(prior, cls):
            return prior
        if isinstance(prior, dict):
            unknown = sorted(set(prior) - {"mass", "com", "inertia"})
            if unknown:
                raise ConfigError(f"prior: unknown fields {unknown}; expected mass, com, inertia")
            if "mass" not in prior:
                raise ConfigError("prior.mass: missing")
            return cls(**prior)
        raise ConfigError(f"prior: expected a PayloadPrior or a mapping with mass, com, "
                          f"inertia; got {type(prior).__name__}")


# -- the result ----------------------------------------------------------------------------
@dc.dataclass(frozen=True)
class ConsistentIdentification:
    """What :func:`identify_consistent` found.

    Attributes
    ----------
    theta : (16,) the estimate ``[φ; b]`` (SI units). A static fit leaves the inertia at 0.
    standard_errors : (16,) from the weighted residual variance σ² and the normal matrix,
        ``σ²·(AᵀWA + P)⁻¹`` (``P`` the prior's precision, pseudo-inverse without a prior), as
        in :func:`ftdrake.compensation.estimators.physics.weighted_least_squares`. When a constraint
        is active they are the unconstrained (linearised) approximation: they ignore that the
        estimate sits on a boundary. Without a prior, ∞ for parameters in a null direction of
        the data (the pseudo-inverse would say 0); NaN for parameters a static fit does not
        identify.
    covariance : (16, 16) the matrix whose diagonal gives ``standard_errors`` (NaN rows and
        columns for parameters not identified).
    condition_number : of the column-normalised weighted regressor (data only, no prior).
    active_constraints : names of the constraints the estimate lies on: ``"min_mass"``
        (``m = min_mass``) and/or ``"pseudo_inertia"`` (``J`` singular: the estimate is a
        degenerate body — a plate, a rod or a point).
    prior_share : (16,) how much the prior decided each parameter: how far the estimate
        follows a change of the prior's value of that parameter, ``∂θ̂_i/∂φ0_i =
        [(AᵀWA + P)⁻¹ P]_ii`` (the posterior mean is ``(AᵀWA + P)⁻¹ (AᵀWA θ_LS + P φ0)``),
        clipped to [0, 1]: ≈ 1 where the data add nothing to the prior (it also counts a
        parameter the data determine only in a combination with others, e.g. mass and force
        bias under a constant gravity direction), ≈ 0 where the data determine it; for one
        parameter alone it is the prior's fraction of the information, ``p / (h + p)``. The
        linearised (no active constraint) value. 0 for the biases (no prior on them) and for
        every parameter without a prior; NaN for parameters not identified.
    poorly_determined : names of the parameters the data alone cannot determine: those with
        a large component in a (near-)null direction of the column-normalised regressor,
        or whose data-only standard error exceeds ``relative_se_limit`` of its group's scale
        (mass; first moment; inertia).
    relative_errors : (16,) the data-only standard error over that group scale (NaN for the
        biases and for parameters not identified).
    theta_least_squares : (16,) the unconstrained weighted least-squares estimate from the
        same weights, without prior (minimum-norm where the data leave directions free).
    least_squares_consistent : whether ``theta_least_squares`` is a physically possible body.
    weights : (6,) the per-axis weights used.
    residual_rms : (6,) per-axis RMS of ``Y − A·theta``.
    solver, status : the solver's name and Drake's ``SolutionResult`` name.
    solve_time : seconds spent in the solver.
    static : whether only mass, first moment and biases were identified.
    """

    theta: np.ndarray
    standard_errors: np.ndarray
    covariance: np.ndarray
    condition_number: float
    active_constraints: tuple[str, ...]
    prior_share: np.ndarray
    poorly_determined: tuple[str, ...]
    relative_errors: np.ndarray
    theta_least_squares: np.ndarray
    least_squares_consistent: bool
    weights: np.ndarray
    residual_rms: np.ndarray
    solver: str
    status: str
    solve_time: float
    static: bool

    @property
    def parameters(self) -> tuple[int, ...]:
        """Indices of θ that were identified."""
        return STATIC_PARAMETERS if self.static else tuple(range(len(self.theta)))

    def summary(self) -> str:
        """A few lines a user can read: the estimate with standard errors and what decided it."""
        lines = [f"{'':5s} {'value':>12s} {'std error':>10s} {'prior share':>11s}"]
        for i in self.parameters:
            lines.append(f"{PARAMETER_NAMES[i]:5s} {self.theta[i]:12.5g} "
                         f"{self.standard_errors[i]:10.3g} {self.prior_share[i]:11.2f}")
        lines.append(f"condition number {self.condition_number:.3g}; active constraints: "
                     f"{', '.join(self.active_constraints) or 'none'}; "
                     f"not determined by the data: {', '.join(self.poorly_determined) or 'none'}")
        return "\n".join(lines)


# -- identification ------------------------------------------------------------------------
def identify_consistent(A, Y, *, weights=None, static=False, prior=None,
                        prior_weight=DEFAULT_PRIOR_WEIGHT, min_mass=DEFAULT_MIN_MASS,
                        solver=None, solver_options=None,
                        relative_se_limit=0.25) -> ConsistentIdentification:
    """Weighted least squares for ``Y ≈ A·θ`` over physically possible payloads.

    Minimises ``Σ_n ‖W (Y_n − A_n θ)‖² + ‖φ − φ0‖²_P`` subject to ``J(φ) ⪰ 0`` and
    ``m ≥ min_mass`` (``static=True``: ``m ≥ min_mass`` only), as a convex program in Drake's
    ``MathematicalProgram``: the data term is reduced once to a 16×16 triangular factor (QR
    of the column-normalised weighted regressor), so the program's size does not depend on
    N, and minimised as a norm (a Lorentz cone) next to the linear matrix inequality on J.
    Without a prior, directions the data leave exactly free (e.g. the inertia from static
    poses) are then settled by a second solve: the smallest such component among the
    physical bodies that fit as well — least squares' minimum-norm rule inside the
    constraints, which for unexcited inertia gives the smallest physical inertia. The
    solver's last ~1e-8 of rounding across the boundary is removed (negative eigenvalues of
    the scaled J clipped, mass clipped to ``min_mass``), so ``theta`` passes
    :func:`is_physically_consistent`.

    Parameters
    ----------
    A : (N, 6, 16) regressor (``payload_regressor``); with ``static=True`` also (N, 6, 10)
        holding only the columns ``STATIC_PARAMETERS``.
    Y : (N, 6) measured wrenches ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m.
    weights : (6,) per-axis weights W, ideally 1 / noise standard deviation. Default: as
        ``weighted_least_squares`` — 1 / RMS of each axis's residual after an unweighted
        first pass, which makes the weighted residuals of unit variance (the prior's weight
        below assumes that scale).
    static : identify mass, first moment and biases only (gravity-only data: the inertia is
        not observable). The pseudo-inertia constraint then has nothing to act on — any
        ``m > 0`` with any first moment is a point mass — so only ``m ≥ min_mass`` remains.
    prior : optional 10 inertial values ``φ0`` (e.g. the tool's CAD model), which must be a
        physically possible body (else :class:`~ftdrake.errors.ConfigError`, a ValueError,
        naming what is wrong). It enters as the second-order form of the log-det (entropic)
        divergence between pseudo-inertias used by Lee, Wensing & Park (2020) and
        ``robot_payload_id``: ``‖φ − φ0‖²_P = prior_weight · tr((J0⁻¹ ΔJ)²)``, a distance
        that does not depend on the frame the body is described in. The prior's
        second moments about its centre of mass are floored at ``m0·(1 mm)²`` so that the
        distance exists for a point mass, a rod or a plate. A static fit uses the prior's
        marginal on mass and first moment.
    prior_weight : w, the prior's precision relative to the data's unit-variance residuals:
        the prior says ``m = m0 ± m0/√w`` (1σ), and likewise each principal second moment
        about the centre of mass ``Σ_k ± Σ_k/√w``. Default 100 (±10 %, a CAD model that
        misses cables and screws); the data overrule it wherever they excite a parameter.
    min_mass : lower bound on the mass in kg, > 0.
    solver : "clarabel" (default when available) or "scs", both shipped with Drake's wheel.
    solver_options : optional {option name: value} for that solver (e.g. ``max_iter``).
    relative_se_limit : a data-only standard error above this fraction of the parameter's
        group scale marks the parameter as poorly determined.

    Returns
    -------
    ConsistentIdentification. Raises :class:`IdentificationError` if the solver fails and
    ValueError for malformed input.
    """
    A, Y = _check_data(A, Y, static)
    width = 16 if static else A.shape[-1]
    cols = np.array(STATIC_PARAMETERS if static else range(width))
    if A.shape[-1] == 16 and static:
        A = A[:, :, cols]
    n_phi = 4 if static else 10  # inertial parameters among the identified columns
    p = len(cols)
    if not (np.isscalar(min_mass) and np.isfinite(min_mass) and min_mass > 0):
        raise ValueError(f"min_mass must be a positive number of kg, got {min_mass!r}")
    if not (np.isscalar(prior_weight) and np.isfinite(prior_weight) and prior_weight > 0):
        raise ValueError(f"prior_weight must be a positive number, got {prior_weight!r}")
    phi0 = None if prior is None else check_prior(prior)
    weights = axis_weights(A, Y) if weights is None else _check_weights(weights)

    # Weighted, column-normalised data, reduced to a p×p factor: ‖Aw θ − yw‖² =
    # ‖R x − z‖² + const with x = scale·θ.
    Aw = (A * weights[None, :, None]).reshape(-1, p)
    yw = (Y * weights[None, :]).reshape(-1)
    scale, zero_columns = column_scale(Aw)
    R, z = reduce_rows(Aw / np.where(zero_columns, 1.0, scale), yw)
    x_ls = np.linalg.lstsq(R, z, rcond=None)[0]  # minimum norm, as lstsq on the full data
    theta_ls = x_ls / np.where(zero_columns, 1.0, scale)
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")

    # Columns the data do not touch get the scale of a typical value instead, so that their
    # variables are of order one in the program.
    m_ref, length = reference_scale(phi0, theta_ls, min_mass)
    typical = np.array([m_ref, m_ref * length, m_ref * length, m_ref * length]
                       + [m_ref * length ** 2] * 6 + [1.0] * 6
                       + [m_ref, m_ref * length, m_ref * length, m_ref * length]
                       + [10.0, 1.0])[cols]  # a tether: N/m, N
    scale = np.where(zero_columns, 1.0 / typical, scale)
    R_x = R * np.where(zero_columns, 0.0, 1.0)  # zero columns stay zero in R

    precision_x = x0 = None  # the prior's P in x coordinates, on the n_phi inertial variables
    if phi0 is not None:
        P = prior_precision(phi0, prior_weight, static)
        precision_x = P / np.outer(scale[:n_phi], scale[:n_phi])
        x0 = phi0[cols[:n_phi]] * scale[:n_phi]

    x, solver_name, status, solve_time = solve_program(
        R_x, z, scale, static, precision_x, x0, min_mass, m_ref, length, solver,
        solver_options)
    theta_c = onto_constraints(x / scale, static, min_mass, m_ref, length)

    # Standard errors: σ² from the weighted residual, normal matrix (+ prior precision).
    residual = yw - Aw @ theta_c
    sigma2 = float(residual @ residual / max(1, len(yw) - p))
    data_cov_x = sigma2 * pinv_normal(R_x)
    cov_x, share = _posterior(R_x, sigma2, data_cov_x, precision_x, n_phi)
    cov = cov_x / np.outer(scale, scale)

    rel, poor, unseen = _poorly_determined(R_x, data_cov_x / np.outer(scale, scale), theta_c,
                                           cols, relative_se_limit)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if precision_x is None:  # the pseudo-inverse reports 0 along null directions
        se[unseen] = np.inf
    active = active_constraints(theta_c, static, min_mass, m_ref, length)

    def full(v, fill):
        return _on_all_columns(v, cols, width, fill)

    cov16 = _on_all_columns(cov, cols, width, np.nan)
    theta16 = full(theta_c, 0.0)
    theta_ls16 = full(theta_ls, 0.0)
    A16 = A if A.shape[-1] == width else _embed(A, cols)
    return ConsistentIdentification(
        theta=theta16,
        standard_errors=full(se, np.nan),
        covariance=cov16,
        condition_number=condition,
        active_constraints=active,
        prior_share=full(share, np.nan),
        poorly_determined=poor,
        relative_errors=full(rel, np.nan),
        theta_least_squares=theta_ls16,
        least_squares_consistent=is_possible(theta_ls16, static),
        weights=weights,
        residual_rms=np.sqrt(np.mean((Y - A16 @ theta16) ** 2, axis=0)),
        solver=solver_name,
        status=status,
        solve_time=solve_time,
        static=bool(static),
    )


def identify_least_squares(A, Y, *, weights=None, static=False,
                           relative_se_limit=0.25) -> ConsistentIdentification:
    """Plain weighted least squares for ``Y ≈ A·θ``, reported like :func:`identify_consistent`.

    The same weights, column normalisation and diagnostics (standard errors — ∞ along null
    directions of the data, where the minimum-norm solution says nothing —, condition
    number, the parameters the data cannot determine), without constraints or prior: the
    estimate may be a body that cannot exist (``least_squares_consistent`` says so).
    """
    A, Y = _check_data(A, Y, static)
    width = 16 if static else A.shape[-1]
    cols = np.array(STATIC_PARAMETERS if static else range(width))
    if A.shape[-1] == 16 and static:
        A = A[:, :, cols]
    p = len(cols)
    weights = axis_weights(A, Y) if weights is None else _check_weights(weights)
    Aw = (A * weights[None, :, None]).reshape(-1, p)
    yw = (Y * weights[None, :]).reshape(-1)
    scale, zero_columns = column_scale(Aw)
    scale = np.where(zero_columns, 1.0, scale)
    R, z = reduce_rows(Aw / scale, yw)
    theta = np.linalg.lstsq(R, z, rcond=None)[0] / scale
    active = ()
    if width > WEIGHT_MASS and theta[WEIGHT_MASS] < 0:
        # A weight without inertia cannot be negative: bounded least squares (the same
        # problem with m_w ≥ 0), which puts it on the bound.
        lower = np.full(p, -np.inf)
        lower[WEIGHT_MASS] = 0.0
        theta = lsq_linear(R, z, bounds=(lower, np.inf), method="bvls").x / scale
        theta[WEIGHT_MASS] = max(theta[WEIGHT_MASS], 0.0)
        active = ("weight_without_inertia >= 0",)
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    residual = yw - Aw @ theta
    sigma2 = float(residual @ residual / max(1, len(yw) - p))
    cov = sigma2 * pinv_normal(R) / np.outer(scale, scale)
    rel, poor, unseen = _poorly_determined(R, cov, theta, cols, relative_se_limit)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    se[unseen] = np.inf

    def full(v, fill):
        return _on_all_columns(v, cols, width, fill)

    cov16 = _on_all_columns(cov, cols, width, np.nan)
    theta16 = full(theta, 0.0)
    A16 = A if A.shape[-1] == width else _embed(A, cols)
    consistent = is_possible(theta16, static)
    return ConsistentIdentification(
        theta=theta16, standard_errors=full(se, np.nan), covariance=cov16,
        condition_number=condition, active_constraints=active,
        prior_share=full(np.zeros(p), np.nan),
        poorly_determined=poor, relative_errors=full(rel, np.nan), theta_least_squares=theta16,
        least_squares_consistent=consistent, weights=weights,
        residual_rms=np.sqrt(np.mean((Y - A16 @ theta16) ** 2, axis=0)), solver="lstsq",
        status="kSolutionFound", solve_time=0.0, static=bool(static))


def is_possible(theta, static=False) -> bool:
    """Whether θ describes a payload that exists: a physically possible body (a positive
    mass for a static fit) and, with a weight carried without inertia, ``m_w ≥ 0``."""
    body = is_physically_consistent(theta[:10]) if not static else bool(theta[0] > 0)
    return body and (len(theta) <= WEIGHT_MASS or bool(theta[WEIGHT_MASS] >= 0))


# -- input checks --------------------------------------------------------------------------


def _check_data(A, Y, static):
    A = np.asarray(A, dtype=float)
    Y = np.asarray(Y, dtype=float)
    widths = (16, 10) if static else (16, 20, 22)
    if A.ndim != 3 or A.shape[1] != 6 or A.shape[2] not in widths:
        raise ValueError(f"A must have shape (N, 6, {' or '.join(map(str, widths))}), "
                         f"got {A.shape}")
    if Y.shape != A.shape[:2]:
        raise ValueError(f"Y must have shape {A.shape[:2]} (one wrench per regressor row), "
                         f"got {Y.shape}")
    for arr, name in ((A, "A"), (Y, "Y")):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} holds NaN or infinity; drop those samples first")
    if 6 * len(A) < A.shape[2]:
        raise ValueError(f"{len(A)} samples give fewer equations than the {A.shape[2]} "
                         "parameters")
    return A, Y


def _check_weights(weights) -> np.ndarray:
    w = np.asarray(weights, dtype=float)
    if w.shape != (6,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(f"weights must be 6 positive finite numbers, got {weights!r}")
    return w


def _embed(A, cols):
    out = np.zeros((*A.shape[:2], 16))
    out[:, :, cols] = A
    return out


def _poorly_determined(R, data_cov, theta, cols, relative_se_limit):
    """:func:`~.regression.poorly_determined` with the parameters named."""
    rel, poor, unseen = poorly_determined(R, data_cov, theta, cols, relative_se_limit)
    return rel, tuple(PARAMETER_NAMES[i] for i in poor), unseen


def _posterior(R_x, sigma2, data_cov_x, precision_x, n_phi):
    """(covariance in x coordinates, prior share per parameter): the data's alone without a
    prior; else σ²·(H + P)⁺ and the diagonal of ∂x̂/∂x0 = (H + P)⁻¹ P (how far the estimate
    follows a change of the prior's value), clipped to [0, 1]."""
    p = R_x.shape[1]
    share = np.zeros(p)
    if precision_x is None:
        return data_cov_x, share
    posterior = R_x.T @ R_x
    posterior[:n_phi, :n_phi] += precision_x
    post_inv = np.linalg.pinv(posterior, hermitian=True)
    sensitivity = post_inv[:, :n_phi] @ precision_x
    share[:n_phi] = np.clip(np.diag(sensitivity[:n_phi]), 0.0, 1.0)
    return sigma2 * post_inv, share


def _on_all_columns(v, cols, width: int, fill: float) -> np.ndarray:
    """`v` (over the identified columns `cols`: a vector, or a square matrix) placed into the
    model's `width` columns, `fill` elsewhere."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 2:
        out = np.full((width, width), fill, dtype=float)
        out[np.ix_(cols, cols)] = v
    else:
        out = np.full(width, fill, dtype=float)
        out[cols] = v
    return out
