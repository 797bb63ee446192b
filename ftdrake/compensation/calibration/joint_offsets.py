"""Joint zero offsets identified from the wrench, jointly with the payload.

An encoder whose zero is off by δ_j reports ``q_measured = q_true − δ_j``: the sensor turns
with the true angles, so the gravity (and, in motion, the accelerations) it feels are those of
``q_measured + δ``. The reading of the payload model
(:mod:`ftdrake.compensation.estimators.physics`) is then

    reading = R_SmS · A(q_measured + δ, q̇, q̈) φ + b

with A the Newton–Euler regressor, φ the tool's inertial parameters (mass and first moment;
the inertia too with ``mode="dynamic"``), b the biases and R_SmS the rotation of the frame the
sensor measures in (its mounting, always identified here: the last joint's offset and a
mounting rotation about its axis are the same thing). The model is nonlinear in δ and the
mounting rotation and linear in φ and b: :func:`identify_joint_offsets` solves for δ and the
rotation by Gauss–Newton (``scipy.optimize.least_squares``) with φ and b eliminated by linear
least squares at each step (variable projection). Forces and torques are weighted by the
inverse RMS of their residual without offsets, one weight per 3-axis block (so a rotation of
the readings does not change the cost).

**Which offsets the data determine.** Before fitting, each joint's column of the Jacobian
(the reading's change per radian of its offset, rows weighted) is compared with the others
(:mod:`ftdrake.compensation.identification.joint_identifiability`). A joint is *not identifiable* —
reported with the reason and given no number — when

* its column is zero: a prismatic joint (it moves S without turning it), a joint not between
  the world and S, or a revolute joint whose axis stays along gravity in every row (the usual
  vertical first axis: turning about it turns nothing the sensor feels);
* its column lies in the span of the payload's, the biases' and the mounting rotation's: the
  last joint before S (its offset is a mounting rotation about its axis, with the centre of
  mass re-expressed);
* its column and other joints' columns are dependent (after the payload's): only a combination
  of their offsets is determined.

An identifiable joint's offset is *confounded with a gravity sag* when its column and the
column of a compliance (``q_link = q_motor − τ_j/k_j``, τ_j the torque that holds the arm
against gravity at that joint, from the robot model's link masses) correlate by at least
:data:`SAG_CORRELATION` after the payload's columns: typically when τ_j keeps its sign over the
data, so that an offset and a stiffness fit equally. Its number is then offset plus mean sag.

**Standard errors** are those of the full nonlinear problem at the solution (offsets, mounting
rotation, payload and biases together, so their correlation is accounted for), widened for a
residual correlated over rows as the payload fit's are
(:func:`~ftdrake.compensation.identification.regression.correlated_variance_ratio`).

**Which offsets to keep** (``include="auto"``): as ``calibrate --correction auto`` chooses its
correction, by held-out error. The offsets of all identifiable joints are fitted, ranked by
|δ|/σ, and nested sets (none, the first, the first two, …) are compared by
:data:`HELD_OUT_FOLDS`-fold cross-validation over blocks of consecutive rows (so that
neighbouring rows of a time series do not leak into the held-out block); a richer set is
chosen only when its error (geometric mean over the axes of the per-axis MSE) is below
:data:`HELD_OUT_GAIN` × the simpler choice's.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ...conventions import WRENCH_AXES
from ...errors import ConfigError
from ...physics.robot import movable_joint_names
from ..estimators.physics import PhysicsPayloadCompensator
from ..identification.joint_identifiability import (
    Identifiability,
    analyse,
    gravity_plant,
    least_squares_solution,
)
from ..identification.payload_identification import BIASES, full_layout
from ..identification.regression import correlated_variance_ratio

__all__ = ["HELD_OUT_FOLDS", "HELD_OUT_GAIN", "INCLUDE", "JointOffsets",
           "identify_joint_offsets", "kinematics_budget"]

#: Folds of the cross-validation that chooses the offsets (blocks of consecutive rows).
HELD_OUT_FOLDS = 5
#: A richer set of offsets is kept only when its held-out error is below this fraction of the
#: simpler set's (geometric mean over the axes of the per-axis MSE).
HELD_OUT_GAIN = 0.95
#: How the offsets to fit are chosen: by held-out error, every identifiable joint's, or none
#: (the payload, biases and mounting alone: the comparison).
INCLUDE = ("auto", "all", "none")
#: Rows at most the budget's kinematics line identifies the offsets on (every k-th row).
BUDGET_ROWS = 1000
#: Step (rad) of the central differences of the readings in an offset or rotation angle.
STEP = 1e-6


@dc.dataclass
class JointOffsets:
    """Joint zero offsets identified from the wrench (module docstring).

    Convention: ``q_true = q_measured + offset`` (an encoder reading ``q_true − offset``);
    angles in degrees (rad for :meth:`corrected`'s rows; a prismatic joint is never given
    one). ``offsets_deg``/``std_errors_deg``: the joints the final fit holds (``included``),
    by name. ``identifiability``: per joint, whether the data determine its offset and why
    not (:class:`~ftdrake.compensation.identification.joint_identifiability.Identifiability`).
    ``parameters``: the payload's (φ, in S, as the payload model's θ[:10]) and biases (in Sm, N and
    N·m) of the final fit; ``mounting_rotvec_deg``: the rotation vector of R_SSm (deg).
    ``residual_rms``: per axis, with the offsets; ``residual_rms_without``: the same fit without
    offsets. ``choice``: the held-out comparison (``include="auto"``) or None.
    ``candidate_offsets_deg`` and ``candidate_std_errors_deg``: every identifiable joint's offset,
    fitted together.
    """

    joints: tuple[str, ...]
    offsets_deg: dict
    std_errors_deg: dict
    included: tuple[str, ...]
    identifiability: Identifiability
    parameters: np.ndarray
    mounting_rotvec_deg: np.ndarray
    residual_rms: np.ndarray
    residual_rms_without: np.ndarray
    candidate_offsets_deg: dict
    candidate_std_errors_deg: dict
    standard_error_factor: float
    rows: int
    choice: dict | None = None

    @property
    def unidentifiable(self) -> dict:
        """{joint: why its offset cannot be told from the data}."""
        return dict(self.identifiability.unidentifiable)

    @property
    def confounded_with_sag(self) -> dict:
        """{joint: why its offset and a gravity sag fit alike}."""
        return dict(self.identifiability.sag)

    def offsets_rad(self) -> np.ndarray:
        """(n,) the offsets in the rows' joint order, rad (0 where none is held)."""
        out = np.zeros(len(self.joints))
        for name, value in self.offsets_deg.items():
            out[self.joints.index(name)] = np.radians(value)
        return out

    def corrected(self, X) -> np.ndarray:
        """Rows [q, …] with the offsets added to q (``q_measured + offset``), a copy."""
        X = np.array(X, dtype=float)
        X[:, :len(self.joints)] += self.offsets_rad()
        return X

    def to_dict(self) -> dict:
        """A plain mapping (what ``calibrate --joint-offsets`` writes)."""
        out = {
            "convention": "q_true = q_measured + offset (deg)",
            "offsets_deg": {k: {"value": float(v), "std_error": float(self.std_errors_deg[k])}
                            for k, v in self.offsets_deg.items()},
            "not_identifiable": dict(self.unidentifiable) or "none",
            "offset_or_gravity_sag": dict(self.confounded_with_sag) or "none",
            "fitted_together": {k: {"value": float(v),
                                    "std_error": float(self.candidate_std_errors_deg[k])}
                                for k, v in self.candidate_offsets_deg.items()},
            "mounting_rotvec_deg": self.mounting_rotvec_deg.tolist(),
            "residual_rms": dict(zip(WRENCH_AXES, self.residual_rms.tolist(), strict=True)),
            "residual_rms_without_offsets": dict(zip(
                WRENCH_AXES, self.residual_rms_without.tolist(), strict=True)),
            "standard_error_factor_for_correlated_rows": float(self.standard_error_factor),
            "rows": int(self.rows),
        }
        if self.choice is not None:
            out["choice"] = self.choice
        return out

    def summary(self) -> str:
        """The offsets and what the data do not determine, as lines a user reads."""
        lines = [(f"joint zero offsets from the wrench ({self.rows} rows; q_true = "
                  "q_measured + offset):")]
        for name in self.joints:
            if name in self.offsets_deg:
                line = (f"  {name}: {self.offsets_deg[name]:+.4f} ± "
                        f"{self.std_errors_deg[name]:.4f} deg")
                if name in self.confounded_with_sag:
                    line += f"  (or a gravity sag: {self.confounded_with_sag[name]})"
                lines.append(line)
            elif name in self.unidentifiable:
                lines.append(f"  {name}: not identifiable: {self.unidentifiable[name]}")
            elif name in self.candidate_offsets_deg:
                lines.append(f"  {name}: not kept ({self.candidate_offsets_deg[name]:+.4f} ± "
                             f"{self.candidate_std_errors_deg[name]:.4f} deg when fitted; "
                             "it does not lower the held-out error)")
        if self.choice is not None:
            lines.append(f"  chosen by held-out error: {self.choice['why']}")
            for label, rms in self.choice["cv_rms"].items():
                lines.append(f"    held-out RMS (Fx..Tz), {label}: "
                             + ", ".join(f"{r:.3g}" for r in rms))
        lines.append("  residual RMS (Fx..Tz): " + ", ".join(
            f"{r:.3g}" for r in self.residual_rms) + "; without offsets: " + ", ".join(
            f"{r:.3g}" for r in self.residual_rms_without))
        return "\n".join(lines)


def identify_joint_offsets(X, Y, model=None, *, include="auto",
                           folds: int = HELD_OUT_FOLDS) -> JointOffsets:
    """Joint zero offsets of the rows X from the readings Y, with the payload (module
    docstring).

    `X`: (N, n) joint positions (rad; m for a prismatic joint) or (N, 3n) ``[q, q̇, q̈]``
    rows in the robot's joint order; `Y`: (N, 6) readings ``[Fx Fy Fz Tx Ty Tz]`` (N, N·m,
    in the sensor's measuring frame). `model`: a
    :class:`~ftdrake.compensation.estimators.physics.PhysicsPayloadCompensator` (fitted or not)
    whose robot, sensor frame, joints, gravity and mode (``"static"``: gravity only; ``"dynamic"``:
    needs the ``[q, q̇, q̈]`` rows) are used; None: ftdrake's arm, static. `include`: ``"auto"``
    (chosen by held-out error), ``"all"`` (every identifiable joint) or ``"none"``. Raises
    ConfigError on a bad `include` or rows that do not fit the robot.
    """
    if include not in INCLUDE:
        raise ConfigError(f"include must be one of {list(INCLUDE)}, got {include!r}")
    # Hundreds of small products (rows × p): a BLAS thread pool costs more than it gains.
    with threadpool_limits(limits=1):
        return _identify(X, Y, model, include, folds)


def _identify(X, Y, model, include, folds) -> JointOffsets:
    problem = OffsetProblem.build(X, Y, model)
    base = problem.fit(())
    status = analyse(problem, base)
    candidates = status.identifiable
    fitted = problem.fit(candidates) if candidates else base
    cand_se = problem.standard_errors(fitted, candidates)[0] if candidates else np.zeros(0)
    choice = None
    if include == "none" or not candidates:
        chosen = ()
    elif include == "all":
        chosen = candidates
    else:
        chosen, choice = choose_offsets(problem, candidates, fitted.delta[list(candidates)],
                                        cand_se, folds)
    final = problem.fit(chosen) if chosen != candidates else fitted
    se, factor = problem.standard_errors(final, chosen)
    names = problem.names
    return JointOffsets(
        joints=tuple(names),
        offsets_deg={names[j]: float(np.degrees(final.delta[j])) for j in chosen},
        std_errors_deg={names[j]: float(np.degrees(s)) for j, s in zip(chosen, se,
                                                                        strict=True)},
        included=tuple(names[j] for j in chosen), identifiability=status,
        parameters=np.concatenate([_full_phi(final.theta, problem.phys), final.theta[-6:]]),
        mounting_rotvec_deg=np.degrees(final.rotvec),
        residual_rms=problem.residual_rms(final), residual_rms_without=problem.residual_rms(base),
        candidate_offsets_deg={names[j]: float(np.degrees(fitted.delta[j])) for j in candidates},
        candidate_std_errors_deg={names[j]: float(np.degrees(s))
                                  for j, s in zip(candidates, cand_se, strict=True)},
        standard_error_factor=factor, rows=len(problem.Y), choice=choice)


def kinematics_budget(model, X, Y) -> dict | None:
    """``replay --budget``'s "kinematics" line: per axis, the share of the in-motion mean
    square of the payload model's residual (its physics part refitted on these rows) that
    joint zero offsets remove, the offsets kept by held-out error (``include="auto"``) with
    their standard errors, and the joints the rows cannot determine. `X`: the model's rows
    ``[q, q̇, q̈]`` (and the temperature, whose fitted drift is taken off `Y` first) in
    motion; `Y` the readings there. At most :data:`BUDGET_ROWS` rows are used (every k-th).
    None for a model without a physics part."""
    physics = getattr(model, "physics_", model)
    if not isinstance(physics, PhysicsPayloadCompensator):
        return None
    X, Y = np.asarray(X, float), np.asarray(Y, float)
    if getattr(physics, "temperature_in_", False):
        if getattr(physics, "temperature_reference_", None) is not None:
            Y = Y - np.outer(X[:, -1] - physics.temperature_reference_,
                             physics.temperature_coefficients_)
        X = X[:, :-1]
    step = max(1, len(X) // BUDGET_ROWS)
    result = identify_joint_offsets(X[::step], Y[::step], physics)
    share = 1.0 - result.residual_rms ** 2 / np.maximum(result.residual_rms_without ** 2,
                                                        1e-300)
    return {"share": dict(zip(WRENCH_AXES, np.round(share, 3).tolist(), strict=True)),
            "offsets_deg": {k: round(v, 4) for k, v in result.offsets_deg.items()},
            "std_errors_deg": {k: round(v, 4) for k, v in result.std_errors_deg.items()},
            "not_identifiable": sorted(result.unidentifiable),
            "meaning": ("share of the in-motion mean square of the payload model's residual "
                        "(refitted on these rows) that joint zero offsets remove")}


def _full_phi(theta, phys) -> np.ndarray:
    """The 10 inertial parameters (zeros where the mode identifies none) from θ's physical
    part."""
    phi = np.zeros(10)
    phi[[c for c in phys if c < 10]] = theta[:len([c for c in phys if c < 10])]
    return phi


def choose_offsets(problem, candidates, delta, std_errors, folds):
    """(the joints to keep, the comparison): nested sets of `candidates` ranked by |δ|/σ,
    compared by cross-validation over blocks of consecutive rows (module docstring)."""
    order = [candidates[i] for i in np.argsort(-np.abs(delta) / np.maximum(std_errors, 1e-300),
                                               kind="stable")]
    sets = [tuple(sorted(order[:k])) for k in range(len(order) + 1)]
    block = np.minimum(np.arange(len(problem.Y)) * folds // len(problem.Y), folds - 1)
    rms, score = {}, {}
    for joints in sets:
        error = np.empty_like(problem.Y)
        for k in range(folds):
            train = block != k
            fit = problem.fit(joints, rows=train)
            error[~train] = problem.Y[~train] - problem.predict(fit, rows=~train)
        label = _label(problem, joints)
        rms[label] = np.sqrt(np.mean(error ** 2, axis=0))
        score[label] = float(np.exp(np.mean(np.log(np.maximum(rms[label], 1e-300) ** 2))))
    chosen = ()
    for joints in sets[1:]:
        if score[_label(problem, joints)] < HELD_OUT_GAIN * score[_label(problem, chosen)]:
            chosen = joints
    why = (f"{_label(problem, chosen)} has the lowest held-out error ({folds} blocks of "
           "consecutive rows)" if chosen else "no offset lowers the held-out error by "
           f"{100 * (1 - HELD_OUT_GAIN):.0f} %")
    return chosen, {"cv_rms": {k: v.tolist() for k, v in rms.items()},
                    "choice": _label(problem, chosen), "why": why}


def _label(problem, joints) -> str:
    return "+".join(problem.names[j] for j in joints) if joints else "none"


@dc.dataclass
class OffsetFit:
    """One fit: offsets per row column (rad, 0 where not fitted), mounting rotation vector
    (rad), θ = [physical parameters in `phys` order, biases in S] and the rows it used."""

    delta: np.ndarray
    rotvec: np.ndarray
    theta: np.ndarray
    rows: np.ndarray


@dc.dataclass
class OffsetProblem:
    """The rows, readings and robot of an offset identification (module docstring)."""

    X: np.ndarray  # (N, 3n) full layout
    Y: np.ndarray  # (N, 6)
    model: object  # the payload model: its regressor
    names: list  # per row column
    phys: list  # the regressor's physical columns the mode identifies
    weights: np.ndarray  # (6,): force and torque block weights

    @classmethod
    def build(cls, X, Y, model) -> OffsetProblem:
        model = PhysicsPayloadCompensator(features="q", mode="static") if model is None \
            else model
        kinematics = model._kinematics()
        n = kinematics.num_joints
        X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
        if X.ndim != 2 or X.shape[1] not in (n, 3 * n) or Y.shape != (len(X), 6):
            raise ConfigError(f"rows must be (N, {n}) joint positions or (N, {3 * n}) "
                              f"[q, q̇, q̈] for this robot ({n} joints) with (N, 6) readings; "
                              f"got X {X.shape}, Y {Y.shape}")
        if model.mode == "dynamic" and X.shape[1] != 3 * n:
            raise ConfigError("a dynamic payload model needs [q, q̇, q̈] rows")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
            raise ConfigError("the rows or readings hold NaN or inf: drop those rows first")
        phys = [0, 1, 2, 3] if model.mode == "static" else list(range(10))
        if getattr(model, "weight_without_inertia", False):
            phys += [16, 17, 18, 19]
        problem = cls(full_layout(X, n) if X.shape[1] == n else X, Y, model,
                      joint_labels(kinematics.chain, model), phys, np.ones(6))
        first = problem.fit((), iterate=False)
        r = problem.residual(first)
        rms = [np.sqrt(np.mean(r[:, s] ** 2)) for s in (slice(0, 3), slice(3, 6))]
        floor = 1e-9 * (1 + np.abs(Y).max())
        problem.weights = np.repeat(1.0 / np.maximum(rms, floor), 3)
        return problem

    # -- the model ------------------------------------------------------------------------
    def regressor(self, delta, rows=slice(None)) -> np.ndarray:
        """(N, 6, p) the physical columns at ``q + delta`` and the 6 bias columns."""
        X = self.X[rows].copy()
        X[:, :len(delta)] += delta
        A = self.model.regressor(X)
        return np.concatenate([A[:, :, self.phys], A[:, :, BIASES]], axis=2)

    def readings_in_S(self, rotvec, rows=slice(None)) -> np.ndarray:
        """The readings rotated from Sm into S (block-wise by R_SSm)."""
        return self.Y[rows] @ _block(rotvec).T

    def predict(self, fit: OffsetFit, rows=slice(None)) -> np.ndarray:
        """(N, 6) the readings the fit predicts, in Sm."""
        return (self.regressor(fit.delta, rows) @ fit.theta) @ _block(fit.rotvec)

    def residual(self, fit: OffsetFit, rows=None) -> np.ndarray:
        """(N, 6) readings − prediction on the fit's rows (in Sm, unweighted)."""
        rows = fit.rows if rows is None else rows
        return self.Y[rows] - self.predict(fit, rows)

    def residual_rms(self, fit: OffsetFit) -> np.ndarray:
        return np.sqrt(np.mean(self.residual(fit) ** 2, axis=0))

    def _linear(self, delta, rotvec, rows):
        """(θ, weighted residual (N, 6)) of the linear fit at these offsets and rotation."""
        A = self.regressor(delta, rows) * self.weights[None, :, None]
        y = self.readings_in_S(rotvec, rows) * self.weights
        theta = least_squares_solution(A.reshape(-1, A.shape[-1]), y.reshape(-1))
        return theta, y - A @ theta

    def fit(self, joints, rows=None, iterate: bool = True) -> OffsetFit:
        """Offsets of the row columns `joints` (indices), the mounting rotation, payload and
        biases, by variable projection on `rows` (bool mask; all by default)."""
        rows = np.ones(len(self.Y), bool) if rows is None else rows
        joints = list(joints)
        n = self.X.shape[1] // 3

        def unpack(x):
            delta = np.zeros(n)
            delta[joints] = x[:len(joints)]
            return delta, x[len(joints):]

        def fun(x):
            return self._linear(*unpack(x), rows)[1].ravel()

        x = np.zeros(len(joints) + 3)
        if iterate:
            x = least_squares(fun, x, method="lm", x_scale=1.0, xtol=1e-12, ftol=1e-12).x
        delta, rotvec = unpack(x)
        theta, _ = self._linear(delta, rotvec, rows)
        return OffsetFit(delta, rotvec, theta, rows)

    # -- the Jacobian ---------------------------------------------------------------------
    def offset_columns(self, fit: OffsetFit, joints) -> np.ndarray:
        """(N, 6, k) the weighted residual's derivative in each joint's offset (central
        differences of the model's prediction, in Sm)."""
        out = np.empty((int(fit.rows.sum()), 6, len(joints)))
        n = len(fit.delta)
        K = _block(fit.rotvec)
        for i, j in enumerate(joints):
            step = np.zeros(n)
            step[j] = STEP
            plus = self.regressor(fit.delta + step, fit.rows) @ fit.theta
            minus = self.regressor(fit.delta - step, fit.rows) @ fit.theta
            out[:, :, i] = -((plus - minus) / (2 * STEP)) @ K * self.weights
        return out

    def nuisance_columns(self, fit: OffsetFit) -> np.ndarray:
        """(N, 6, 3 + p) the weighted residual's derivative in the mounting rotation vector
        (central differences) and in θ (the regressor, rotated into Sm)."""
        A = self.regressor(fit.delta, fit.rows)
        wrench = A @ fit.theta
        rot = np.empty((len(A), 6, 3))
        for i in range(3):
            step = np.zeros(3)
            step[i] = STEP
            rot[:, :, i] = -wrench @ ((_block(fit.rotvec + step) - _block(fit.rotvec - step))
                                      / (2 * STEP))
        linear = -np.einsum("nip,ij->njp", A, _block(fit.rotvec))
        return np.concatenate([rot, linear], axis=2) * self.weights[None, :, None]

    def standard_errors(self, fit: OffsetFit, joints) -> tuple[np.ndarray, float]:
        """(the offsets' standard errors (rad), the factor the correlated rows widened them
        by): from the whole Jacobian (offsets, rotation, payload, biases) at the fit."""
        J = np.concatenate([self.offset_columns(fit, joints), self.nuisance_columns(fit)],
                           axis=2)
        r = self.residual(fit) * self.weights
        flat = J.reshape(-1, J.shape[-1])
        scale = np.linalg.norm(flat, axis=0)
        scale[scale == 0] = 1.0
        sigma2 = float(np.sum(r ** 2) / max(1, r.size - J.shape[-1]))
        cov = sigma2 * np.linalg.pinv((flat / scale).T @ (flat / scale), hermitian=True)
        cov /= np.outer(scale, scale)
        ratio, _ = correlated_variance_ratio(J, r)
        k = len(joints)
        se = np.sqrt(np.maximum(np.diag(cov)[:k], 0.0) * ratio[:k])
        return se, float(np.sqrt(np.median(ratio[:k]))) if k else 1.0


def _block(rotvec) -> np.ndarray:
    """K (6, 6) with reading (row) = wrench in S (row) @ K: R_SSm on forces and torques."""
    return np.kron(np.eye(2), Rotation.from_rotvec(rotvec).as_matrix())


def joint_labels(chain, model) -> list[str]:
    """A name per row column: the chain's joint that reads it, else the model's joint list's
    name (or the model's own joint order), else ``q_<i>``."""
    names = [f"q_{i}" for i in range(chain.num_positions)]
    listed = model._joint_columns()
    if not listed:  # the rows hold the model's joints in its order: their names
        plant = gravity_plant(model.robot_description())[0]
        if plant.num_positions() == chain.num_positions:
            listed = movable_joint_names(plant)
    for i, name in enumerate(listed[:len(names)]):
        names[i] = name
    moving = [j for j in chain.joints if j.q_index >= 0]
    for joint in moving:
        names[joint.q_index] = joint.name
    return names
