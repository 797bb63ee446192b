"""Calibration of a wrist F/T sensor from a table of static poses (``ftdrake calibrate``).

A calibration log is often not a time series but a table: each row one pose held still and
the wrench read there (velocities zero, nothing to differentiate, often no time column;
:mod:`.static_table` reads it). The sensor's orientation comes either

* as **joint angles** with a robot description (URDF/SDF and the sensor frame): the
  identified model is a static :class:`~..estimators.physics.PhysicsPayloadCompensator`
  (gravity only), which also identifies the sensor's mounting rotation ``R_SSm`` (the frame the
  sensor measures in) and is saved as a model file ``evaluate`` and the station use; or
* **directly as a rotation** (:data:`~.static_table.ORIENTATIONS`): the mounting rotation is
  then absorbed in the orientation (the rotation given *is* the one of the measuring frame, as
  far as the data can tell) and is not identified.

Static poses determine the mass, the first moment ``m·c`` (so the centre of mass) and the six
biases — not the inertia, which only acceleration excites: a static calibration says so and
leaves it out. With a ``temperature`` column (°C) the per-axis zero drift per kelvin is
identified as well. Every parameter comes with its standard error; the fit is the physically
consistent one (mass > 0; optional prior) of :mod:`ftdrake.compensation.identification.consistent`.
``correction="block"`` or ``"full"`` also identifies the sensor's gain/cross-talk correction
(:mod:`.correction`; several known loads: the table columns ``known_mass``,
``known_com_x/y/z`` per row).

:func:`calibrate_table` returns a :class:`StaticCalibration` with :meth:`~StaticCalibration.
to_dict` (what the YAML holds), :meth:`~StaticCalibration.summary` and
:meth:`~StaticCalibration.predict` (the reading at held-out poses of a table).
"""

from __future__ import annotations

import dataclasses as dc
import warnings

import numpy as np
import pandas as pd

from ...conventions import GRAVITY_W, MEASURED, TEMPERATURE, WRENCH_AXES
from ...data.logs import expand_columns, option_hint
from ...errors import ConfigError, LogError, option_name
from ..estimators.physics import ExcitationWarning, PhysicsPayloadCompensator, payload_regressor
from ..identification.consistent import PayloadPrior, identify_consistent, identify_least_squares
from ..identification.payload_identification import project_out
from ..identification.regression import correlated_variance_ratio
from .correction import (
    CORRECTIONS,
    CalibrationCorrection,
    identify_correction,
    temperature_deviation,
    true_wrench,
    uncorrected_rms,
)
from .static_table import (
    KNOWN_COM,
    KNOWN_MASS,
    ORIENTATIONS,
    gravity_in_sensor,
    joint_columns,
    joint_layout,
    known_payload_rows,
    numeric_columns,
    orientation_kind,
    static_table_hint,
)

__all__ = [  # with the table reader's and the correction's names callers take from here
    "CORRECTIONS", "KNOWN_COM", "KNOWN_MASS", "NOT_IDENTIFIABLE", "ORIENTATIONS",
    "STATIC_NAMES", "STATIC_UNITS", "CalibrationCorrection", "StaticCalibration",
    "calibrate_table", "gravity_in_sensor", "identify_correction", "orientation_kind",
    "static_table_hint", "true_wrench",
]

STATIC_NAMES = ("m", "mcx", "mcy", "mcz", "bFx", "bFy", "bFz", "bTx", "bTy", "bTz")
STATIC_UNITS = ("kg", "kg*m", "kg*m", "kg*m", "N", "N", "N", "N*m", "N*m", "N*m")
NOT_IDENTIFIABLE = ("static poses determine the mass, the first moment m·c (so the centre of "
                    "mass) and the biases; the inertia needs motion (a dynamic log, trained "
                    "on with kind physics)")


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
    covariance: np.ndarray | None = None  # (10, 10) of `parameters`
    #: How the default (``correction="auto"``) chose: {candidate: per-axis cross-validated
    #: RMS}, the choice and why, or None when a correction was asked for by name.
    choice: dict | None = None

    def gravity_in_sensor(self, frame: pd.DataFrame) -> np.ndarray:
        """(N, 3) gravity in S (m/s²) at the poses of `frame`, from the same kind of columns
        (joint angles through the robot, or the orientation columns)."""
        if self.model is not None:
            X = joint_layout(frame, list(self.positions), self.position_unit)
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
            temperature = numeric_columns(frame, [TEMPERATURE])[:, 0]
        if self.correction is not None and corrected:
            payload = self.correction.payload
            if payload is None:  # fitted with a known payload per row: the table gives it
                payload, _ = known_payload_rows(frame, None)
                if payload is None:
                    raise LogError(f"the correction was fitted with a known payload per row; "
                                   f"the table needs the columns {KNOWN_MASS}, "
                                   f"{', '.join(KNOWN_COM)}")
            return self.correction.reading(true_wrench(self.gravity_in_sensor(frame), payload),
                                           temperature)
        if self.model is not None:
            X = joint_layout(frame, list(self.positions), self.position_unit)
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
        if self.choice is not None:
            table["correction_choice"] = self.choice
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
        if self.choice is not None:
            lines.extend(_choice_lines(self.choice, self.correction))
        if self.correction is not None:
            lines.extend(self.correction.summary())
        lines.append(f"  note: {NOT_IDENTIFIABLE}")
        return "\n".join(lines)


def _wrench_columns_label() -> str:
    """How a wrench-column error names the option that picks them (a flag on the command
    line, a keyword in Python)."""
    return f"wrench columns (choose them with {option_hint('targets', 'PAT')})"


def calibrate_table(frame: pd.DataFrame, *, robot=None, sensor_frame=None, base_frame=None,
                    positions="q_*", targets=f"{MEASURED}_*", position_unit="rad",
                    prior=None, identification="consistent", identify_mounting=True,
                    gravity=GRAVITY_W, correction=None,
                    known_payload=None, joints=None, fixed_joints=None) -> StaticCalibration:
    """Identifies payload, biases (and mounting, temperature coefficients) from static poses.

    `frame`: one row per pose; 6 wrench columns (`targets`) and either joint angles
    (`positions`, with `robot`/`sensor_frame`; ``robot="ftdrake"`` or None with joint columns
    present: ftdrake's simulated arm) or orientation columns (:data:`ORIENTATIONS`); a
    ``temperature`` column (°C) adds temperature coefficients. `prior`: a
    :class:`~..identification.consistent.PayloadPrior` or mapping (its mass must be positive).
    `correction` (``"block"``, ``"full"``): also identify the sensor's gain/cross-talk
    correction (module docstring) against the wrench of a `known_payload` (mapping with
    ``mass`` kg and ``com`` m, in S; or the table's ``known_mass``, ``known_com_x/y/z``
    columns, one payload per row) or, without one, of the payload identified here.
    `joints`, `fixed_joints`: which joints of `robot` the position columns hold and where the
    others stand (as :class:`~ftdrake.compensation.estimators.physics.PhysicsPayloadCompensator`'s).
    Raises LogError/ConfigError/RobotModelError naming the column, field or frame at fault.
    """
    if correction is not None and correction not in (*CORRECTIONS, "auto"):
        raise ConfigError(f"correction must be one of {[*CORRECTIONS, 'auto']} or None, got "
                          f"{correction!r}")
    if correction in (None, "auto") and known_payload is not None:
        raise ConfigError("known_payload is used by the gain/cross-talk correction: give "
                          "correction='block' or 'full'")
    cal = _calibrate(frame, robot, sensor_frame, base_frame, positions, targets,
                     position_unit, prior, identification, identify_mounting, gravity,
                     (joints, fixed_joints))
    if correction == "auto":
        correction, cal.choice = choose_correction(cal, frame, targets)
    if correction is None:
        return cal
    payload, loads = known_payload_rows(frame, known_payload)
    known = payload is not None
    if not known:
        payload = np.tile(cal.parameters[:4], (len(frame), 1))
    Y = numeric_columns(frame, expand_columns(targets, list(frame.columns),
                                              _wrench_columns_label()))
    temperature = numeric_columns(frame, [TEMPERATURE])[:, 0] if TEMPERATURE in frame else None
    W_S = true_wrench(cal.gravity_in_sensor(frame), payload)
    # The comparison without correction: the gravity + bias fit above, or, with a known
    # payload, its wrench plus the best bias (and temperature drift).
    rigid = cal.residual_rms if not known else uncorrected_rms(Y - W_S, temperature)
    cal.correction = identify_correction(
        W_S, Y, correction, temperature, rigid, known_payload=known, loads=loads,
        # One payload for every row (identified or given): kept for predicting held-out
        # poses. Known payloads from the table's columns are read from each table.
        payload=None if known and KNOWN_MASS in frame else payload[0])
    return cal


#: ``correction="auto"`` needs this many poses per parameter of a corrected axis (7 for the
#: full 6 × 6: six entries and a bias) to compare the candidates by cross-validation.
AUTO_ROWS_PER_PARAMETER = 4
#: Folds of the cross-validation that chooses the correction.
AUTO_FOLDS = 5
#: A richer candidate is chosen only when its cross-validated error (geometric mean over
#: the axes of the per-axis MSE) is below this fraction of the simpler one's.
AUTO_GAIN = 0.9


def choose_correction(cal: StaticCalibration, frame, targets) -> tuple[str | None, dict]:
    """The correction the data support, by 5-fold cross-validation over the poses: gravity +
    bias (None), ``"block"`` or ``"full"``, each refitted on the other folds (payload by
    least squares, then the correction against its wrench) and scored on the held-out poses.
    The richest candidate whose error (geometric mean of the per-axis MSE) is below
    :data:`AUTO_GAIN` × the simpler choice's wins. Returns (choice, {"cv_rms": {candidate:
    per-axis RMS}, "choice", "why"}). Several known loads per row, a temperature column or
    too few poses keep gravity + bias (said in "why")."""
    if KNOWN_MASS in frame:
        return None, {"choice": "none", "why": "the table holds known loads: name the "
                      "correction (block or full) to use them"}
    if TEMPERATURE in frame:
        return None, {"choice": "none", "why": "the table has a temperature column: name "
                      "the correction (block or full) to fit it with the drift"}
    if len(frame) < AUTO_ROWS_PER_PARAMETER * 7 * AUTO_FOLDS / (AUTO_FOLDS - 1):
        return None, {"choice": "none", "why": f"{len(frame)} poses are too few to tell a "
                      "correction from noise by cross-validation"}
    Y = numeric_columns(frame, expand_columns(targets, list(frame.columns),
                                              _wrench_columns_label()))
    g_S = cal.gravity_in_sensor(frame)
    A = _static_regressor(g_S)[:, :, [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]]
    folds = np.arange(len(Y)) % AUTO_FOLDS
    np.random.default_rng(0).shuffle(folds)
    errors = {name: np.zeros_like(Y) for name in ("none", "block", "full")}
    for k in range(AUTO_FOLDS):
        train, test = folds != k, folds == k
        payload = identify_least_squares(A[train], Y[train], static=True).theta[
            [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]]
        errors["none"][test] = Y[test] - A[test] @ payload
        W_train, W_test = (true_wrench(g_S[rows], payload[:4]) for rows in (train, test))
        for name in ("block", "full"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ExcitationWarning)  # free directions: fine
                fitted = identify_correction(W_train, Y[train], name)
            errors[name][test] = Y[test] - fitted.reading(W_test)
    rms = {name: np.sqrt(np.mean(e ** 2, axis=0)) for name, e in errors.items()}
    score = {name: float(np.exp(np.mean(np.log(np.maximum(r, 1e-300) ** 2))))
             for name, r in rms.items()}
    choice = "none"
    for name in ("block", "full"):
        if score[name] < AUTO_GAIN * score[choice]:
            choice = name
    why = (f"cross-validated ({AUTO_FOLDS} folds) error of {choice} is the lowest"
           if choice != "none" else "no correction lowers the cross-validated error by "
           f"{100 * (1 - AUTO_GAIN):.0f} %")
    return (None if choice == "none" else choice), {
        "cv_rms": {name: r.tolist() for name, r in rms.items()}, "choice": choice,
        "why": why}


def _calibrate(frame, robot, sensor_frame, base_frame, positions, targets, position_unit,
               prior, identification, identify_mounting, gravity,
               mapping=(None, None)) -> StaticCalibration:
    """calibrate_table without the correction."""
    prior = PayloadPrior.coerce(prior)
    target_cols = expand_columns(targets, list(frame.columns), _wrench_columns_label())
    if len(target_cols) != 6:
        raise LogError(f"need 6 wrench columns (Fx..Tz); {targets!r} matches {target_cols}")
    Y = numeric_columns(frame, target_cols)
    temperature = numeric_columns(frame, [TEMPERATURE])[:, 0] if TEMPERATURE in frame else None
    kind = orientation_kind(frame.columns)
    joint_cols = joint_columns(frame, positions)
    if joint_cols and (robot is not None or kind is None):
        return _calibrate_joint_angles(frame, joint_cols, Y, temperature, robot, sensor_frame,
                                       base_frame, position_unit, prior, identification,
                                       identify_mounting, gravity, mapping)
    if kind is None:
        raise LogError("no orientation in the table: give joint angles (columns "
                       f"{positions!r}) with {option_name('robot')} and "
                       f"{option_name('sensor_frame')}, or one of the column "
                       "sets " + "; ".join(", ".join(c if len(c) < 5 else (c[0], "…", c[-1]))
                                             for c in ORIENTATIONS.values()))
    g_S = gravity_in_sensor(frame, kind, gravity)
    A = _static_regressor(g_S)
    cols = [0, 1, 2, 3, 10, 11, 12, 13, 14, 15]
    reference, d = temperature_deviation(temperature)
    A_fit, Y_fit = (A, Y) if d is None else (project_out(A, d), project_out(Y, d))
    if identification == "consistent":
        result = identify_consistent(A_fit[:, :, cols], Y_fit, static=True,
                                     prior=None if prior is None else prior.phi())
    else:
        result = identify_least_squares(A_fit[:, :, cols], Y_fit, static=True)
    theta = result.theta[cols]
    # Rows that are a time series of held poses are not independent: widen the errors.
    ratio, _ = correlated_variance_ratio(A_fit[:, :, cols] * result.weights[None, :, None],
                                         (Y_fit - A_fit[:, :, cols] @ theta) * result.weights)
    factor = np.sqrt(ratio)
    cov = result.covariance[np.ix_(cols, cols)] * np.outer(factor, factor)
    residual = Y - A[:, :, cols] @ theta
    k = se_k = None
    if d is not None:
        k = residual.T @ d / (d @ d)
        residual = residual - np.outer(d, k)
        se_k = np.sqrt(np.mean(residual ** 2, axis=0)) / np.sqrt(d @ d)
    com, com_se = _com(theta, cov)
    return StaticCalibration(
        source=kind, parameters=theta, standard_errors=result.standard_errors[cols] * factor,
        com=com,
        covariance=cov,
        com_std_error=com_se, residual_rms=np.sqrt(np.mean(residual ** 2, axis=0)),
        condition_number=float(result.condition_number), rows=len(frame),
        temperature_reference=reference, temperature_coefficients=k,
        temperature_std_errors=se_k, gravity=tuple(gravity))


def _calibrate_joint_angles(frame, joint_cols, Y, temperature, robot, sensor_frame,
                            base_frame, position_unit, prior, identification,
                            identify_mounting, gravity, mapping=(None, None)):
    if robot in (None, "ftdrake"):
        robot = sensor_frame = None
    elif not sensor_frame:
        raise ConfigError(f"{option_name('robot')} {robot} needs {option_name('sensor_frame')} "
                          "(the frame of the wrench)")
    X = joint_layout(frame, joint_cols, position_unit)
    if temperature is not None:
        X = np.column_stack([X, temperature])
    model = PhysicsPayloadCompensator(
        features="q", mode="static", robot=robot, sensor_frame=sensor_frame,
        base_frame=base_frame, gravity=tuple(gravity), identification=identification,
        prior=prior, identify_mounting=identify_mounting, joints=mapping[0],
        fixed_joints=mapping[1])
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
        covariance=cov,
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


# -- helpers -------------------------------------------------------------------------------


def _choice_lines(choice: dict, correction=None) -> list[str]:
    """How the default chose the correction, as lines a user reads; when the chosen
    correction's entries are not all determined, what the choice rests on."""
    lines = [f"  correction chosen from the data: {choice['choice']} ({choice['why']})"]
    for name, rms in choice.get("cv_rms", {}).items():
        lines.append(f"    cross-validated RMS (Fx..Tz), {name:5s}: "
                     + ", ".join(f"{r:.3g}" for r in rms))
    free = None if correction is None else correction.free_entries()
    if free is not None and free.any():
        fixed = (correction.sensor_std_errors == 0) & (correction.sensor_matrix == 0)
        lines.append(
            f"    chosen for what these poses determine — the correction's effect on this "
            f"payload's readings, which the cross-validation scored — not for its entries one "
            f"by one: {int(free.sum())} of {int((~fixed).sum())} are not determined (below, "
            "'free'). It corrects readings of this payload; for other loads, calibrate with "
            "poses of other known loads")
    return lines


def _static_regressor(g_S):
    zeros = np.zeros_like(g_S)
    return payload_regressor(zeros, zeros, -g_S)


def _com(theta, cov):
    m, h = theta[0], theta[1:4]
    J = np.hstack([-h[:, None] / m ** 2, np.eye(3) / m])
    return h / m, np.sqrt(np.maximum(np.diag(J @ cov[:4, :4] @ J.T), 0.0))
