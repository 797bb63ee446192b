"""Calibration of a wrist F/T sensor from a table of static poses (``ftdrake calibrate``).

A calibration log is often not a time series but a table: each row one pose held still and
the wrench read there (velocities zero, nothing to differentiate, often no time column). The
sensor's orientation comes either

* as **joint angles** (``q_*`` columns, rad or deg) with a robot description (URDF/SDF and the
  sensor frame): the identified model is a static
  :class:`~ftdrake.compensation.physics.PhysicsPayloadCompensator` (gravity only), which
  also identifies the sensor's mounting rotation ``R_SSm`` (the frame the sensor measures in)
  and is saved as a model file ``evaluate`` and the station use; or
* **directly as a rotation**, one of (checked in this order)

  - ``qw, qx, qy, qz``: the quaternion of ``R_WS`` (S in the world; gravity along −z of W),
  - ``r00 … r22``: ``R_WS`` row by row,
  - ``roll, pitch, yaw`` (rad): ``R_WS = RollPitchYaw(roll, pitch, yaw)`` (Drake's, extrinsic
    x-y-z),
  - ``gx, gy, gz``: gravity in S (m/s²; a unit vector is scaled to 9.81 m/s²).

  The mounting rotation is then absorbed in the orientation (the rotation given *is* the one
  of the measuring frame, as far as the data can tell) and is not identified.

Static poses determine the mass, the first moment ``m·c`` (so the centre of mass) and the six
biases — not the inertia, which only acceleration excites: a static calibration says so and
leaves it out. With a ``temperature`` column (°C) the per-axis zero drift per kelvin is
identified as well. Every parameter comes with its standard error; the fit is the physically
consistent one (mass > 0; optional prior) of :mod:`ftdrake.compensation.consistent`.

**Gain and cross-talk** (``correction="block"`` or ``"full"``; iCub's "secondary calibration
matrix"): a 6 × 6 correction ``C`` with ``W_S ≈ C·(W_meas − b − k·ΔT)``, identified by linear
least squares from the wrench each pose should give, ``W_S = [m·g_S; m·c × g_S]`` (gravity
known, the payload known or identified): the reading is ``M·W_S + b (+ k·ΔT)`` with
``M = C⁻¹``, linear in M and b. ``"block"`` fits forces from forces and torques from torques
(two 3 × 3 blocks), ``"full"`` all 36 entries. What the data determine depends on the loads:

* one load (the tool): its torques are all ⊥ its centre of mass (``T = c × F``), so the torque
  correction along c is not determined, and in ``"full"`` the forces and torques are tied
  (three directions free; the fit is then the general linear model of that load, which
  predicts its readings best); the force block is determined, as its effective value for
  this load (``M_FF + M_FT·[c]×``: the torque-to-force cross-talk folded in);
* without a known payload, the mean force gain cannot be told from the mass (the identified
  mass absorbs it) nor the torque gain from the centre of mass;
* the full 6 × 6 needs at least three known loads whose centres of mass are not on one line
  (table columns ``known_mass``, ``known_com_x/y/z`` per row).

Directions the data leave free are kept at the identity (no correction: the least-change
solution) and their entries get an infinite standard error; an :class:`ExcitationWarning`
names them. The standard errors of C come from those of M by the delta method
(``dC = −C·dM·C``), rows of M independent, the payload taken as exact.

:func:`calibrate_table` returns a :class:`StaticCalibration` with :meth:`~StaticCalibration.
to_dict` (what the YAML holds), :meth:`~StaticCalibration.summary` and
:meth:`~StaticCalibration.predict` (the reading at held-out poses of a table).
"""

from __future__ import annotations

import dataclasses as dc
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.math import RollPitchYaw

from ..conventions import GRAVITY_W, MEASURED, TEMPERATURE, WRENCH_AXES
from ..data.logs import expand_columns, is_table, read_frame
from ..errors import ConfigError, LogError
from .consistent import PayloadPrior, identify_consistent, identify_least_squares
from .physics import ExcitationWarning, PhysicsPayloadCompensator, payload_regressor

#: Orientation column sets, in the order they are looked for.
ORIENTATIONS = {
    "quaternion": ("qw", "qx", "qy", "qz"),
    "rotation_matrix": tuple(f"r{i}{j}" for i in range(3) for j in range(3)),
    "roll_pitch_yaw": ("roll", "pitch", "yaw"),
    "gravity": ("gx", "gy", "gz"),
}
STATIC_NAMES = ("m", "mcx", "mcy", "mcz", "bFx", "bFy", "bFz", "bTx", "bTy", "bTz")
STATIC_UNITS = ("kg", "kg*m", "kg*m", "kg*m", "N", "N", "N", "N*m", "N*m", "N*m")
NOT_IDENTIFIABLE = ("static poses determine the mass, the first moment m·c (so the centre of "
                    "mass) and the biases; the inertia needs motion (a dynamic log with "
                    "`ftdrake train --kind physics`)")
#: Structures of the gain/cross-talk correction C: two 3 × 3 blocks, or all of the 6 × 6.
CORRECTIONS = ("block", "full")
#: Table columns of a known payload per row (kg; m, from So in S): several loads in one table.
KNOWN_MASS = "known_mass"
KNOWN_COM = ("known_com_x", "known_com_y", "known_com_z")
#: A singular value below this fraction of the largest is a direction the data do not span.
_RANK_TOL = 1e-6
_SEVERAL_LOADS = ("the table holds {} loads: the payload and biases above are one gravity + bias "
                  "fit over all of them (not a payload); the correction uses the known ones")


@dc.dataclass
class CalibrationCorrection:
    """The sensor's gain/cross-talk correction identified from static poses.

    ``matrix`` C (6 × 6, dimensionless between like axes, 1/m from torque to force and m from
    force to torque): ``W_S ≈ C·(W_meas − bias − k·ΔT)``, the wrench in the model's frame S
    (a mounting rotation included) from a reading; ``sensor_matrix`` M = C⁻¹ (the reading per
    true wrench). ``std_errors`` / ``sensor_std_errors``: their standard errors (∞ where the
    data do not determine an entry; 0 where the structure fixes it). ``bias`` and
    ``temperature_coefficients`` are re-identified with it. ``payload`` ``[m, m·cx, m·cy,
    m·cz]`` is the one the true wrench was computed with (None with one per row);
    ``residual_rms`` the fit's per axis, ``rigid_residual_rms`` the gravity + bias model's.
    ``free_directions`` (k × 6, unit rows): wrench directions the data do not span, along which
    C is not determined (``undetermined`` says the same in words).
    """

    structure: str
    matrix: np.ndarray
    std_errors: np.ndarray
    sensor_matrix: np.ndarray
    sensor_std_errors: np.ndarray
    bias: np.ndarray
    bias_std_errors: np.ndarray
    residual_rms: np.ndarray
    rigid_residual_rms: np.ndarray
    condition_number: float
    rank: tuple
    undetermined: list
    known_payload: bool
    loads: int
    payload: np.ndarray | None = None
    temperature_reference: float | None = None
    temperature_coefficients: np.ndarray | None = None
    temperature_std_errors: np.ndarray | None = None
    free_directions: np.ndarray = dc.field(default_factory=lambda: np.zeros((0, 6)))

    def reading(self, W_S: np.ndarray, temperature=None) -> np.ndarray:
        """(N, 6) readings for true wrenches `W_S` (N, 6) in S: ``M·W + b (+ k·ΔT)``."""
        out = W_S @ self.sensor_matrix.T + self.bias
        if self.temperature_coefficients is not None and temperature is not None:
            out = out + np.outer(np.asarray(temperature) - self.temperature_reference,
                                 self.temperature_coefficients)
        return out

    def to_dict(self) -> dict:
        table = {
            "structure": self.structure,
            "matrix": self.matrix.tolist(),
            "std_errors": self.std_errors.tolist(),
            "meaning": ("C: wrench in S = C·(reading − bias − k·ΔT); rows and columns Fx, Fy, "
                        "Fz, Tx, Ty, Tz (torque-to-force entries in 1/m, force-to-torque in m)"),
            "sensor_matrix": self.sensor_matrix.tolist(),
            "sensor_std_errors": self.sensor_std_errors.tolist(),
            "bias": dict(zip(WRENCH_AXES, self.bias.tolist(), strict=True)),
            "bias_std_errors": dict(zip(WRENCH_AXES, self.bias_std_errors.tolist(),
                                        strict=True)),
            "residual_rms": dict(zip(WRENCH_AXES, self.residual_rms.tolist(), strict=True)),
            "residual_rms_gravity_and_bias_only": dict(zip(
                WRENCH_AXES, self.rigid_residual_rms.tolist(), strict=True)),
            "condition_number": float(self.condition_number),
            "rank": list(self.rank),
            "loads": self.loads,
            "payload": ("known (given)" if self.known_payload else
                        "identified from these poses: the mean force gain is absorbed in the "
                        "mass, the torque gain in the centre of mass"),
            "not_determined": list(self.undetermined) or "none",
        }
        if self.loads > 1:
            table["note"] = _SEVERAL_LOADS.format(self.loads)
        if self.temperature_coefficients is not None:
            table["temperature_coefficients_per_k"] = dict(zip(
                WRENCH_AXES, self.temperature_coefficients.tolist(), strict=True))
        return table

    def summary(self) -> list[str]:
        how = {"block": "force and torque 3 × 3 blocks", "full": "full 6 × 6"}[self.structure]
        payload = ("known payload" if self.known_payload else
                   "payload identified from the same poses (mean force gain absorbed in the "
                   "mass)")
        lines = [(f"  gain/cross-talk correction C ({how}; {self.loads} load(s), {payload}; "
                  f"condition number {self.condition_number:.3g}):"),
                 ("    wrench in S = C·(reading − bias), rows/columns Fx..Tz; entry ± std "
                  "error (· fixed at 0 by the structure)")]
        fixed = (self.sensor_std_errors == 0) & (self.sensor_matrix == 0)
        for i, axis in enumerate(WRENCH_AXES):
            lines.append(f"    {axis}: " + "  ".join(
                f"{'·':^18s}" if fixed[i, j] else f"{v:+.5f} ± {_se(e):7s}"
                for j, (v, e) in enumerate(zip(self.matrix[i], self.std_errors[i],
                                               strict=True))))
        lines.append("    residual RMS (Fx..Tz): " + ", ".join(
            f"{r:.3g}" for r in self.residual_rms) + "; gravity + bias only: " + ", ".join(
            f"{r:.3g}" for r in self.rigid_residual_rms))
        for note in self.undetermined:
            lines.append(f"    not determined: {note}")
        if self.loads > 1:
            lines.append(f"    note: {_SEVERAL_LOADS.format(self.loads)}")
        return lines



def orientation_kind(columns) -> str | None:
    """Which orientation columns a table has (a key of :data:`ORIENTATIONS`), or None."""
    present = set(columns)
    for kind, names in ORIENTATIONS.items():
        if set(names) <= present:
            return kind
    return None


def gravity_in_sensor(frame: pd.DataFrame, kind: str, gravity=GRAVITY_W) -> np.ndarray:
    """(N, 3) gravity expressed in S from the orientation columns of `kind`."""
    g_W = np.asarray(gravity, dtype=float)
    values = _numeric(frame, ORIENTATIONS[kind])
    if kind == "gravity":
        norm = np.linalg.norm(values, axis=1)
        if np.any(norm == 0):
            raise LogError("gx, gy, gz: a row has zero gravity")
        unit = np.all(np.abs(norm - 1.0) < 0.05)
        return values * (np.linalg.norm(g_W) if unit else 1.0)
    if kind == "quaternion":
        q = values / np.linalg.norm(values, axis=1, keepdims=True)
        w, x, y, z = q.T
        R = np.stack([
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ], axis=1)
    elif kind == "rotation_matrix":
        R = values.reshape(-1, 3, 3)
        err = np.abs(R @ np.transpose(R, (0, 2, 1)) - np.eye(3)).max()
        if err > 1e-3:
            raise LogError(f"r00..r22: not a rotation matrix (|R Rᵀ − I| = {err:.2g})")
    else:
        R = np.array([RollPitchYaw(r).ToRotationMatrix().matrix() for r in values])
    return np.einsum("nji,j->ni", R, g_W)  # g_S = R_WSᵀ g_W


@dc.dataclass
class StaticCalibration:
    """What a static calibration identified (SI units, in the sensor frame S).

    ``parameters``/``standard_errors`` follow :data:`STATIC_NAMES`; ``com`` and its standard
    errors by the delta method; ``temperature_*`` per axis (N/K, N·m/K) about
    ``temperature_reference`` (°C) when the table had a temperature; ``mounting_rpy_deg``
    when joint angles and a robot were given (None when absorbed in the orientation);
    ``model`` the fitted static physics model (joint-angle input) or None; ``correction``
    the gain/cross-talk correction when asked for (:class:`CalibrationCorrection`; the model
    file does not apply it).
    """

    source: str  # "joint_angles" or an ORIENTATIONS key
    parameters: np.ndarray
    standard_errors: np.ndarray
    com: np.ndarray
    com_std_error: np.ndarray
    residual_rms: np.ndarray
    condition_number: float
    rows: int
    temperature_reference: float | None = None
    temperature_coefficients: np.ndarray | None = None
    temperature_std_errors: np.ndarray | None = None
    mounting_rpy_deg: np.ndarray | None = None
    mounting_std_deg: np.ndarray | None = None
    model: PhysicsPayloadCompensator | None = None
    gravity: tuple = GRAVITY_W
    positions: tuple = ()
    position_unit: str = "rad"
    correction: CalibrationCorrection | None = None

    def gravity_in_sensor(self, frame: pd.DataFrame) -> np.ndarray:
        """(N, 3) gravity in S (m/s²) at the poses of `frame`, from the same kind of columns
        (joint angles through the robot, or the orientation columns)."""
        if self.model is not None:
            X = _joint_layout(frame, list(self.positions), self.position_unit)
            return self.model.regressor(X)[:, :3, 0]  # static: the mass column is g_S
        return gravity_in_sensor(frame, self.source, self.gravity)

    def predict(self, frame: pd.DataFrame, corrected: bool = True) -> np.ndarray:
        """(N, 6) the readings at the poses of `frame` (same kind of orientation columns).

        With a :attr:`correction` (and `corrected`), ``M·W_S + b + k·ΔT`` with the payload the
        correction was fitted with (or the table's known_* columns); else the gravity + bias
        model.
        """
        temperature = None
        if self.temperature_reference is not None:
            if TEMPERATURE not in frame:
                raise LogError(f"the calibration has temperature coefficients; the table has "
                               f"no '{TEMPERATURE}' column (°C)")
            temperature = _numeric(frame, [TEMPERATURE])[:, 0]
        if self.correction is not None and corrected:
            payload = self.correction.payload
            if payload is None:  # fitted with a known payload per row: the table gives it
                payload, _ = _known_payload(frame, None)
                if payload is None:
                    raise LogError(f"the correction was fitted with a known payload per row; "
                                   f"the table needs the columns {KNOWN_MASS}, "
                                   f"{', '.join(KNOWN_COM)}")
            return self.correction.reading(true_wrench(self.gravity_in_sensor(frame), payload),
                                           temperature)
        if self.model is not None:
            X = _joint_layout(frame, list(self.positions), self.position_unit)
            if temperature is not None:
                X = np.column_stack([X, temperature])
            return self.model.predict(X)
        A = _static_regressor(gravity_in_sensor(frame, self.source, self.gravity))
        out = A[:, :, [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]] @ self.parameters
        if temperature is not None:
            out = out + np.outer(temperature - self.temperature_reference,
                                 self.temperature_coefficients)
        return out

    def to_dict(self) -> dict:
        """A plain mapping (what ``calibrate`` writes as YAML)."""
        table = {
            "source": self.source,
            "rows": self.rows,
            "parameters": {name: {"value": float(v), "std_error": float(e), "unit": u}
                           for name, v, e, u in zip(STATIC_NAMES, self.parameters,
                                                    self.standard_errors, STATIC_UNITS,
                                                    strict=True)},
            "com_m": {"value": self.com.tolist(), "std_error": self.com_std_error.tolist(),
                      "frame": "p_SoScm_S: from the sensor origin, in S"},
            "residual_rms": dict(zip(WRENCH_AXES, self.residual_rms.tolist(), strict=True)),
            "condition_number": float(self.condition_number),
            "not_identifiable": NOT_IDENTIFIABLE,
        }
        if self.temperature_reference is not None:
            table["temperature"] = {
                "reference_c": float(self.temperature_reference),
                "coefficients_per_k": dict(zip(WRENCH_AXES,
                                               self.temperature_coefficients.tolist(),
                                               strict=True)),
                "std_errors_per_k": dict(zip(WRENCH_AXES, self.temperature_std_errors.tolist(),
                                             strict=True))}
        if self.correction is not None:
            table["correction"] = self.correction.to_dict()
        if self.mounting_rpy_deg is not None:
            table["mounting_rpy_deg"] = {
                "value": self.mounting_rpy_deg.tolist(),
                "std_error": self.mounting_std_deg.tolist(),
                "frame": "R_SSm: the frame the sensor measures in, in S (roll, pitch, yaw)"}
        else:
            table["mounting_rpy_deg"] = ("not identified: with the orientation given directly, "
                                         "a mounting rotation is absorbed in it")
        return table

    def summary(self) -> str:
        """The identified parameters with standard errors, as lines a user reads."""
        lines = [(f"static calibration from {self.rows} poses ({self.source}); condition "
                  f"number {self.condition_number:.3g}"),
                 f"  {'':5s} {'value':>12s} {'std error':>10s} unit"]
        for name, v, e, u in zip(STATIC_NAMES, self.parameters, self.standard_errors,
                                 STATIC_UNITS, strict=True):
            lines.append(f"  {name:5s} {v:12.6g} {e:10.3g} {u}")
        lines.append("  centre of mass p_SoScm_S: " + ", ".join(
            f"{1e3 * c:.2f} ± {1e3 * e:.2f}"
            for c, e in zip(self.com, self.com_std_error, strict=True)) + " mm")
        if self.mounting_rpy_deg is not None:
            lines.append("  sensor mounting R_SSm roll, pitch, yaw: " + ", ".join(
                f"{v:.3f} ± {e:.3f}" for v, e in zip(self.mounting_rpy_deg,
                                                     self.mounting_std_deg, strict=True))
                + " deg")
        else:
            lines.append("  sensor mounting: absorbed in the given orientation (not identified)")
        if self.temperature_reference is not None:
            lines.append(f"  zero drift per K (Fx..Tz, about {self.temperature_reference:.2f} "
                         "°C): " + ", ".join(
                f"{v:.4g} ± {e:.2g}" for v, e in zip(self.temperature_coefficients,
                                                      self.temperature_std_errors,
                                                      strict=True)))
        lines.append("  residual RMS (Fx..Tz): "
                     + ", ".join(f"{r:.3g}" for r in self.residual_rms))
        if self.correction is not None:
            lines.extend(self.correction.summary())
        lines.append(f"  note: {NOT_IDENTIFIABLE}")
        return "\n".join(lines)


def calibrate_table(frame: pd.DataFrame, *, robot=None, sensor_frame=None, base_frame=None,
                    positions="q_*", targets=f"{MEASURED}_*", position_unit="rad",
                    prior=None, identification="consistent", identify_mounting=True,
                    gravity=GRAVITY_W, correction=None,
                    known_payload=None) -> StaticCalibration:
    """Identifies payload, biases (and mounting, temperature coefficients) from static poses.

    `frame`: one row per pose; 6 wrench columns (`targets`) and either joint angles
    (`positions`, with `robot`/`sensor_frame`; ``robot="ftdrake"`` or None with joint columns
    present: ftdrake's simulated arm) or orientation columns (:data:`ORIENTATIONS`); a
    ``temperature`` column (°C) adds temperature coefficients. `prior`: a
    :class:`~.consistent.PayloadPrior` or mapping (its mass must be positive).
    `correction` (``"block"``, ``"full"``): also identify the sensor's gain/cross-talk
    correction (module docstring) against the wrench of a `known_payload` (mapping with
    ``mass`` kg and ``com`` m, in S; or the table's ``known_mass``, ``known_com_x/y/z``
    columns, one payload per row) or, without one, of the payload identified here.
    Raises LogError/ConfigError/RobotModelError naming the column, field or frame at fault.
    """
    if correction is not None and correction not in CORRECTIONS:
        raise ConfigError(f"correction must be one of {list(CORRECTIONS)} or None, got "
                          f"{correction!r}")
    if correction is None and known_payload is not None:
        raise ConfigError("known_payload is used by the gain/cross-talk correction: give "
                          "correction='block' or 'full'")
    cal = _calibrate(frame, robot, sensor_frame, base_frame, positions, targets,
                     position_unit, prior, identification, identify_mounting, gravity)
    if correction is None:
        return cal
    payload, loads = _known_payload(frame, known_payload)
    known = payload is not None
    if not known:
        payload = np.tile(cal.parameters[:4], (len(frame), 1))
    Y = _numeric(frame, expand_columns(targets, list(frame.columns), "wrench columns"))
    temperature = _numeric(frame, [TEMPERATURE])[:, 0] if TEMPERATURE in frame else None
    W_S = true_wrench(cal.gravity_in_sensor(frame), payload)
    # The comparison without correction: the gravity + bias fit above, or, with a known
    # payload, its wrench plus the best bias (and temperature drift).
    rigid = cal.residual_rms if not known else _uncorrected_rms(Y - W_S, temperature)
    cal.correction = identify_correction(
        W_S, Y, correction, temperature, rigid, known_payload=known, loads=loads,
        # One payload for every row (identified or given): kept for predicting held-out
        # poses. Known payloads from the table's columns are read from each table.
        payload=None if known and KNOWN_MASS in frame else payload[0])
    return cal


def _calibrate(frame, robot, sensor_frame, base_frame, positions, targets, position_unit,
               prior, identification, identify_mounting, gravity) -> StaticCalibration:
    """calibrate_table without the correction."""
    prior = PayloadPrior.coerce(prior)
    target_cols = expand_columns(targets, list(frame.columns), "wrench columns")
    if len(target_cols) != 6:
        raise LogError(f"need 6 wrench columns (Fx..Tz); {targets!r} matches {target_cols}")
    Y = _numeric(frame, target_cols)
    temperature = _numeric(frame, [TEMPERATURE])[:, 0] if TEMPERATURE in frame else None
    kind = orientation_kind(frame.columns)
    joint_cols = _joint_columns(frame, positions)
    if joint_cols and (robot is not None or kind is None):
        return _calibrate_joint_angles(frame, joint_cols, Y, temperature, robot, sensor_frame,
                                       base_frame, position_unit, prior, identification,
                                       identify_mounting, gravity)
    if kind is None:
        raise LogError("no orientation in the table: give joint angles (columns "
                       f"{positions!r}) with --robot and --sensor-frame, or one of the column "
                       "sets " + "; ".join(", ".join(c if len(c) < 5 else (c[0], "…", c[-1]))
                                             for c in ORIENTATIONS.values()))
    g_S = gravity_in_sensor(frame, kind, gravity)
    A = _static_regressor(g_S)
    cols = [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]
    reference, d = _temperature_deviation(temperature)
    A_fit, Y_fit = (A, Y) if d is None else (_project_out(A, d), _project_out(Y, d))
    if identification == "consistent":
        result = identify_consistent(A_fit[:, :, cols], Y_fit, static=True,
                                     prior=None if prior is None else prior.phi())
    else:
        result = identify_least_squares(A_fit[:, :, cols], Y_fit, static=True)
    theta = result.theta[cols]
    cov = result.covariance[np.ix_(cols, cols)]
    residual = Y - A[:, :, cols] @ theta
    k = se_k = None
    if d is not None:
        k = residual.T @ d / (d @ d)
        residual = residual - np.outer(d, k)
        se_k = np.sqrt(np.mean(residual ** 2, axis=0)) / np.sqrt(d @ d)
    com, com_se = _com(theta, cov)
    return StaticCalibration(
        source=kind, parameters=theta, standard_errors=result.standard_errors[cols], com=com,
        com_std_error=com_se, residual_rms=np.sqrt(np.mean(residual ** 2, axis=0)),
        condition_number=float(result.condition_number), rows=len(frame),
        temperature_reference=reference, temperature_coefficients=k,
        temperature_std_errors=se_k, gravity=tuple(gravity))


def _calibrate_joint_angles(frame, joint_cols, Y, temperature, robot, sensor_frame,
                            base_frame, position_unit, prior, identification,
                            identify_mounting, gravity):
    if robot in (None, "ftdrake"):
        robot = sensor_frame = None
    elif not sensor_frame:
        raise ConfigError(f"--robot {robot} needs --sensor-frame (the frame of the wrench)")
    X = _joint_layout(frame, joint_cols, position_unit)
    if temperature is not None:
        X = np.column_stack([X, temperature])
    model = PhysicsPayloadCompensator(
        features="q", mode="static", robot=robot, sensor_frame=sensor_frame,
        base_frame=base_frame, gravity=tuple(gravity), identification=identification,
        prior=prior, identify_mounting=identify_mounting)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)  # the inertia: said in the note
        try:
            model.fit(X, Y)
        except ValueError as e:
            if "joints" in str(e):
                raise LogError(f"{e} (joint columns {joint_cols})") from None
            raise
    t = model.identified()
    cols = [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]
    theta, cov = model.parameters_[cols], model.covariance_[np.ix_(cols, cols)]
    com, com_se = _com(theta, np.nan_to_num(cov))
    has_t = model.temperature_reference_ is not None
    return StaticCalibration(
        source="joint_angles", parameters=theta, standard_errors=model.standard_errors_[cols],
        com=com, com_std_error=com_se, residual_rms=model.residual_rms_,
        condition_number=model.condition_number_, rows=len(frame),
        temperature_reference=model.temperature_reference_ if has_t else None,
        temperature_coefficients=model.temperature_coefficients_ if has_t else None,
        temperature_std_errors=model.temperature_std_errors_ if has_t else None,
        mounting_rpy_deg=(np.array(t["mounting_rpy_deg"]["value"]) if identify_mounting
                          else None),
        mounting_std_deg=(np.array(t["mounting_rpy_deg"]["std_error"]) if identify_mounting
                          else None),
        model=model, gravity=tuple(gravity), positions=tuple(joint_cols),
        position_unit=position_unit)


def static_table_hint(path) -> str | None:
    """For ``train``: a sentence pointing to ``ftdrake calibrate`` when `path` is a table of
    static poses (orientation columns, or no time column), else None."""
    if not is_table(path):
        return None
    try:
        columns = list(read_frame(path).columns)
    except (LogError, OSError):
        return None
    if orientation_kind(columns) is None and "t" in columns:
        return None
    return (f"{Path(path).name} looks like a table of static poses (orientation columns or "
            f"no time column): identify payload and biases with `ftdrake calibrate --data "
            f"{path}` (add --robot/--sensor-frame for joint angles)")


# -- the gain/cross-talk correction -----------------------------------------------------------
def identify_correction(W_S, Y, structure="block", temperature=None,
                        rigid_residual_rms=None, *, known_payload=False, loads=1,
                        payload=None) -> CalibrationCorrection:
    """Fits ``Y ≈ M·W_S + b (+ k·ΔT)`` by linear least squares; C = M⁻¹ (module docstring).

    `W_S` (N, 6): the wrench each pose should give in S (gravity on the payload); `Y` (N, 6)
    the readings; `temperature` (N,) °C or None. Each row of M is one least-squares problem
    on the design ``[W_S (its block's columns), 1, ΔT]``, columns scaled to unit RMS; the
    deviation from the identity is the minimum-norm solution, so directions the design does
    not span (singular values below 1e-6 of the largest) stay uncorrected and their entries
    get an infinite standard error.
    """
    if structure not in CORRECTIONS:
        raise ConfigError(f"correction must be one of {list(CORRECTIONS)}, got {structure!r}")
    W_S, Y = np.asarray(W_S, float), np.asarray(Y, float)
    reference, d = _temperature_deviation(temperature)
    groups = ([[0, 1, 2], [3, 4, 5]] if structure == "block" else [list(range(6))])
    M, M_se = np.eye(6), np.zeros((6, 6))
    bias, bias_se = np.zeros(6), np.zeros(6)
    k, k_se = np.zeros(6), np.zeros(6)
    residual = np.empty_like(Y)
    per_row = {}  # row i → (its columns, covariance of its M entries, null directions)
    ranks, conditions, undetermined, free_directions = [], [], [], []
    for cols in groups:
        nc = len(cols)
        D = np.column_stack([W_S[:, cols], np.ones(len(Y))] + ([] if d is None else [d]))
        scale = np.sqrt(np.mean(D ** 2, axis=0))
        scale[scale == 0] = 1.0
        U, S, Vt = np.linalg.svd(D / scale, full_matrices=False)
        r = int(np.sum(S > _RANK_TOL * S[0]))
        ranks.append(r)
        conditions.append(float(S[0] / S[r - 1]))
        target = Y[:, cols] - W_S[:, cols]  # the deviation from the identity
        coef = (Vt[:r].T @ ((U[:, :r].T @ target) / S[:r, None])) / scale[:, None]
        residual[:, cols] = target - D @ coef
        sigma2 = np.sum(residual[:, cols] ** 2, axis=0) / max(len(Y) - r, 1)
        unit = Vt[:r].T / S[:r]
        unit = (unit @ unit.T) / np.outer(scale, scale)  # (DᵀD)⁺ in the original units
        null = (Vt[r:].T / scale[:, None])  # null directions of D, original units
        free = np.linalg.norm(Vt[r:].T, axis=1) > 1e-6 if r < D.shape[1] else \
            np.zeros(D.shape[1], bool)
        se_unit = np.where(free, np.inf, np.sqrt(np.maximum(np.diag(unit), 0.0)))
        for row, i in enumerate(cols):
            M[i, cols] += coef[:nc, row]
            M_se[i, cols] = np.sqrt(sigma2[row]) * se_unit[:nc]
            bias[i], bias_se[i] = coef[nc, row], np.sqrt(sigma2[row]) * se_unit[nc]
            if d is not None:
                k[i], k_se[i] = coef[nc + 1, row], np.sqrt(sigma2[row]) * se_unit[nc + 1]
            per_row[i] = (cols, sigma2[row] * unit[:nc, :nc], null[:nc])
        if r < D.shape[1]:
            undetermined.append(_describe_null(cols, null[:nc]))
            for v in null[:nc].T:
                if np.linalg.norm(v) > 0:
                    direction = np.zeros(6)
                    direction[cols] = v / np.linalg.norm(v)
                    free_directions.append(direction)
    C = np.linalg.inv(M)
    C_se = _inverse_std_errors(C, per_row)
    if undetermined:
        warnings.warn(
            "the poses do not determine the whole gain/cross-talk correction: "
            + "; ".join(undetermined) + ". Those directions are left uncorrected (standard "
            "error ∞); poses with other known loads (columns known_mass, known_com_x/y/z) "
            "determine them", ExcitationWarning, stacklevel=3)
    return CalibrationCorrection(
        structure=structure, matrix=C, std_errors=C_se, sensor_matrix=M,
        sensor_std_errors=M_se, bias=bias, bias_std_errors=bias_se,
        residual_rms=np.sqrt(np.mean(residual ** 2, axis=0)),
        rigid_residual_rms=(np.full(6, np.nan) if rigid_residual_rms is None
                            else np.asarray(rigid_residual_rms, float)),
        condition_number=max(conditions), rank=tuple(ranks), undetermined=undetermined,
        known_payload=known_payload, loads=int(loads),
        payload=None if payload is None else np.asarray(payload, float),
        temperature_reference=reference if d is not None else None,
        temperature_coefficients=k if d is not None else None,
        temperature_std_errors=k_se if d is not None else None,
        free_directions=np.array(free_directions).reshape(-1, 6))


def _uncorrected_rms(residual, temperature) -> np.ndarray:
    """Per-axis RMS of `residual` after the best constant (and temperature slope)."""
    _, d = _temperature_deviation(temperature)
    D = np.ones((len(residual), 1)) if d is None else np.column_stack([np.ones(len(d)), d])
    coef, *_ = np.linalg.lstsq(D, residual, rcond=None)
    return np.sqrt(np.mean((residual - D @ coef) ** 2, axis=0))


def _inverse_std_errors(C, per_row) -> np.ndarray:
    """Standard errors of C = M⁻¹ from those of M's rows (independent): dC = −C·dM·C, so
    var(C_ab) = Σ_i C_ai² · c_bᵀ Σ_i c_b with c_b column b of C on row i's columns; ∞ where
    a direction row i's data leave free moves C_ab."""
    se = np.zeros((6, 6))
    for b in range(6):
        for a in range(6):
            var, free = 0.0, False
            for i, (cols, cov, null) in per_row.items():
                if abs(C[a, i]) < 1e-12:
                    continue
                c = C[cols, b]
                var += C[a, i] ** 2 * float(c @ cov @ c)
                if null.size and np.any(np.abs(null.T @ c) > 1e-6 * np.linalg.norm(c)
                                        * np.linalg.norm(null, axis=0)):
                    free = True
            se[a, b] = np.inf if free else np.sqrt(max(var, 0.0))
    return se


def _describe_null(cols, null) -> str:
    """A sentence naming the wrench directions a block's data do not span."""
    names = [WRENCH_AXES[c] for c in cols]
    parts = []
    for v in null.T:
        if np.linalg.norm(v) == 0:
            continue
        v = v / np.linalg.norm(v)
        v = v * np.sign(v[np.argmax(np.abs(v))])
        parts.append("(" + ", ".join(f"{n} {x:+.2f}" for n, x in zip(names, v, strict=True)
                                     if abs(x) >= 0.005) + ")")
    what = ("torque" if cols[0] == 3 else "force") if len(cols) == 3 else "wrench"
    why = ("one load's torques are all perpendicular to its centre of mass"
           if what == "torque" else "the loads' forces and torques are tied (T = c × F)")
    return (f"the {what} correction along {len(parts)} direction(s) "
            f"{', '.join(parts)} ({why})")


def true_wrench(g_S: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """(N, 6) wrench ``[m·g_S; h × g_S]`` a payload at rest puts on the sensor, in S.

    `g_S` (N, 3) gravity in S (m/s²); `payload` ``[m, h]`` (4,) or one per row (N, 4), with
    ``h = m·c`` the first moment (kg·m) about So.
    """
    payload = np.broadcast_to(np.asarray(payload, float), (len(g_S), 4))
    return np.hstack([payload[:, :1] * g_S, np.cross(payload[:, 1:], g_S)])


def _known_payload(frame, known) -> tuple[np.ndarray | None, int]:
    """(N, 4) ``[m, m·c]`` per row from `known` (mass, com) or the table's known_* columns,
    and the number of distinct loads; (None, 1) when neither is given."""
    has_columns = KNOWN_MASS in frame
    if known is not None and has_columns:
        raise ConfigError(f"a known payload is given twice: as known_payload and as the "
                          f"table's {KNOWN_MASS!r} column; keep one")
    if known is None and not has_columns:
        return None, 1
    if has_columns:
        mass = _numeric(frame, [KNOWN_MASS])[:, 0]
        com = _numeric(frame, list(KNOWN_COM))
        where = f"column {KNOWN_MASS!r}"
    else:
        known = dict(known) if not isinstance(known, PayloadPrior) else {
            "mass": known.mass, "com": known.com}
        unknown = set(known) - {"mass", "com"}
        if unknown:
            raise ConfigError(f"known_payload: unknown fields {sorted(unknown)}; give mass "
                              "(kg) and com (m, from So in S)")
        mass = np.full(len(frame), float(known.get("mass", np.nan)))
        com = np.tile(np.asarray(known.get("com", (0.0, 0.0, 0.0)), float).reshape(1, 3),
                      (len(frame), 1))
        where = "known_payload.mass"
    if not np.all(np.isfinite(mass) & (mass > 0)):
        raise ConfigError(f"{where}: a known mass must be a positive number of kg, got "
                          f"{mass[~(np.isfinite(mass) & (mass > 0))][0]}")
    if not np.all(np.isfinite(com)):
        raise ConfigError("known centre of mass: must be three finite numbers (m)")
    payload = np.column_stack([mass, mass[:, None] * com])
    loads = len(np.unique(np.round(payload, 9), axis=0))
    return payload, loads


# -- helpers -------------------------------------------------------------------------------
def _se(e: float) -> str:
    return "∞" if not np.isfinite(e) else f"{e:.1e}"


def _static_regressor(g_S):
    zeros = np.zeros_like(g_S)
    return payload_regressor(zeros, zeros, -g_S)


def _com(theta, cov):
    m, h = theta[0], theta[1:4]
    J = np.hstack([-h[:, None] / m ** 2, np.eye(3) / m])
    return h / m, np.sqrt(np.maximum(np.diag(J @ cov[:4, :4] @ J.T), 0.0))


def _temperature_deviation(temperature):
    if temperature is None:
        return None, None
    reference = float(np.mean(temperature))
    d = temperature - reference
    return reference, (d if np.any(np.abs(d) > 1e-9) else None)


def _project_out(M, d):
    coef = np.tensordot(d, M, axes=(0, 0)) / (d @ d)
    return M - np.multiply.outer(d, coef)


def _joint_columns(frame, positions) -> list[str]:
    try:
        return expand_columns(positions, list(frame.columns), "joint position columns")
    except (LogError, ConfigError):
        return []


def _joint_layout(frame, joint_cols, position_unit="rad") -> np.ndarray:
    missing = [c for c in joint_cols if c not in frame]
    if missing:
        raise LogError(f"the table has no joint columns {missing}")
    q = _numeric(frame, joint_cols)
    if position_unit == "deg":
        q = np.radians(q)
    return np.hstack([q, np.zeros((len(q), 2 * q.shape[1]))])


def _numeric(frame, names) -> np.ndarray:
    missing = [n for n in names if n not in frame]
    if missing:
        raise LogError(f"the table has no column(s) {missing}")
    values = frame[list(names)].to_numpy(dtype=float)
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise LogError(f"columns {list(names)}: NaN or empty in {bad.sum()} rows (first at row "
                       f"{int(np.flatnonzero(bad)[0])})")
    return values

