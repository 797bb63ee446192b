"""Physically consistent identification of a rigid payload on a wrist F/T sensor.

The sensor's reading is linear in ``θ = [φ; b]``: the payload's 10 inertial parameters
``φ = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (mass, first moment ``h = m·c``,
inertia matrix entries about the sensor origin So; all expressed in S) and 6 biases — the
model and regressor of :mod:`ftdrake.compensation.physics` (``reading = A·θ``, ``A`` of shape
(N, 6, 16); (N, 6, 20) with a weight carried without inertia, whose 4 parameters are
unconstrained like the biases). Plain least squares does not know that ``φ`` describes a
body: with poor excitation it returns a negative mass or an inertia no body has. Here the fit
is constrained to the set of bodies that exist.

A body is physically realisable (a non-negative mass density, possibly degenerate: a point,
a rod, a plate) if and only if its *pseudo-inertia*

    J = ∫ [p; 1][p; 1]ᵀ dm = [[Σ, h], [hᵀ, m]],   Σ = ∫ p pᵀ dm = ½ tr(I)·1 − I,

is positive semidefinite (Wensing, Kim, Slotine, "Linear matrix inequalities for physically
consistent inertial parameter identification: a statistical perspective on the mass
distribution", IEEE RA-L 2017). ``J ⪰ 0`` implies ``m ≥ 0`` and, about the centre of mass,
the triangle inequalities of the principal moments (``I1 + I2 ≥ I3`` and permutations). It is
linear in ``φ``, so the constrained fit is a small semidefinite program.

What is here:

* :func:`pseudo_inertia` – φ → J.
* :func:`physical_violations` / :func:`is_physically_consistent` – whether a φ is a body, and
  if not, what is wrong with it, in words.
* :func:`identify_consistent` – weighted least squares subject to ``J ⪰ 0`` and
  ``m ≥ min_mass``, optionally pulled toward a prior (e.g. CAD values), solved with Drake's
  ``MathematicalProgram`` and Clarabel (or SCS); returns a
  :class:`ConsistentIdentification` holding the estimate, the unconstrained least-squares
  estimate for comparison, standard errors, the condition number, the active constraints,
  how much the prior decided each parameter and which parameters the data alone cannot
  determine.

This module imports nothing from :mod:`ftdrake.compensation.physics` (which calls it).
"""

from __future__ import annotations

import dataclasses as dc
import time

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, ScsSolver, SolverOptions

from ..errors import ConfigError, FtdrakeError

#: θ's entries: payload φ (10), biases (6) and, with a weight carried without inertia, its
#: mass and first moment (4; :mod:`ftdrake.compensation.physics`).
PARAMETER_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
                   "bFx", "bFy", "bFz", "bTx", "bTy", "bTz", "mw", "mwcx", "mwcy", "mwcz")
#: θ's entries a static (gravity-only) model identifies: mass, first moment, biases.
STATIC_PARAMETERS = (0, 1, 2, 3, 10, 11, 12, 13, 14, 15)

#: Default weight of a prior: it counts as a measurement of the body to about ±10 % (1σ).
DEFAULT_PRIOR_WEIGHT = 100.0
#: Default lower bound on the mass, kg (the constraint is m ≥ min_mass > 0).
DEFAULT_MIN_MASS = 1e-3

# Singular values of the column-normalised regressor below this fraction of the largest mark
# a direction the data does not determine at all (least squares' pseudo-inverse drops them,
# so their parameters would otherwise show small standard errors).
_NULL_DIRECTION_TOL = 1e-7
# A regressor column below this fraction of the largest column's norm is round-off, not data.
_ZERO_COLUMN_TOL = 1e-9
# A prior's second moments about its centre of mass are floored at m0·(1 mm)² so that the
# metric the prior uses exists for a point mass, a rod or a plate.
_PRIOR_MIN_SPREAD = 1e-3


class IdentificationError(FtdrakeError, RuntimeError):
    """The convex program of :func:`identify_consistent` did not solve."""


# -- pseudo-inertia ------------------------------------------------------------------------
def inertia_matrix(theta10) -> np.ndarray:
    """The 3×3 inertia about So, from ``φ[4:10] = [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    phi = _as_phi(theta10)
    Ixx, Ixy, Ixz, Iyy, Iyz, Izz = phi[4:10]
    return np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])


def pseudo_inertia(theta10) -> np.ndarray:
    """The 4×4 pseudo-inertia ``J = [[½tr(I)·1 − I, h], [hᵀ, m]]`` of ``φ`` (SI units).

    ``I`` is the inertia about So and ``h = m·c`` the first moment, both in S, so
    ``J = ∫ [p; 1][p; 1]ᵀ dm`` over the body's points p (measured from So, in S). J is
    positive semidefinite exactly when some (possibly degenerate) body has these parameters
    (Wensing, Kim, Slotine 2017); see :func:`is_physically_consistent`.
    """
    phi = _as_phi(theta10)
    inertia = inertia_matrix(phi)
    J = np.empty((4, 4))
    J[:3, :3] = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    J[:3, 3] = J[3, :3] = phi[1:4]
    J[3, 3] = phi[0]
    return J


def physical_violations(theta10, tol: float = 1e-9) -> list[str]:
    """Why ``φ`` is not a physically possible body, in words; empty if it is one.

    The test is ``m > 0`` and ``λ_min(J) ≥ −tol·λ_max(J)`` for the pseudo-inertia J. With
    ``m > 0`` the second condition says that the second moment about the centre of mass,
    ``Σ_c = ½ tr(I_c)·1 − I_c``, is positive semidefinite, i.e. that the principal moments
    ``I1, I2, I3`` about the centre of mass satisfy the triangle inequalities; a failure is
    reported as the inequality it breaks.
    """
    phi = _as_phi(theta10)
    mass = phi[0]
    if not mass > 0:
        return [f"mass {mass:.6g} kg is not positive"]
    eig_J = np.linalg.eigvalsh(pseudo_inertia(phi))
    if eig_J[0] >= -tol * max(eig_J[-1], 0.0):
        return []
    com = phi[1:4] / mass
    inertia_com = inertia_matrix(phi) - mass * (com @ com * np.eye(3) - np.outer(com, com))
    moments = np.linalg.eigvalsh(inertia_com)
    problems = []
    for k, name in enumerate(("I1", "I2", "I3")):
        others = [j for j in range(3) if j != k]
        slack = moments[others].sum() - moments[k]
        if slack < 0:
            a, b = (("I1", "I2", "I3")[j] for j in others)
            problems.append(
                f"its principal moments about the centre of mass "
                f"(I1, I2, I3) = ({moments[0]:.4g}, {moments[1]:.4g}, {moments[2]:.4g}) kg·m² "
                f"break the triangle inequality {a} + {b} ≥ {name}")
    if not problems:  # J fails only by rounding beyond tol: still say what J says
        problems.append(f"its pseudo-inertia has eigenvalue {eig_J[0]:.3g} < 0")
    return problems


def is_physically_consistent(theta10, tol: float = 1e-9) -> bool:
    """True if ``φ`` (the 10 inertial parameters) is a physically possible body.

    ``m > 0`` and the pseudo-inertia ``J`` positive semidefinite up to ``tol`` relative to its
    largest eigenvalue. ``J ⪰ 0`` ⇔ some non-negative mass distribution has these
    parameters (Wensing, Kim, Slotine 2017, "Linear matrix inequalities for physically
    consistent inertial parameter identification"); it implies ``m ≥ 0``, a positive
    semidefinite inertia and the triangle inequalities ``I1 + I2 ≥ I3`` of the principal
    moments about the centre of mass — conditions that are each necessary but, checked
    separately on the inertia about So, not sufficient.
    """
    return not physical_violations(theta10, tol)


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
        in :func:`ftdrake.compensation.physics.weighted_least_squares`. When a constraint is
        active they are the unconstrained (linearised) approximation: they ignore that the
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
    :func:`is_physically_consistent`. Typical solve: 1–15 ms with Clarabel.

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
    phi0 = None if prior is None else _check_prior(prior)
    weights = axis_weights(A, Y) if weights is None else _check_weights(weights)

    # Weighted, column-normalised data, reduced to a p×p factor: ‖Aw θ − yw‖² =
    # ‖R x − z‖² + const with x = scale·θ.
    Aw = (A * weights[None, :, None]).reshape(-1, p)
    yw = (Y * weights[None, :]).reshape(-1)
    scale, zero_columns = _column_scale(Aw)
    R, z = _reduce(Aw / np.where(zero_columns, 1.0, scale), yw)
    x_ls = np.linalg.lstsq(R, z, rcond=None)[0]  # minimum norm, as lstsq on the full data
    theta_ls = x_ls / np.where(zero_columns, 1.0, scale)
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")

    # Columns the data do not touch get the scale of a typical value instead, so that their
    # variables are of order one in the program.
    m_ref, length = _reference_scale(phi0, theta_ls, min_mass)
    typical = np.array([m_ref, m_ref * length, m_ref * length, m_ref * length]
                       + [m_ref * length ** 2] * 6 + [1.0] * 6
                       + [m_ref, m_ref * length, m_ref * length, m_ref * length])[cols]
    scale = np.where(zero_columns, 1.0 / typical, scale)
    R_x = R * np.where(zero_columns, 0.0, 1.0)  # zero columns stay zero in R

    prior_precision = None  # P in x coordinates, on the n_phi inertial variables
    if phi0 is not None:
        P = _prior_precision(phi0, prior_weight, static)
        prior_precision = P / np.outer(scale[:n_phi], scale[:n_phi])
        x0 = phi0[cols[:n_phi]] * scale[:n_phi]

    x, solver_name, status, solve_time = _solve(
        R_x, z, scale, static, prior_precision, x0 if phi0 is not None else None, min_mass,
        m_ref, length, solver, solver_options)
    theta_c = _onto_constraints(x / scale, static, min_mass, m_ref, length)

    # Standard errors: σ² from the weighted residual, normal matrix (+ prior precision).
    residual = yw - Aw @ theta_c
    dof = max(1, len(yw) - p)
    sigma2 = float(residual @ residual / dof)
    normal = R_x.T @ R_x
    data_cov_x = sigma2 * _pinv_normal(R_x)
    if prior_precision is None:
        cov_x = data_cov_x
        share = np.zeros(p)
    else:
        posterior = normal.copy()
        posterior[:n_phi, :n_phi] += prior_precision
        post_inv = np.linalg.pinv(posterior, hermitian=True)
        cov_x = sigma2 * post_inv
        # ∂x̂/∂x0 = (H + P)⁻¹ P: how far the estimate follows a change of the prior's value.
        sensitivity = post_inv[:, :n_phi] @ prior_precision
        share = np.zeros(p)
        share[:n_phi] = np.clip(np.diag(sensitivity[:n_phi]), 0.0, 1.0)
    cov = cov_x / np.outer(scale, scale)

    rel, poor, unseen = _poorly_determined(R_x, data_cov_x / np.outer(scale, scale), theta_c,
                                           cols, relative_se_limit)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if prior_precision is None:  # the pseudo-inverse reports 0 along null directions
        se[unseen] = np.inf
    active = _active_constraints(theta_c, static, min_mass, m_ref, length)

    def full(v, fill):
        out = np.full(width, fill, dtype=float)
        out[cols] = v
        return out

    cov16 = np.full((width, width), np.nan)
    cov16[np.ix_(cols, cols)] = cov
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
        least_squares_consistent=is_physically_consistent(theta_ls16[:10]) if not static
        else bool(theta_ls16[0] > 0),
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
    scale, zero_columns = _column_scale(Aw)
    scale = np.where(zero_columns, 1.0, scale)
    R, z = _reduce(Aw / scale, yw)
    theta = np.linalg.lstsq(R, z, rcond=None)[0] / scale
    singular = np.linalg.svd(R, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else float("inf")
    residual = yw - Aw @ theta
    sigma2 = float(residual @ residual / max(1, len(yw) - p))
    cov = sigma2 * _pinv_normal(R) / np.outer(scale, scale)
    rel, poor, unseen = _poorly_determined(R, cov, theta, cols, relative_se_limit)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    se[unseen] = np.inf

    def full(v, fill):
        out = np.full(width, fill, dtype=float)
        out[cols] = v
        return out

    cov16 = np.full((width, width), np.nan)
    cov16[np.ix_(cols, cols)] = cov
    theta16 = full(theta, 0.0)
    A16 = A if A.shape[-1] == width else _embed(A, cols)
    consistent = (is_physically_consistent(theta16[:10]) if not static
                  else bool(theta16[0] > 0))
    return ConsistentIdentification(
        theta=theta16, standard_errors=full(se, np.nan), covariance=cov16,
        condition_number=condition, active_constraints=(), prior_share=full(np.zeros(p), np.nan),
        poorly_determined=poor, relative_errors=full(rel, np.nan), theta_least_squares=theta16,
        least_squares_consistent=consistent, weights=weights,
        residual_rms=np.sqrt(np.mean((Y - A16 @ theta16) ** 2, axis=0)), solver="lstsq",
        status="kSolutionFound", solve_time=0.0, static=bool(static))


def axis_weights(A, Y) -> np.ndarray:
    """Per-axis weights 1 / RMS of the residual of an unweighted least-squares pass (as
    ``weighted_least_squares``), floored so that an exact fit does not divide by zero."""
    p = A.shape[-1]
    R, z = _reduce(A.reshape(-1, p), Y.reshape(-1))
    theta = np.linalg.lstsq(R, z, rcond=None)[0]
    rms = np.sqrt(np.mean((Y - A @ theta) ** 2, axis=0))
    return 1.0 / np.maximum(rms, 1e-9 * (1 + np.abs(Y).max()))


def _column_scale(Aw):
    """(column norms, which columns the data do not touch). A column at round-off level
    (below 1e-9 of the largest, e.g. an inertia entry no rotation reaches: its entries are
    1e-16-level leftovers of the kinematics) counts as zero, and is zeroed in `Aw` in
    place: normalised to unit norm it would pass for an excited parameter."""
    scale = np.linalg.norm(Aw, axis=0)
    zero = scale <= _ZERO_COLUMN_TOL * max(scale.max(), 1e-300)
    Aw[:, zero] = 0.0
    return np.where(zero, 0.0, scale), zero


def _reduce(M, y):
    """(R, z) with ‖M x − y‖² = ‖R x − z‖² + const for every x (R: p×p upper triangular),
    from the QR factorisation of [M y] without forming Q."""
    p = M.shape[1]
    R_aug = np.linalg.qr(np.column_stack([M, y]), mode="r")
    R_aug = np.vstack([R_aug, np.zeros((p + 1 - len(R_aug), p + 1))])  # fewer rows than p+1
    return R_aug[:p, :p], R_aug[:p, p]


# -- the program ---------------------------------------------------------------------------
def _solve(R, z, scale, static, prior_precision, x0, min_mass, m_ref, length, solver,
           solver_options):
    """Solves the program in x = scale·θ; returns (x, solver name, status, seconds).

    Stage 1 minimises the misfit ``‖B x − d‖`` (data, plus the prior if any) over the
    constraints. Without a prior, directions the data leave exactly flat (null directions of
    R) are then fixed by a second stage: the smallest component of x along them among the
    physical bodies that fit as well (to 1e-6 relative) — least squares' minimum-norm rule,
    kept inside the constraints (for unexcited inertia: the smallest physical inertia).
    """
    p = len(z)
    n_phi = 4 if static else 10
    rows, rhs = [R], [z]
    if prior_precision is not None:
        L = np.linalg.cholesky(prior_precision).T  # LᵀL = P
        rows.append(np.hstack([L, np.zeros((n_phi, p - n_phi))]))
        rhs.append(L @ x0)
    B, d = np.vstack(rows), np.concatenate(rhs)

    def program():
        prog = MathematicalProgram()
        x = prog.NewContinuousVariables(p, "x")
        prog.AddBoundingBoxConstraint(min_mass * scale[0], np.inf, x[0])
        if not static:
            # J ⪰ 0 written for D·J·D, D = diag(1/L, 1/L, 1/L, 1)/√m_ref (a congruence: the
            # same cone), so that its entries are of order one whatever the body's size.
            D = np.diag([1 / length] * 3 + [1.0]) / np.sqrt(m_ref)
            F = [np.zeros((4, 4))]
            for a in range(10):
                e = np.zeros(10)
                e[a] = 1.0 / scale[a]
                F.append(D @ pseudo_inertia(e) @ D)
            prog.AddLinearMatrixInequalityConstraint(F, x[:10])
        return prog, x

    dut, name = _pick_solver(solver)
    options = SolverOptions()
    for key, value in (solver_options or {}).items():
        options.SetOption(dut.solver_id(), key, value)

    def run(prog, stage):
        start = time.perf_counter()
        result = dut.Solve(prog, None, options)
        elapsed = time.perf_counter() - start
        status = result.get_solution_result().name
        if not result.is_success():
            raise IdentificationError(
                f"the physically consistent identification did not solve ({stage}): {name} "
                f"returned {status}. Check the data for outliers and the regressor's units, "
                "or try solver='scs' / 'clarabel' or a prior")
        return result, status, elapsed

    prog, x = program()
    prog.AddL2NormCostUsingConicConstraint(B, -d, x)
    result, status, elapsed = run(prog, "fit")
    x_hat = result.GetSolution(x)

    _, s, Vt = np.linalg.svd(R)
    null = Vt[s <= _NULL_DIRECTION_TOL * s[0]] if s[0] > 0 else Vt
    if prior_precision is None and len(null):
        misfit = float(np.linalg.norm(B @ x_hat - d))
        prog, x = program()
        prog.AddLorentzConeConstraint(
            np.vstack([np.zeros((1, p)), B]), np.concatenate([[misfit * (1 + 1e-6) + 1e-6], -d]),
            x)
        prog.AddL2NormCostUsingConicConstraint(null, np.zeros(len(null)), x)
        result, status, more = run(prog, "minimum-norm stage")
        x_hat, elapsed = result.GetSolution(x), elapsed + more
    return x_hat, name, status, elapsed


def _onto_constraints(theta, static, min_mass, m_ref, length):
    """Removes the solver's last rounding (~1e-8) across the constraints' boundary: clips
    negative eigenvalues of the scaled pseudo-inertia to zero and the mass to `min_mass`, so
    the estimate passes :func:`is_physically_consistent` exactly."""
    theta = theta.copy()
    if not static:
        D = np.diag([1 / length] * 3 + [1.0]) / np.sqrt(m_ref)
        lam, V = np.linalg.eigh(D @ pseudo_inertia(theta[:10]) @ D)
        if lam[0] < 0:
            Dinv = np.linalg.inv(D)
            theta[:10] = _from_pseudo_inertia(Dinv @ ((V * np.maximum(lam, 0.0)) @ V.T) @ Dinv)
    theta[0] = max(theta[0], min_mass)
    return theta


def _from_pseudo_inertia(J) -> np.ndarray:
    """φ from J (the inverse of :func:`pseudo_inertia`): I = tr(Σ)·1 − Σ."""
    J = 0.5 * (J + J.T)
    sigma = J[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[0, 2],
                     inertia[1, 1], inertia[1, 2], inertia[2, 2]])


def _pick_solver(solver):
    choices = {"clarabel": ClarabelSolver, "scs": ScsSolver}
    if solver is None:
        for key in ("clarabel", "scs"):
            candidate = choices[key]()
            if candidate.available() and candidate.enabled():
                return candidate, candidate.solver_id().name()
        raise IdentificationError("neither Clarabel nor SCS is available in this Drake build")
    key = str(solver).lower()
    if key not in choices:
        raise ValueError(f"solver must be 'clarabel' or 'scs', got {solver!r}")
    candidate = choices[key]()
    if not (candidate.available() and candidate.enabled()):
        raise IdentificationError(f"solver {solver!r} is not available in this Drake build")
    return candidate, candidate.solver_id().name()


def _active_constraints(theta, static, min_mass, m_ref, length, tol=1e-6):
    """Names of the constraints θ lies on (to `tol`, in the program's scaling)."""
    active = []
    if theta[0] <= min_mass * (1 + tol):
        active.append("min_mass")
    if not static:
        # The smallest eigenvalue of D·J·D (the scaled J of the program, entries of order
        # one): zero = a degenerate body (plate, rod, point), on the boundary of J ⪰ 0.
        D = np.diag([1 / length] * 3 + [1.0]) / np.sqrt(m_ref)
        eig = np.linalg.eigvalsh(D @ pseudo_inertia(theta[:10]) @ D)
        if eig[0] <= tol * eig[-1]:
            active.append("pseudo_inertia")
    return tuple(active)


def _pinv_normal(R):
    """(RᵀR)⁺ from the SVD of R, dropping directions below the null-direction tolerance."""
    _, s, Vt = np.linalg.svd(R)
    keep = s > _NULL_DIRECTION_TOL * s[0] if s[0] > 0 else np.zeros_like(s, bool)
    inv = np.zeros_like(s)
    inv[keep] = 1.0 / s[keep] ** 2
    return (Vt.T * inv) @ Vt


def _poorly_determined(R, data_cov, theta, cols, relative_se_limit):
    """(relative data-only standard errors, names of the parameters the data cannot
    determine, indices of those in a null direction of R)."""
    names = set()
    _, s, Vt = np.linalg.svd(R)
    for k in np.flatnonzero(s <= _NULL_DIRECTION_TOL * s[0]):
        v = np.abs(Vt[k])
        names.update(np.flatnonzero(v >= 0.5 * v.max()).tolist())
    unseen = sorted(names)
    se = np.sqrt(np.maximum(np.diag(data_cov), 0.0))
    rel = np.full(len(cols), np.nan)
    magnitude = np.abs(theta)
    for group in ((0,), (1, 2, 3), (4, 5, 6, 7, 8, 9), (16,), (17, 18, 19)):
        idx = [i for i, c in enumerate(cols) if c in group]
        if not idx:
            continue
        group_scale = max(magnitude[idx].max(), 1e-12)
        rel[idx] = se[idx] / group_scale
        names.update(i for i in idx if rel[i] > relative_se_limit)
    ordered = tuple(PARAMETER_NAMES[cols[i]] for i in sorted(names))
    return rel, ordered, unseen


# -- the prior -----------------------------------------------------------------------------
def _check_prior(prior) -> np.ndarray:
    phi0 = np.asarray(prior, dtype=float)
    if phi0.shape != (10,):
        raise ConfigError(
            "prior must hold the 10 inertial parameters [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, "
            f"Iyy, Iyz, Izz] (inertia about the sensor origin, in S), got shape {phi0.shape}")
    if not np.all(np.isfinite(phi0)):
        raise ConfigError(f"prior holds NaN or infinity: {phi0.tolist()}")
    problems = physical_violations(phi0)
    if problems:
        raise ConfigError("prior is not a physically possible body: " + "; ".join(problems))
    return phi0


def _prior_precision(phi0, weight, static):
    """The prior's precision P on φ (10×10, or its marginal on [m, h] for a static fit):
    ``Δφᵀ P Δφ = weight · tr(J0⁻¹ ΔJ J0⁻¹ ΔJ)``."""
    m0 = phi0[0]
    c0 = phi0[1:4] / m0
    J0 = pseudo_inertia(phi0)
    sigma_c = J0[:3, :3] - m0 * np.outer(c0, c0)
    w, V = np.linalg.eigh(sigma_c)
    sigma_c = (V * np.maximum(w, m0 * _PRIOR_MIN_SPREAD ** 2)) @ V.T
    J0 = np.block([[sigma_c + m0 * np.outer(c0, c0), m0 * c0[:, None]],
                   [m0 * c0[None, :], np.array([[m0]])]])
    J0_inv = np.linalg.inv(J0)
    G = []
    for a in range(10):
        e = np.zeros(10)
        e[a] = 1.0
        G.append(J0_inv @ pseudo_inertia(e))
    M = np.array([[np.trace(Ga @ Gb) for Gb in G] for Ga in G])
    P = weight * 0.5 * (M + M.T)
    if static:
        P = np.linalg.inv(np.linalg.inv(P)[:4, :4])
    return P


def _reference_scale(phi0, theta_ls, min_mass):
    """A mass (kg) and a length (m) of the body's order, only to scale the program."""
    if phi0 is not None:
        m = phi0[0]
        J0 = pseudo_inertia(phi0)
        length = np.sqrt(max(np.trace(J0[:3, :3]), 0.0) / m)
    else:
        m = max(abs(theta_ls[0]), min_mass)
        length = np.linalg.norm(theta_ls[1:4]) / m if len(theta_ls) > 1 else 0.1
    length = float(np.clip(length if np.isfinite(length) else 0.1, 0.01, 1.0))
    return float(m), length


# -- input checks --------------------------------------------------------------------------
def _as_phi(theta10) -> np.ndarray:
    phi = np.asarray(theta10, dtype=float).reshape(-1)
    if phi.shape[0] in (16, 20):
        phi = phi[:10]
    if phi.shape != (10,):
        raise ValueError(f"expected the 10 inertial parameters (or all 16 or 20), got "
                         f"{phi.shape}")
    return phi


def _check_data(A, Y, static):
    A = np.asarray(A, dtype=float)
    Y = np.asarray(Y, dtype=float)
    widths = (16, 10) if static else (16, 20)
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
