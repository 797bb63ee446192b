"""Which joint offsets a log of wrench readings determines, and why the others it does not
(:mod:`ftdrake.compensation.calibration.joint_offsets`).

From the Jacobian of the weighted residual at the fit without offsets: each joint's column
(the reading's change per radian of its offset) against the nuisance columns (the mounting
rotation, the payload's parameters and the biases) and against the other joints':

* a column at round-off level (below :data:`ZERO_COLUMN` of the weighted gravity wrench per
  radian): the offset changes nothing the sensor feels — a prismatic joint, a joint not
  between the world and S, or a revolute axis along gravity in every row;
* a column whose part left after projecting out the nuisance columns is below
  :data:`SPANNED` of its norm: the offset is a change of the mounting rotation (the last
  joint before S) or of the payload and biases;
* columns, each so projected and normalised, whose smallest singular value is below
  :data:`SPANNED`: only a combination of those joints' offsets is determined;
* an offset whose column correlates by :data:`SAG_CORRELATION` or more with that of a gravity
  sag at the same joint (``−τ_j(q)`` times its column, per row; τ_j the torque that holds the
  robot model's links against gravity, in N·m, from Drake's
  ``CalcGravityGeneralizedForces``), both after the nuisance columns: an offset and a
  compliance fit alike. The payload's own weight counts only as far as the robot model holds
  the tool.
"""

from __future__ import annotations

import dataclasses as dc
import functools

import numpy as np

from ...physics.chain import PRISMATIC
from .regression import NULL_DIRECTION_TOL

#: A column below this fraction of the weighted gravity wrench (per radian) is zero.
ZERO_COLUMN = 1e-6
#: A column (or combination of columns) whose part outside the others' span is below this
#: fraction of its norm is not determined.
SPANNED = 1e-3
#: An offset and a gravity sag whose columns correlate this much (after the nuisance
#: columns) are named as confounded.
SAG_CORRELATION = 0.95


@dc.dataclass
class Identifiability:
    """Per joint (by name), whether the data determine its offset.

    ``identifiable``: the row columns whose offsets are determined (indices);
    ``unidentifiable``: {name: reason}; ``sag``: {name: reason} for identifiable offsets that
    a gravity sag fits alike; ``sag_correlation``: {name: |correlation|} of the offset's and
    the sag's columns; ``gravity_torque_range``: {name: (min, max)} of the holding torque
    (N·m) over the rows; ``singular_values``: of the identifiable joints' normalised columns
    after the nuisance columns (1 for orthogonal columns, 0 for dependent ones).
    """

    identifiable: tuple[int, ...]
    unidentifiable: dict
    sag: dict
    sag_correlation: dict
    gravity_torque_range: dict
    singular_values: np.ndarray


def analyse(problem, fit) -> Identifiability:
    """The identifiability of every joint's offset in `problem` (a
    :class:`~ftdrake.compensation.calibration.joint_offsets.OffsetProblem`) at `fit` (its fit
    without offsets)."""
    names = problem.names
    n = len(names)
    rows = int(fit.rows.sum())
    J = problem.offset_columns(fit, range(n)).reshape(6 * rows, n)
    nuisance = problem.nuisance_columns(fit).reshape(6 * rows, -1)
    gravity = problem.regressor(fit.delta, fit.rows)[:, :, :len(problem.phys)] @ \
        fit.theta[:len(problem.phys)]
    scale = max(np.linalg.norm(gravity * problem.weights), 1e-300)
    perp = _orthogonal(J, nuisance)
    perp_no_rotation = _orthogonal(J, nuisance[:, 3:])
    norms = np.linalg.norm(J, axis=0)
    unidentifiable = {}
    for j in range(n):
        if norms[j] <= ZERO_COLUMN * scale:
            unidentifiable[names[j]] = _zero_reason(problem, j)
        elif np.linalg.norm(perp[:, j]) <= SPANNED * norms[j]:
            if np.linalg.norm(perp_no_rotation[:, j]) > 10 * SPANNED * norms[j]:
                unidentifiable[names[j]] = (
                    "the same as a rotation of the sensor's mounting about its axis (no joint "
                    "between it and S turns relative to it): identify the mounting, or this "
                    "offset, from another source")
            else:
                unidentifiable[names[j]] = ("the same as a change of the payload's centre "
                                            "of mass or the biases")
    free = [j for j in range(n) if names[j] not in unidentifiable]
    singular = _separate(perp, norms, free, names, unidentifiable)
    identifiable = tuple(j for j in free if names[j] not in unidentifiable)
    torques = gravity_torques(problem.model, problem.X[fit.rows, :n])
    sag, correlation, ranges = {}, {}, {}
    if torques is not None:
        for j in identifiable:
            tau = torques[:, j]
            ranges[names[j]] = (float(tau.min()), float(tau.max()))
            column = (-tau[:, None] * J[:, j].reshape(rows, 6)).reshape(-1, 1)
            s = _orthogonal(column, nuisance)[:, 0]
            denominator = np.linalg.norm(s) * np.linalg.norm(perp[:, j])
            rho = float(abs(s @ perp[:, j]) / denominator) if denominator > 0 else 1.0
            correlation[names[j]] = rho
            if rho >= SAG_CORRELATION:
                sag[names[j]] = _sag_reason(*ranges[names[j]], rho)
    return Identifiability(identifiable, unidentifiable, sag, correlation, ranges, singular)


def _orthogonal(columns, basis) -> np.ndarray:
    """`columns` minus their least-squares projection on `basis` (columns scaled first)."""
    scale = np.linalg.norm(basis, axis=0)
    keep = scale > 0
    B = basis[:, keep] / scale[keep]
    return columns - B @ least_squares_solution(B, columns)


def least_squares_solution(M, y) -> np.ndarray:
    """The minimum-norm x of ‖M x − y‖ (y: a vector or columns) from the column-scaled
    normal equations, directions below :data:`~.regression.NULL_DIRECTION_TOL` of the
    largest singular value dropped: a p × p problem, however many rows."""
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    Ms = M / scale
    lam, V = np.linalg.eigh(Ms.T @ Ms)
    keep = lam > NULL_DIRECTION_TOL ** 2 * max(lam.max(), 1e-300)
    x = ((V[:, keep] / lam[keep]) @ V[:, keep].T) @ (Ms.T @ y)
    return x / (scale if x.ndim == 1 else scale[:, None])


def _separate(perp, norms, free, names, unidentifiable) -> np.ndarray:
    """Marks groups of joints in `free` whose projected columns are dependent (in
    `unidentifiable`); returns the singular values of the remaining joints' columns."""
    while True:
        left = [j for j in free if names[j] not in unidentifiable]
        if not left:
            return np.zeros(0)
        U = perp[:, left] / norms[left]
        _, s, Vt = np.linalg.svd(U, full_matrices=False)
        if s[-1] > SPANNED:
            return s
        loading = np.abs(Vt[-1])
        group = [left[i] for i in np.flatnonzero(loading >= 0.3 * loading.max())]
        for j in group:
            others = [names[i] for i in group if i != j]
            unidentifiable[names[j]] = (
                "cannot be told apart from the offset of " + ", ".join(others)
                + ": together they turn gravity in S alike in these data (only a combination "
                "is determined; rows in other poses may separate them)"
                if others else "the data do not turn gravity in S by it")


def _zero_reason(problem, j) -> str:
    chain = problem.model._kinematics().chain
    joint = next((c for c in chain.joints if c.q_index == j), None)
    if joint is None:
        return "not between the world and the sensor: it does not move S"
    if joint.type == PRISMATIC:
        return "a prismatic joint: it moves S without turning it, so gravity in S is the same"
    return ("its axis stays along gravity in every row (a vertical axis): turning about it "
            "does not turn gravity in S")


def _sag_reason(low, high, rho) -> str:
    sign = ("keeps its sign" if low * high > 0 else "changes sign but little")
    return (f"its gravity torque {sign} ({low:+.3g} to {high:+.3g} N·m): an offset and a "
            f"compliance (q_link = q_motor − τ/k) fit alike (correlation {rho:.3f}); the value "
            "is the offset plus the mean sag")


def gravity_torques(model, q) -> np.ndarray | None:
    """(N, n) the torque (N·m; N for a prismatic joint) that holds the robot model's links
    against gravity at each row's joint positions `q` (rad, m), per row column; None when the
    model has no link masses or no joint maps to the rows."""
    plant, context, index = gravity_plant(model.robot_description())
    if index is None:
        return None
    out = np.zeros(q.shape)
    positions = plant.GetPositions(context).copy()
    for r, row in enumerate(q):
        for column, (qi, _) in index.items():
            positions[qi] = row[column]
        plant.SetPositions(context, positions)
        tau = -plant.CalcGravityGeneralizedForces(context)
        for column, (_, vi) in index.items():
            out[r, column] = tau[vi]
    return out if np.any(out) else None


@functools.lru_cache(maxsize=4)
def gravity_plant(description):
    """(plant, context with the fixed joints set, {row column: (q index, v index)})."""
    plant, _ = description.build_plant()
    context = plant.CreateDefaultContext()
    for name, value in description.fixed_joints:
        joint = plant.GetJointByName(name)
        positions = plant.GetPositions(context).copy()
        positions[joint.position_start()] = value
        plant.SetPositions(context, positions)
    if description.joints:
        index = {}
        for column, name in enumerate(description.joints):
            joint = plant.GetJointByName(name)
            index[column] = (joint.position_start(), joint.velocity_start())
        return plant, context, index
    if plant.num_positions() != plant.num_velocities():
        return plant, context, None
    return plant, context, {i: (i, i) for i in range(plant.num_positions())}
