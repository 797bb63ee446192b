"""Joint torques of a whole arm: its rigid-body dynamics, identified, plus joint friction.

The second source paper's "analytical model" part for a user's arm: the arm's URDF/SDF gives
the structure (Drake computes its kinematics; :mod:`ftdrake.physics.arm_dynamics` the
regressor, checked against Drake's inverse dynamics), the data give the numbers::

    τ_j = Y_j(q, q̇, q̈)·φ + fv_j q̇_j + fc_j tanh(q̇_j / v_c) + τ0_j

φ stacks each moving rigid group's 10 inertial parameters (a body and everything welded to
it, about the body's origin, in its frame), fv/fc the viscous (N·m·s/rad) and Coulomb (N·m)
friction, τ0 a constant offset per joint (N·m: a torque sensor's or current loop's zero);
``v_c`` (rad/s) smooths the Coulomb step so the model is continuous at rest.

Identification is weighted least squares over all rows and joints (each joint weighted by the
inverse RMS of its residual from a first pass). Only some combinations of φ — the *base
parameters* — change the torques at all (the first joint's inertia about any axis but its
own, the masses of the wrist seen through the elbow, …); the column-normalised regressor's
singular values give their number, and the directions the data leave undetermined are taken
from the prior (the model file's values) instead of being set to zero:

* ``identification="least_squares"``: ``θ = θ0 + A⁺ (τ − A θ0)`` (the prior θ0 fills only the
  null directions; plain least squares where the data decide);
* ``identification="consistent"`` (default): the same fit constrained to physically possible
  bodies (each group's pseudo-inertia ⪰ 0, so masses > 0 and the triangle inequalities hold)
  and to non-negative friction, with the prior as a weak pull (``prior_weight``, in the metric
  of :mod:`ftdrake.compensation.identification.consistent`), solved as one semidefinite program with
  Drake's ``MathematicalProgram`` and Clarabel (or SCS).

Predictive std: the parameter covariance (weighted residual variance × (AᵀWA)⁺, in the
identified directions) propagated to each torque, plus the per-joint residual variance (so it
is the std of a new measurement; ``std_includes_noise``).
"""

from __future__ import annotations

import functools
import os
import warnings
from numbers import Real
from typing import ClassVar

import numpy as np
from pydrake.solvers import MathematicalProgram, SolverOptions
from sklearn.utils._param_validation import Interval, StrOptions

from ...conventions import GRAVITY_W
from ...errors import ConfigError, RobotModelError, option_name
from ...physics.arm_dynamics import INERTIAL_NAMES, INERTIAL_UNITS, ArmDynamics, ArmModel
from ..identification.consistent_program import IdentificationError, pick_solver, prior_precision
from ..identification.inertial import (
    from_pseudo_inertia,
    is_physically_consistent,
    physical_violations,
    pseudo_inertia,
)
from .base import Compensator
from .robot_file import CarriesRobot

IDENTIFICATIONS = ("least_squares", "consistent")
#: Default weight of the model file's values as a prior (consistent identification): about a
#: ±100 % (1σ) measurement of each body, so that it decides only what the data do not.
DEFAULT_PRIOR_WEIGHT = 1.0
#: Singular values of the column-normalised weighted regressor below this fraction of the
#: largest are directions the data do not determine (not base parameters).
NULL_TOL = 1e-7
#: Alternations between the parameters (gains fixed) and the gains (parameters fixed).
GAIN_ITERATIONS = 4
#: A parameter whose unit vector has a component above this along a null direction of the
#: (column-normalised) regressor is not determined by the data on its own.
IDENTIFIABLE_TOL = 1e-4
#: Drive gains outside [1/PLAUSIBLE_GAIN, PLAUSIBLE_GAIN] are checked against fixed unit
#: gains: when those fit as well, the targets are joint torques and the gains mean nothing
#: (a joint whose rigid-body torque is small trades its gain off against its friction).
PLAUSIBLE_GAIN = 1.5
#: "As well": the fixed-gain fit's residual RMS within this factor of the identified one's.
SAME_FIT = 1.05


class ExcitationWarning(UserWarning):
    """The data determine fewer base parameters than the arm has."""


class DriveGainWarning(ExcitationWarning):
    """Identified drive gains far from 1 that unit gains explain as well (the data do not
    determine them: the targets are joint torques)."""


class ArmDynamicsCompensator(CarriesRobot, Compensator):
    """Predicts an arm's joint torques (N·m; N for prismatic joints) from ``[q, q̇, q̈]``.

    Parameters
    ----------
    robot : the arm's URDF/SDF file or ``package://`` URL (required).
    base_frame : a frame of `robot` welded to the world (None: the model welds itself).
    package_xmls : extra package.xml files for the model's ``package://`` URLs.
    gravity : (3,) in the world frame, m/s².
    identification : "consistent" (default) or "least_squares" (module docstring).
    prior : "model" (the model file's inertial values, default) or None (no prior: the
        unexcited directions get least squares' minimum norm).
    prior_weight : the prior's weight in the consistent fit.
    friction : identify viscous and Coulomb friction per joint.
    coulomb_velocity : v_c of the smoothed Coulomb term, rad/s.
    offsets : identify a constant torque offset per joint.
    drive_gains : "fixed" (the targets are joint torques) or "identify": the targets are
        proportional to the joint torques with an unknown gain and sign per joint (motor
        currents, as UR's CB3 drivers publish in ``effort``, or torques in another sign
        convention); ``target_j = g_j·τ_j`` with ``g_j`` identified (see
        :meth:`_identify`). The gains' common scale is set by the prior's masses.

    Fitted attributes: ``parameters_`` (φ, then fv, fc, τ0 per joint), ``gains_`` (n,),
    ``gain_std_errors_``, ``parameter_names_``,
    ``standard_errors_``, ``model_parameters_`` (the prior), ``base_parameters_`` (how many
    the data determine), ``condition_number_``, ``residual_rms_`` (per joint),
    ``physically_consistent_``.
    """

    provides_std = True
    std_includes_noise = True
    _parameter_constraints: ClassVar[dict] = {
        "features": [StrOptions({"q,qd,qdd"})],  # τ needs q̇ and q̈
        "robot": [str, os.PathLike, None],
        "base_frame": [str, None],
        "package_xmls": ["array-like"],
        "gravity": ["array-like"],
        "identification": [StrOptions(set(IDENTIFICATIONS))],
        "prior": [StrOptions({"model"}), None],
        "prior_weight": [Interval(Real, 0, None, closed="neither")],
        "friction": ["boolean"],
        "coulomb_velocity": [Interval(Real, 0, None, closed="neither")],
        "offsets": ["boolean"],
        "drive_gains": [StrOptions({"fixed", "identify"})],
    }

    def __init__(self, features="q,qd,qdd", robot=None, base_frame=None, package_xmls=(),
                 gravity=GRAVITY_W, identification="consistent", prior="model",
                 prior_weight=DEFAULT_PRIOR_WEIGHT, friction=True, coulomb_velocity=0.02,
                 offsets=True, drive_gains="fixed"):
        super().__init__(features=features)
        self.robot = robot
        self.base_frame = base_frame
        self.package_xmls = package_xmls
        self.gravity = gravity
        self.identification = identification
        self.prior = prior
        self.prior_weight = prior_weight
        self.friction = friction
        self.coulomb_velocity = coulomb_velocity
        self.offsets = offsets
        self.drive_gains = drive_gains

    # -- the regressor ---------------------------------------------------------------------
    def arm_model(self) -> ArmModel:
        """The arm's model description."""
        if self.robot is None:
            raise ConfigError("ArmDynamicsCompensator needs robot= (the arm's URDF/SDF)")
        model, package_xmls = self._robot_source()
        return ArmModel(model, self.base_frame, package_xmls)

    def _build_robot(self) -> None:
        self.dynamics()

    def dynamics(self) -> ArmDynamics:
        """The arm's regressor (built once per model file and gravity)."""
        return _dynamics_for(self.arm_model(), tuple(self.gravity))

    def regressor(self, X) -> np.ndarray:
        """A of shape (N, n, p): ``τ = A·parameters_`` (rigid body, friction, offsets)."""
        X = np.asarray(X, dtype=float)
        n = X.shape[1] // 3
        q, v, vdot = X[:, :n], X[:, n:2 * n], X[:, 2 * n:3 * n]
        blocks = [self.dynamics().regressor(q, v, vdot)]
        eye = np.eye(n)
        if self.friction:
            blocks += [v[:, :, None] * eye,
                       np.tanh(v / float(self.coulomb_velocity))[:, :, None] * eye]
        if self.offsets:
            blocks.append(np.broadcast_to(eye, (len(X), n, n)))
        return np.concatenate(blocks, axis=2)

    # -- fitting ----------------------------------------------------------------------------
    def _fit(self, Z, Y):
        if getattr(self, "temperature_in_", False):
            raise ValueError("ArmDynamicsCompensator takes no temperature column")
        self._embed_robot()
        dyn = self.dynamics()
        if dyn.n != self.n_joints_:
            raise RobotModelError(
                f"the data has {self.n_joints_} joints, the robot model "
                f"{self.arm_model().label} has "
                f"{dyn.n} ({', '.join(dyn.joint_names)})")
        if Y.shape[1] != dyn.n:
            raise ValueError(f"the arm model predicts {dyn.n} joint torques; got {Y.shape[1]} "
                             "targets")
        if len(Z) < 2:
            raise ValueError(f"{len(Z)} row(s): too few to identify the arm's parameters")
        A = self.regressor(Z)
        p_rb = dyn.num_parameters
        self.parameter_names_ = self._names(dyn)
        prior = np.zeros(A.shape[2])
        if self.prior == "model":
            prior[:p_rb] = dyn.model_parameters()
        self.model_parameters_ = prior
        gains = np.ones(dyn.n)
        if self.drive_gains == "identify":
            gains = self._initial_gains(A, Y, prior, p_rb)
            for _ in range(GAIN_ITERATIONS):
                theta = self._identify(A, Y / gains, prior, dyn)
                gains = _gains_given(A @ theta, Y)
        theta = self._identify(A, Y / gains, prior, dyn)
        self.gains_ = gains
        tau = A @ theta
        self.gain_std_errors_ = np.zeros(dyn.n)
        if self.drive_gains == "identify":
            resid = Y - tau * gains
            self.gain_std_errors_ = (np.sqrt(np.mean(resid ** 2, axis=0))
                                     / np.sqrt(np.maximum(np.sum(tau ** 2, axis=0), 1e-300)))
        self.residual_rms_ = np.sqrt(np.mean((Y - tau * gains) ** 2, axis=0))
        self.physically_consistent_ = all(
            is_physically_consistent(theta[10 * k:10 * k + 10], tol=1e-7)
            for k in range(len(dyn.bodies)))
        if self.drive_gains == "identify":
            self._check_gains(A, Y, prior, dyn)
        if self.base_parameters_ < _expected_base(dyn, A.shape[2] - p_rb):
            warnings.warn(
                f"the data determine {self.base_parameters_} of the arm's parameter "
                f"combinations (condition number {self.condition_number_:.3g}); the rest come "
                f"from {'the model file (prior)' if self.prior else 'the minimum norm'}. "
                "Excite every joint (speed and acceleration) for more", ExcitationWarning,
                stacklevel=3)

    def _identify(self, A, Y, prior, dyn):
        """θ from the (N, n, p) regressor and torques Y; sets the base-parameter count, the
        condition number and the covariance factor."""
        weights = _joint_weights(A, Y)
        Aw = (A * weights[None, :, None]).reshape(-1, A.shape[2])
        yw = (Y * weights).reshape(-1)
        scale = np.linalg.norm(Aw, axis=0)
        # Columns the data never move (or only at round-off) are null directions; scaling
        # them up by 1/round-off would only amplify noise in the program's matrices.
        scale[scale <= 1e-10 * scale.max()] = 1.0
        U, s, Vt = np.linalg.svd(Aw / scale, full_matrices=False)
        keep = s > NULL_TOL * s[0]
        self.base_parameters_ = int(keep.sum())
        self.condition_number_ = float(s[0] / s[keep][-1])
        # A parameter the data determine on its own lies in the regressor's row space: its
        # unit vector has no component along a null direction. With one it is determined
        # only in a combination with others (or not at all: component 1).
        self.null_component_ = np.linalg.norm(Vt[~keep], axis=0)
        self.identifiable_ = self.null_component_ < IDENTIFIABLE_TOL
        self._null_directions = Vt[~keep]
        if self.identification == "least_squares":
            x0 = prior * scale
            x = x0 + (Vt[keep].T / s[keep]) @ (U[:, keep].T @ (yw - (Aw / scale) @ x0))
            theta = x / scale
        else:
            theta = self._consistent(Aw / scale, yw, scale, prior, dyn)
        residual = yw - Aw @ theta
        dof = max(1, len(yw) - self.base_parameters_)
        sigma2 = residual @ residual / dof
        # Covariance in the identified directions only (the others are the prior's): Σ = F Fᵀ.
        self.covariance_factor_ = (Vt[keep].T / s[keep]) / scale[:, None] * np.sqrt(sigma2)
        # ∞ for a parameter the data do not determine alone: the identified directions' part
        # of its error is only the part the data see (it would print as ± 0.000).
        self.standard_errors_ = np.where(
            self.identifiable_, np.sqrt(np.sum(self.covariance_factor_ ** 2, axis=1)), np.inf)
        self.parameters_ = theta
        return theta

    def _check_gains(self, A, Y, prior, dyn):
        """Warns when identified gains are far from 1 although unit gains fit as well: the
        targets are then joint torques (an arm that measures them has no drive gain), and a
        gain of 0.05 only trades off against a joint's friction and offset."""
        far = np.flatnonzero((np.abs(self.gains_) > PLAUSIBLE_GAIN)
                             | (np.abs(self.gains_) < 1.0 / PLAUSIBLE_GAIN))
        if not len(far):
            return
        fitted = {k: v for k, v in vars(self).items() if k.endswith("_")}
        fitted["_null_directions"] = self._null_directions
        try:
            unit_rms = np.sqrt(np.mean((Y - A @ self._identify(A, Y, prior, dyn)) ** 2,
                                       axis=0))
        finally:
            vars(self).update(fitted)  # the identified-gain fit stays the model
        if np.all(unit_rms[far] <= SAME_FIT * self.residual_rms_[far] + 1e-12):
            self.gain_warning_ = (
                "implausible drive gains " + ", ".join(
                    f"{self.gains_[j]:.3g} ({dyn.joint_names[j]})" for j in far)
                + ": with every gain fixed at 1 the torques fit as well (residual RMS "
                + ", ".join(f"{unit_rms[j]:.3g}" for j in far) + " against "
                + ", ".join(f"{self.residual_rms_[j]:.3g}" for j in far)
                + " N·m), so the targets are joint torques: an arm that measures joint torque "
                "has no drive gain to identify (a gain that far from 1 only trades off "
                f"against the joint's friction and offset). Drop {option_name('drive_gains')} "
                "identify")
            warnings.warn(self.gain_warning_, DriveGainWarning, stacklevel=4)

    def _initial_gains(self, A, Y, prior, p_rb):
        """Each joint's gain by least squares of its target on the prior's rigid-body torque,
        with friction and offset columns free. Its sign comes from friction when there is
        friction: a drive always pushes along its velocity against friction (fv, fc ≥ 0), the
        most robust sign in any log with motion; the rigid-body torque of a wrist joint can be
        too small to tell."""
        tau_prior = A[:, :, :p_rb] @ prior[:p_rb]
        gains = np.ones(Y.shape[1])
        for j in range(Y.shape[1]):
            M = np.column_stack([tau_prior[:, j], A[:, j, p_rb:]])
            coef = np.linalg.lstsq(M, Y[:, j], rcond=None)[0]
            magnitude = abs(coef[0]) if abs(coef[0]) > 1e-6 else 1.0
            sign = np.sign(coef[0]) or 1.0
            if self.friction:
                n = Y.shape[1]
                friction = (A[:, j, p_rb:p_rb + 2 * n] @ coef[1:1 + 2 * n])
                drive = np.sum(friction * A[:, j, p_rb + j])  # against q̇_j
                sign = np.sign(drive) or sign
            gains[j] = sign * magnitude
        return gains

    def _consistent(self, B, y, scale, prior, dyn):
        """The weighted fit over physical bodies and non-negative friction, in x = scale·θ."""
        p = B.shape[1]
        nb = len(dyn.bodies)
        Q, R = np.linalg.qr(B)
        rows, rhs = [R], [Q.T @ y]
        if self.prior == "model":
            for k in range(nb):
                phi0 = prior[10 * k:10 * k + 10]
                if phi0[0] <= 0:
                    continue  # a massless group in the file: no prior for it
                P = prior_precision(phi0, float(self.prior_weight), False)
                L = np.linalg.cholesky(P).T / scale[10 * k:10 * k + 10]  # on x
                block = np.zeros((10, p))
                block[:, 10 * k:10 * k + 10] = L
                rows.append(block)
                rhs.append(L @ (phi0 * scale[10 * k:10 * k + 10]))
        # A whisper of ridge fixes whatever neither the data nor a prior decide.
        rows.append(1e-9 * np.linalg.norm(R) * np.eye(p))
        rhs.append(np.zeros(p))
        prog = MathematicalProgram()
        x = prog.NewContinuousVariables(p, "x")
        for k in range(nb):
            m_ref = max(prior[10 * k], 0.1)
            D = np.diag([10.0, 10.0, 10.0, 1.0]) / np.sqrt(m_ref)  # lengths of ~0.1 m
            F = [np.zeros((4, 4))]
            for a in range(10):
                e = np.zeros(10)
                e[a] = 1.0 / scale[10 * k + a]
                F.append(D @ pseudo_inertia(e) @ D)
            prog.AddLinearMatrixInequalityConstraint(F, x[10 * k:10 * k + 10])
        if self.friction:
            n = dyn.n
            prog.AddBoundingBoxConstraint(0.0, np.inf, x[10 * nb:10 * nb + 2 * n])
        prog.AddL2NormCostUsingConicConstraint(np.vstack(rows), -np.concatenate(rhs), x)
        solver, name = pick_solver(None)
        result = solver.Solve(prog, None, SolverOptions())
        if not result.is_success():
            raise IdentificationError(
                f"the arm's physically consistent identification did not solve: {name} "
                f"returned {result.get_solution_result().name}; try "
                "identification='least_squares' or check the data for outliers")
        self.solver_ = name
        return _onto_bodies(result.GetSolution(x) / scale, prior, nb)

    # -- prediction -------------------------------------------------------------------------
    def _predict(self, Z):
        return (self.regressor(Z) @ self.parameters_) * self._gains()

    def _gains(self):
        return getattr(self, "gains_", np.ones(self.n_outputs_))

    def _variance(self, Z, include_noise):
        A = self.regressor(Z)
        var = np.sum((A @ self.covariance_factor_) ** 2, axis=2) * self._gains() ** 2
        return var + self.residual_rms_ ** 2 if include_noise else var

    def _predict_std(self, Z):
        return np.sqrt(self._variance(Z, include_noise=True))

    def row_predictor(self, include_noise: bool = True):
        """``row → (mean, std)`` through the regressor (Drake's kinematics per row: about
        a tenth of a millisecond per body; for logs and offline use, not a 1 kHz loop)."""
        def predict(row):
            Z = row[None, :3 * self.n_joints_]
            var = self._variance(Z, include_noise)[0]
            return self._predict(Z)[0], np.sqrt(var)
        return predict

    # -- reporting --------------------------------------------------------------------------
    def identified(self) -> dict:
        """Every parameter with its standard error, model-file value and unit."""
        units = self._units()
        return {name: {"value": float(v), "std_error": float(se), "model": float(m),
                       "unit": u}
                for name, v, se, m, u in zip(self.parameter_names_, self.parameters_,
                                             self.standard_errors_, self.model_parameters_,
                                             units, strict=True)}

    def summary(self) -> str:
        """Masses, friction and offsets per joint, and what the data determined, in words.

        A parameter the data do not determine on its own (:attr:`identifiable_` False) is
        printed as such, with where its value comes from, never with a standard error; the
        physical-consistency verdict is one line, naming each violation once.
        """
        dyn = self.dynamics()
        how = {"consistent": "least squares constrained to bodies that exist (SDP)",
               "least_squares": "weighted least squares"}[self.identification]
        lines = [(f"arm model {self.arm_model().label}: {len(dyn.bodies)} moving bodies, "
                  f"{dyn.n} joints; {how}; the data determine {self.base_parameters_} of "
                  f"{len(self.parameters_)} parameter combinations (condition number "
                  f"{self.condition_number_:.3g})")]
        identifiable = self._identifiable()
        source = self._undetermined_source()
        for k, body in enumerate(dyn.bodies):
            phi = self.parameters_[10 * k:10 * k + 10]
            m = phi[0]
            com = phi[1:4] / m if abs(m) > 1e-9 else np.full(3, np.nan)
            lines.append(f"  {body.name()}: m = {m:.3f} "
                         f"{self._how_known(10 * k, identifiable, 'kg', '.3f')} "
                         f"(file {self.model_parameters_[10 * k]:.3f}), c = "
                         f"({', '.join(f'{1e3 * c:.1f}' for c in com)}) mm")
        p_rb = 10 * len(dyn.bodies)
        for i, name in enumerate(self.parameter_names_[p_rb:], start=p_rb):
            lines.append(f"  {name} = {self.parameters_[i]:.4g} "
                         f"{self._how_known(i, identifiable, '', '.2g')}")
        if self.drive_gains == "identify":
            lines.append("  drive gains (target per N·m): " + ", ".join(
                f"{g:.4g} ± {e:.2g}" for g, e in zip(self.gains_, self.gain_std_errors_,
                                                    strict=True)))
            if getattr(self, "gain_warning_", None):
                lines.append(f"  warning: {self.gain_warning_}")
        lines.append("  " + self._verdict(dyn))
        lines.append("  residual RMS per joint: "
                     + ", ".join(f"{r:.3g}" for r in self.residual_rms_))
        undetermined = int(np.sum(~identifiable))
        if undetermined:
            lines.append(f"  {undetermined} of {len(identifiable)} parameters are not "
                         f"identifiable from this data on their own ({source}); the data "
                         "determine only their combinations (base parameters)")
        return "\n".join(lines)

    def _identifiable(self) -> np.ndarray:
        # Models saved before identifiability was recorded: every finite error counts.
        return getattr(self, "identifiable_", np.isfinite(self.standard_errors_)
                       & (self.standard_errors_ > 0))

    def _undetermined_source(self) -> str:
        if self.identification == "consistent" and self.prior == "model":
            return "their values: the prior (model file) and the physical constraints"
        if self.prior == "model":
            return "kept at the model file's values where the data are silent"
        return "least squares' minimum norm where the data are silent"

    def _how_known(self, i, identifiable, unit, fmt) -> str:
        if identifiable[i]:
            return f"± {format(self.standard_errors_[i], fmt)}{' ' + unit if unit else ''}"
        null = getattr(self, "null_component_", np.ones(len(identifiable)))[i]
        if null > 0.999:
            return "(not identifiable from this data)"
        return ("(not identifiable from this data on its own: only in a combination with "
                f"{', '.join(self._partners(i))})")

    def _partners(self, i, count=3) -> list[str]:
        """The parameters whose values trade off against parameter i along the data's null
        directions (the largest components of the null projection of its unit vector)."""
        null = getattr(self, "_null_directions", None)
        if null is None or not len(null):
            return ["others"]
        along = null.T @ null[:, i]
        along[i] = 0.0
        order = np.argsort(-np.abs(along))[:count]
        return [self.parameter_names_[j] for j in order if abs(along[j]) > IDENTIFIABLE_TOL]

    def _verdict(self, dyn) -> str:
        """One line: whether every body is physically possible, each violation named once."""
        problems = []
        for k, body in enumerate(dyn.bodies):
            for problem in physical_violations(self.parameters_[10 * k:10 * k + 10], tol=1e-7):
                problems.append(f"{body.name()}: {problem}")
        if not problems:
            return "every body physically possible: yes"
        hint = ("" if self.identification == "consistent" else
                " (identification='consistent', the default, constrains them)")
        return "physically possible bodies: NO — " + "; ".join(problems) + hint

    def _names(self, dyn):
        names = list(dyn.parameter_names())
        for kind, on in (("fv", self.friction), ("fc", self.friction),
                         ("tau0", self.offsets)):
            if on:
                names += [f"{kind}_{j}" for j in dyn.joint_names]
        return names

    def _units(self):
        units = []
        for name in self.parameter_names_:
            head = name.split("_", 1)[0]
            if head in INERTIAL_NAMES:
                units.append(INERTIAL_UNITS[INERTIAL_NAMES.index(head)])
            else:
                units.append({"fv": "N*m*s/rad", "fc": "N*m", "tau0": "N*m"}[head])
        return units


@functools.lru_cache(maxsize=8)
def _dynamics_for(model: ArmModel, gravity: tuple) -> ArmDynamics:
    return ArmDynamics(model.build_plant(), gravity)


def _onto_bodies(theta, prior, nb):
    """Removes the solver's last rounding (~1e-8) across J ⪰ 0: each group's negative
    eigenvalues of its scaled pseudo-inertia (the program's scaling) clipped to 0, so that
    a consistent fit passes :func:`is_physically_consistent` and says so."""
    theta = theta.copy()
    for k in range(nb):
        D = np.diag([10.0, 10.0, 10.0, 1.0]) / np.sqrt(max(prior[10 * k], 0.1))
        lam, V = np.linalg.eigh(D @ pseudo_inertia(theta[10 * k:10 * k + 10]) @ D)
        if lam[0] < 0:
            Dinv = np.linalg.inv(D)
            J = Dinv @ ((V * np.maximum(lam, 0.0)) @ V.T) @ Dinv
            theta[10 * k:10 * k + 10] = from_pseudo_inertia(0.5 * (J + J.T))
    return theta


def _gains_given(tau, Y):
    """Each joint's gain, target ≈ g·τ, by least squares through the origin."""
    num, den = np.sum(Y * tau, axis=0), np.sum(tau * tau, axis=0)
    return np.where(den > 0, num / np.maximum(den, 1e-300), 1.0)


def _joint_weights(A, Y):
    """1 / RMS of each joint's residual after an unweighted first pass (joints' torques
    differ by an order of magnitude; each counts by its own noise)."""
    theta = np.linalg.lstsq(A.reshape(-1, A.shape[2]), Y.reshape(-1), rcond=None)[0]
    rms = np.sqrt(np.mean((Y - A @ theta) ** 2, axis=0))
    return 1.0 / np.maximum(rms, 1e-9 * (1.0 + np.abs(Y).max()))


def _expected_base(dyn: ArmDynamics, extra: int) -> int:
    """How many parameter combinations rich data determine: the base parameters of the
    rigid bodies on random states, plus friction and offsets."""
    return _base_count(id(dyn), dyn) + extra


@functools.lru_cache(maxsize=8)
def _base_count(_key, dyn: ArmDynamics) -> int:
    rng = np.random.default_rng(0)
    n = dyn.n
    q, v, vd = (rng.uniform(-np.pi, np.pi, (40 * n, n)) for _ in range(3))
    A = dyn.regressor(q, v, vd).reshape(-1, dyn.num_parameters)
    scale = np.linalg.norm(A, axis=0)
    scale[scale <= 1e-10 * scale.max()] = 1.0
    s = np.linalg.svd(A / scale, compute_uv=False)
    return int(np.sum(s > NULL_TOL * s[0]))
