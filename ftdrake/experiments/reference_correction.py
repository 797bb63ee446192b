"""Part two of the two-part compensation: a learned correction of the motor reference.

The encoders sit on the motor shafts, so a gearbox's twist under load moves the tool while
the controller sees nothing; the feedback cannot remove what it cannot see. Part two learns,
from tool-side measurements of earlier runs, how much each joint's *motor reference* has to
be offset so that the tool lands on the path: a function of the desired state
``x_d = [q_d, q̇_d, q̈_d]`` (what loads the gearboxes: gravity, inertia, friction), one GP
per joint, with the data subset and the confidence rule of part one
(:mod:`ftdrake.systems.learned_feedforward`). Indexed by state, it carries over to a path it
has not run; where the GP does not know, the correction is scaled down to nothing.

Learning target (iteration k, at the rows the tool error is known):
``y = c_k(x_d) + γ · J⁺(q_d) · e_tool``, the correction applied plus the tool error mapped to
joint space through the damped pseudo-inverse of the tool tip's translational Jacobian.
``e_tool`` comes either from a timed measurement (``p_desired − p_measured``, 3-D) or from an
untimed contour (the deviation along the ideal path's normal, with its sign, in the cutting
plane; see :mod:`ftdrake.sim.tool_measurement`).

The corrected reference is built before the run (the path is known in advance, as on a
cutting robot), on knots every ``knot_dt`` s, so the controller gets its velocity and
acceleration too: ``q_ref = q_d + c(x_d)``.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.trajectories import PiecewisePolynomial

from ..compensation.compiled.gp import CompiledGaussianProcess
from ..systems.learned_feedforward import (
    _feedforward_one,
    check_feedforward_model,
    prior_std,
)


class ReferenceCorrection:
    """A fitted reference-correction GP with part one's confidence rule.

    ``correction = confidence · mean``, ``confidence = clip((reject − σ/σ₀) /
    (reject − trust), 0, 1)`` per joint (σ: the GP's std of the function, σ₀ its prior std).
    `model` is fitted by :func:`~ftdrake.systems.learned_feedforward.fit_feedforward_gp`
    on ``[q_d, q̇_d, q̈_d]`` → reference offsets (rad).
    """

    def __init__(self, model, *, trust_ratio: float = 0.5, reject_ratio: float = 0.9):
        check_feedforward_model(model)
        if not 0 <= trust_ratio < reject_ratio <= 1:
            raise ValueError(f"need 0 <= trust_ratio < reject_ratio <= 1; got {trust_ratio}, "
                             f"{reject_ratio}")
        self.model = model
        self.trust_ratio, self.reject_ratio = float(trust_ratio), float(reject_ratio)
        self.n = int(model.n_joints_)
        self._gp = CompiledGaussianProcess(model)
        self.prior_std = prior_std(model)
        self._rule = np.array([self.trust_ratio, self.reject_ratio])
        self._mean, self._std = np.empty(self.n), np.empty(self.n)

    def evaluate(self, X) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X (N, 3n) desired states → (correction (rad), std (rad), confidence), each (N, n)."""
        mean, std = self._gp.predict_with_std(np.asarray(X, dtype=float))
        ratio = std / self.prior_std
        confidence = np.clip((self.reject_ratio - ratio) / (self.reject_ratio - self.trust_ratio),
                             0.0, 1.0)
        return confidence * mean, std, confidence

    def evaluate_one(self, x, out: np.ndarray | None = None) -> np.ndarray:
        """One desired state (3n,) → ``[correction, std, confidence]`` (3n,), in one compiled
        call (part one's: the GP's mean and std and the rule); what a loop evaluating the
        correction online would run each step."""
        out = np.empty(3 * self.n) if out is None else out
        _feedforward_one(np.asarray(x, dtype=float), *self._gp._arrays, self.prior_std,
                         self._rule, self._mean, self._std, out)
        return out


def desired_states(trajectory: PiecewisePolynomial, t) -> np.ndarray:
    """``[q, q̇, q̈]`` (N, 3n) of `trajectory` at times t."""
    return np.hstack([trajectory.vector_values(t).T,
                      trajectory.derivative(1).vector_values(t).T,
                      trajectory.derivative(2).vector_values(t).T])


def corrected_reference(trajectory: PiecewisePolynomial, offset_at, *,
                        knot_dt: float = 0.01) -> PiecewisePolynomial:
    """``q_d(t) + offset_at(t)`` as a C² spline on knots every `knot_dt` s (at rest at both
    ends). `offset_at` maps times (N,) to offsets (N, n) in rad."""
    t = np.arange(trajectory.start_time(), trajectory.end_time() + 1e-9, knot_dt)
    Q = trajectory.vector_values(t) + np.asarray(offset_at(t)).T
    zero = np.zeros((Q.shape[0], 1))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, Q, zero, zero)


def tip_jacobian_pinv(plant, arm, tip_frame, Q, damping: float = 1e-4) -> np.ndarray:
    """Damped pseudo-inverses ``Jᵀ (J Jᵀ + λ² I)⁻¹`` (N, n, 3) of the tool tip's
    translational Jacobian at each row of Q (N, n); λ = `damping` (m)."""
    context = plant.CreateDefaultContext()
    world = plant.world_frame()
    out = np.empty((len(Q), Q.shape[1], 3))
    eye = np.eye(3) * damping**2
    for i, q in enumerate(Q):
        plant.SetPositions(context, arm, q)
        J = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kQDot,
                                                    tip_frame, np.zeros(3), world, world)
        out[i] = J.T @ np.linalg.inv(J @ J.T + eye)
    return out


__all__ = ["ReferenceCorrection", "corrected_reference", "desired_states", "tip_jacobian_pinv"]
