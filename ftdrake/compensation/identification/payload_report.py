"""What a fitted payload model identified, as a table and as lines a user reads, and the
warning when the data do not excite its parameters (:class:`ExcitationWarning`).

The functions take a fitted :class:`~..estimators.physics.PhysicsPayloadCompensator` (its
``identified()``, ``summary()`` and fit call them).
"""

from __future__ import annotations

import warnings

import numpy as np
from pydrake.math import RollPitchYaw, RotationMatrix

from ...errors import spelled
from .consistent import PARAMETER_NAMES, STATIC_PARAMETERS

#: The excitation warning's advice (:func:`excitation_message`) and what it becomes for a
#: command-line user.
_PYTHON_ADVICE = ("give a prior (identification='consistent', prior=PayloadPrior(...)) or "
                  "use a richer trajectory (e.g. kind 'fourier' or 'z_rich')")
_CLI_ADVICE = ("record a log in which every joint moves, faster and through more of its "
               "range, so that the tool turns through more orientations; or identify the "
               "payload from static poses with `ftdrake calibrate` (which also takes a prior "
               "of its mass and centre of mass)")


class ExcitationWarning(UserWarning):
    """The data does not determine some payload parameters well."""

#: The unit of each entry of θ (:data:`~.consistent.PARAMETER_NAMES`).
PARAMETER_UNITS = (["kg", "kg*m", "kg*m", "kg*m"] + ["kg*m^2"] * 6 + ["N"] * 3 + ["N*m"] * 3
                   + ["kg", "kg*m", "kg*m", "kg*m"] + ["N/m", "N"])


def identified_table(model) -> dict:
    """Identified parameters with standard errors and units, plus derived CoM (m).

    Each parameter: ``value``, ``std_error`` (∞ where the data leave it free and no prior
    decides it), ``unit`` and ``prior_share`` (how much the prior decided it, 0–1; 0
    without a prior). Also ``com`` (``p_SoScm_S``, m, with standard errors by the delta
    method), ``condition_number``, ``identification``, ``physically_consistent``,
    ``not_determined`` (parameters the data cannot determine) and, for the consistent
    fit, ``least_squares`` (the unconstrained estimate and whether it is a body).
    """
    p, se = model.parameters_, model.standard_errors_
    result = getattr(model, "identification_", None)
    share = result.prior_share if result is not None else np.zeros(len(p))
    table = {
        name: {"value": float(p[i]), "std_error": float(se[i]), "unit": PARAMETER_UNITS[i],
               "prior_share": float(np.nan_to_num(share[i]))}
        for i, name in enumerate(PARAMETER_NAMES[:len(p)])
        if model.mode == "dynamic" or i in STATIC_PARAMETERS
    }
    mass = p[0]
    com_se = None
    cov = getattr(model, "covariance_", None)
    if mass and cov is not None and np.all(np.isfinite(cov[:4, :4])):
        # c = h / m: Jacobian [−h/m², I/m] on (m, h).
        J = np.hstack([-p[1:4, None] / mass ** 2, np.eye(3) / mass])
        com_se = np.sqrt(np.maximum(np.diag(J @ cov[:4, :4] @ J.T), 0.0)).tolist()
    table["com"] = {"value": (p[1:4] / mass).tolist() if mass else None,
                    "std_error": com_se, "unit": "m"}
    rotation = getattr(model, "mounting_rotation_", None)
    if rotation is not None and model.identify_mounting:
        table["mounting_rpy_deg"] = {
            "value": np.degrees(RollPitchYaw(RotationMatrix(rotation)).vector()).tolist(),
            "std_error": model.mounting_std_deg_.tolist(), "unit": "deg",
            "frame": "R_SSm: the frame the sensor measures in, in S (roll, pitch, yaw)"}
    crosstalk = getattr(model, "crosstalk_", None)
    if crosstalk is not None:
        table["crosstalk"] = {
            "value": crosstalk.tolist(), "unit": "1 (forces from forces, torques from torques), "
            "N/(N*m) (forces from torques), m (torques from forces)",
            "meaning": ("E in the reading matrix M = (I + E)·R_SmS: reading = M·W_S + b; "
                        "free motion determines only some combinations of E's entries, the "
                        "prior (±2 %) keeps the others near zero")}
    if getattr(model, "temperature_reference_", None) is not None:
        table["temperature"] = {
            "coefficients": model.temperature_coefficients_.tolist(),
            "std_error": model.temperature_std_errors_.tolist(),
            "unit": "N/K (forces), N*m/K (torques)",
            "reference_c": model.temperature_reference_}
    if getattr(model, "tether_frame_", None) is not None:
        k, k_rest = p[20], p[21]
        table["tether"] = {
            "frame": model.tether_frame_,
            "anchor": {"value": model.tether_anchor_.tolist(), "unit": "m",
                       "frame": "the child frame M of joint `frame` (or the world)"},
            "attach": {"value": model.tether_attach_.tolist(), "unit": "m", "frame": "S"},
            "rest_length": {"value": float(k_rest / k) if k else None, "unit": "m"},
            "residual_share_by_frame": dict(model.tether_search_),
            "meaning": ("tension k·(length − rest_length) from the attach point towards the "
                        "anchor; residual_share_by_frame: the weighted residual sum of squares "
                        "left with the tether's far end in each frame tried, against none")}
    factor = getattr(model, "standard_error_factor_", None)
    if factor is not None:
        finite = factor[np.isfinite(factor)]
        table["correlated_rows"] = {
            "window_rows": int(model.correlation_window_),
            "standard_error_factor": float(np.median(finite)) if finite.size else 1.0,
            "meaning": ("standard errors widened by this factor (median over the parameters) "
                        "because the rows of a time series are not independent: overlapping "
                        "batch means over windows of window_rows rows")}
    table["condition_number"] = model.condition_number_
    table["identification"] = getattr(model, "identification", "least_squares")
    table["physically_consistent"] = bool(getattr(model, "physically_consistent_", True))
    table["not_determined"] = list(result.poorly_determined) if result is not None else []
    if result is not None and model.identification == "consistent":
        cols = STATIC_PARAMETERS if model.mode == "static" else list(range(len(p)))
        table["least_squares"] = {
            "values": {PARAMETER_NAMES[i]: float(result.theta_least_squares[i])
                       for i in cols},
            "physically_consistent": bool(result.least_squares_consistent)}
    if result is not None:
        table["active_constraints"] = list(result.active_constraints)
    return table


def summary_text(model) -> str:
    """The identified parameters with standard errors, as lines a user reads."""
    t = identified_table(model)
    how = {"least_squares": "weighted least squares",
           "consistent": "least squares over physically possible bodies (SDP)"}
    lines = [(f"payload identified by {how.get(t['identification'], t['identification'])} "
              f"({model.mode} model; condition number {t['condition_number']:.3g})"),
             f"  {'':5s} {'value':>12s} {'std error':>10s} {'unit':<7s} prior share"]
    for name in PARAMETER_NAMES:
        if name in t and isinstance(t[name], dict) and "prior_share" in t[name]:
            row = t[name]
            lines.append(f"  {name:5s} {row['value']:12.5g} {row['std_error']:10.3g} "
                         f"{row['unit']:<7s} {row['prior_share']:.2f}")
    com = t["com"]
    if com["value"] is not None:
        se = com["std_error"] or [np.nan] * 3
        lines.append("  centre of mass p_SoScm_S: "
                     + ", ".join(f"{1e3 * v:.2f} ± {1e3 * e:.2f}"
                                 for v, e in zip(com["value"], se, strict=True)) + " mm")
    if "mounting_rpy_deg" in t:
        m = t["mounting_rpy_deg"]
        lines.append("  sensor mounting R_SSm roll, pitch, yaw: " + ", ".join(
            f"{v:.3f} ± {e:.3f}" for v, e in zip(m["value"], m["std_error"], strict=True))
            + " deg")
    if "crosstalk" in t:
        E = np.asarray(t["crosstalk"]["value"])
        lines.append(f"  cross-talk E (reading = (I + E)·R_SmS·W_S + b), largest: forces from "
                     f"forces {np.abs(E[:3, :3]).max():.4f}, torques from torques "
                     f"{np.abs(E[3:, 3:]).max():.4f}, forces from torques "
                     f"{np.abs(E[:3, 3:]).max():.3f} N/(N·m), torques from forces "
                     f"{1e3 * np.abs(E[3:, :3]).max():.2f} mm")
    if "temperature" in t:
        k = t["temperature"]
        lines.append(f"  zero drift per K (Fx..Tz, about {k['reference_c']:.2f} °C): "
                     + ", ".join(
            f"{v:.4g} ± {e:.2g}" for v, e in zip(k["coefficients"], k["std_error"],
                                                  strict=True)))
    if "tether" in t:
        tether, share = t["tether"], t["tether"]["residual_share_by_frame"]
        rest = tether["rest_length"]["value"]
        lines.append(
            f"  tether from Q = ({', '.join(f'{1e3 * v:.1f}' for v in tether['attach']['value'])}"
            f") mm in S to P = ({', '.join(f'{1e3 * v:.1f}' for v in tether['anchor']['value'])}"
            f") mm after {tether['frame']}, rest length "
            + ("?" if rest is None else f"{1e3 * rest:.0f} mm")
            + "; residual left by frame: "
            + ", ".join(f"{name} {v:.3f}" for name, v in sorted(share.items(),
                                                                 key=lambda item: item[1])))
    if t.get("correlated_rows", {}).get("standard_error_factor", 1.0) > 1.05:
        c = t["correlated_rows"]
        lines.append(f"  standard errors ×{c['standard_error_factor']:.2g} (median) for "
                     f"correlated rows: the residual stays correlated over ~"
                     f"{max(1, c['window_rows'] // 3)} rows, so the rows count as fewer "
                     "independent samples")
    lines.append(f"  physically possible body: {'yes' if t['physically_consistent'] else 'NO'}"
                 + ("" if "least_squares" not in t else
                    f" (plain least squares: "
                    f"{'yes' if t['least_squares']['physically_consistent'] else 'no'})"))
    if "weight_without_inertia >= 0" in t.get("active_constraints", ()):
        lines.append("  mw is on its bound 0: a weight carried without inertia cannot be "
                     "negative, and the data pull it below (no hanging weight; or an upward "
                     "pull the model does not have)")
    lines.append(f"  not determined by the data: {', '.join(t['not_determined']) or 'none'}")
    return "\n".join(lines)


def excitation_message(model) -> str | None:
    """What the warning says when the data do not excite the payload parameters well
    (condition number above 1e4, or parameters the data cannot determine); None otherwise."""
    result = model.identification_
    # Only the inertial parameters can be "poorly excited"; a bias named here is one the
    # data determine only in a combination with the mass (a constant gravity direction).
    poor = list(result.poorly_determined)
    if model.condition_number_ <= 1e4 and not poor:
        return None
    share = result.prior_share
    if model.prior is not None and model.identification == "consistent":
        decided = ", ".join(f"{n} {share[PARAMETER_NAMES.index(n)]:.0%}" for n in poor
                            if n in PARAMETER_NAMES[:10])
        how = f"the prior decided (share of each estimate): {decided or 'none'}"
    else:
        how = _PYTHON_ADVICE
    return (f"the data does not excite the payload parameters well (condition number "
            f"{model.condition_number_:.3g}); not determined by the data (a null direction of "
            f"the regressor, or standard error > 25% of its group's scale): "
            f"{', '.join(poor) or 'none'}; {how}")


def warn_if_poorly_excited(model, stacklevel: int) -> None:
    """Warns (:class:`ExcitationWarning`, :func:`excitation_message`) when the data do not
    excite the fitted `model`'s parameters well; `stacklevel` as ``warnings.warn``'s, counted
    from the caller."""
    message = excitation_message(model)
    if message is not None:
        # The command line has no prior and no simulator kinds: it gets its own advice.
        message = message.replace(_PYTHON_ADVICE, spelled(_PYTHON_ADVICE, _CLI_ADVICE))
        warnings.warn(message, ExcitationWarning, stacklevel=stacklevel + 1)
