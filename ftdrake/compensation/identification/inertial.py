"""Inertial parameters of a rigid body, and whether they describe a body that can exist.

``φ = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``: mass (kg), first moment ``h = m·c``
(kg·m) and the inertia matrix entries about the frame's origin (kg·m²), all in one frame.
A body is physically realisable (a non-negative mass density, possibly degenerate: a point,
a rod, a plate) if and only if its *pseudo-inertia*

    J = ∫ [p; 1][p; 1]ᵀ dm = [[Σ, h], [hᵀ, m]],   Σ = ∫ p pᵀ dm = ½ tr(I)·1 − I,

is positive semidefinite (Wensing, Kim, Slotine, "Linear matrix inequalities for physically
consistent inertial parameter identification: a statistical perspective on the mass
distribution", IEEE RA-L 2017). ``J ⪰ 0`` implies ``m ≥ 0`` and, about the centre of mass,
the triangle inequalities of the principal moments (``I1 + I2 ≥ I3`` and permutations). It is
linear in ``φ``, so a fit constrained to it is a small semidefinite program
(:mod:`.consistent`).
"""

from __future__ import annotations

import numpy as np


def inertia_matrix(theta10) -> np.ndarray:
    """The 3×3 inertia about So, from ``φ[4:10] = [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    phi = as_phi(theta10)
    Ixx, Ixy, Ixz, Iyy, Iyz, Izz = phi[4:10]
    return np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])


def pseudo_inertia(theta10) -> np.ndarray:
    """The 4×4 pseudo-inertia ``J = [[½tr(I)·1 − I, h], [hᵀ, m]]`` of ``φ`` (SI units).

    ``I`` is the inertia about So and ``h = m·c`` the first moment, both in S, so
    ``J = ∫ [p; 1][p; 1]ᵀ dm`` over the body's points p (measured from So, in S). J is
    positive semidefinite exactly when some (possibly degenerate) body has these parameters
    (Wensing, Kim, Slotine 2017); see :func:`is_physically_consistent`.
    """
    phi = as_phi(theta10)
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
    phi = as_phi(theta10)
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


def from_pseudo_inertia(J) -> np.ndarray:
    """φ from J (the inverse of :func:`pseudo_inertia`): I = tr(Σ)·1 − Σ."""
    J = 0.5 * (J + J.T)
    sigma = J[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array([J[3, 3], *J[:3, 3], inertia[0, 0], inertia[0, 1], inertia[0, 2],
                     inertia[1, 1], inertia[1, 2], inertia[2, 2]])


def as_phi(theta10) -> np.ndarray:
    phi = np.asarray(theta10, dtype=float).reshape(-1)
    if phi.shape[0] in (16, 20):
        phi = phi[:10]
    if phi.shape != (10,):
        raise ValueError(f"expected the 10 inertial parameters (or all 16 or 20), got "
                         f"{phi.shape}")
    return phi
