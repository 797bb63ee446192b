"""The convex program of the physically consistent identification (:mod:`.consistent`):
weighted least squares over the bodies that exist, in Drake's ``MathematicalProgram``.

The data term enters as a norm (a Lorentz cone) of the reduced p × p factor, the body as the
linear matrix inequality ``J(φ) ⪰ 0`` on its pseudo-inertia (:mod:`.inertial`), the mass as
``m ≥ min_mass``, and a prior as the second-order form of the log-det divergence between
pseudo-inertias (:func:`prior_precision`). Solved with Clarabel (or SCS), both shipped with
Drake's wheel.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, ScsSolver, SolverOptions

from ...errors import ConfigError, FtdrakeError
from .inertial import from_pseudo_inertia, physical_violations, pseudo_inertia
from .regression import NULL_DIRECTION_TOL

# A prior's second moments about its centre of mass are floored at m0·(1 mm)² so that the
# metric the prior uses exists for a point mass, a rod or a plate.
_PRIOR_MIN_SPREAD = 1e-3
#: θ's index of the mass of a weight carried without inertia (when θ has 20 entries).
WEIGHT_MASS = 16


class IdentificationError(FtdrakeError, RuntimeError):
    """The convex program of the consistent identification did not solve."""


def solve_program(R, z, scale, static, prior_precision, x0, min_mass, m_ref, length, solver,
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
        if p > WEIGHT_MASS:  # a weight carried without inertia weighs something or nothing
            prog.AddBoundingBoxConstraint(0.0, np.inf, x[WEIGHT_MASS])
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

    dut, name = pick_solver(solver)
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
    null = Vt[s <= NULL_DIRECTION_TOL * s[0]] if s[0] > 0 else Vt
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


def onto_constraints(theta, static, min_mass, m_ref, length):
    """Removes the solver's last rounding (~1e-8) across the constraints' boundary: clips
    negative eigenvalues of the scaled pseudo-inertia to zero and the mass to `min_mass`, so
    the estimate passes :func:`is_physically_consistent` exactly."""
    theta = theta.copy()
    if not static:
        D = np.diag([1 / length] * 3 + [1.0]) / np.sqrt(m_ref)
        lam, V = np.linalg.eigh(D @ pseudo_inertia(theta[:10]) @ D)
        if lam[0] < 0:
            Dinv = np.linalg.inv(D)
            theta[:10] = from_pseudo_inertia(Dinv @ ((V * np.maximum(lam, 0.0)) @ V.T) @ Dinv)
    theta[0] = max(theta[0], min_mass)
    if len(theta) > WEIGHT_MASS:
        theta[WEIGHT_MASS] = max(theta[WEIGHT_MASS], 0.0)
    return theta


def pick_solver(solver):
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


def active_constraints(theta, static, min_mass, m_ref, length, tol=1e-6):
    """Names of the constraints θ lies on (to `tol`, in the program's scaling)."""
    active = []
    if theta[0] <= min_mass * (1 + tol):
        active.append("min_mass")
    if len(theta) > WEIGHT_MASS and theta[WEIGHT_MASS] <= tol * max(abs(theta[0]), 1e-12):
        active.append("weight_without_inertia >= 0")
    if not static:
        # The smallest eigenvalue of D·J·D (the scaled J of the program, entries of order
        # one): zero = a degenerate body (plate, rod, point), on the boundary of J ⪰ 0.
        D = np.diag([1 / length] * 3 + [1.0]) / np.sqrt(m_ref)
        eig = np.linalg.eigvalsh(D @ pseudo_inertia(theta[:10]) @ D)
        if eig[0] <= tol * eig[-1]:
            active.append("pseudo_inertia")
    return tuple(active)


def check_prior(prior) -> np.ndarray:
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


def prior_precision(phi0, weight, static):
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


def reference_scale(phi0, theta_ls, min_mass):
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
