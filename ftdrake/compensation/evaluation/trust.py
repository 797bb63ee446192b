"""Which predictions not to trust, and why: the rows a compensator predicts outside what it
was trained on.

A row's prediction is flagged *per target* when the predictive std of that target exceeds
:data:`~.metrics.UNCERTAIN_STD_FACTOR` × the model's residual on its training rows (the model
lacks data there; models with a calibrated std that keep ``residual_rms_``: the GP, physics,
the arm), or when the prediction lies outside the training range of its target widened by
:data:`~.metrics.TARGET_RANGE_MARGIN` (extrapolating). A row with a used input outside its
training range flags every target only for a model without such a std (a black box, which
cannot tell how far it may extrapolate); a model with one says per target, through its std,
whether an input outside the range matters — a physics model extrapolates by construction, so
an input a little outside the range need not make any prediction untrustworthy.
:func:`assess_trust` gives the share of rows flagged per target and cause, and one warning
line per cause that flags more than :data:`UNTRUSTED_WARN_FRACTION` of some target's rows.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .metrics import TARGET_RANGE_MARGIN, UNCERTAIN_STD_FACTOR

#: A cause flagging more than this share of some target's rows gets a warning line.
UNTRUSTED_WARN_FRACTION = 0.1

_SAID = {
    "inputs_outside_range": "inputs outside the training range",
    "std_above_factor_x_residual": (f"predictive std > {UNCERTAIN_STD_FACTOR:g}× the "
                                    "training residual (the model lacks data there)"),
    "prediction_outside_target_range": (f"predictions beyond the training range of the "
                                        f"target (±{100 * TARGET_RANGE_MARGIN:.0f} %)"),
}


def trust_references(model, target_names, std, target_ranges: Mapping | None = None):
    """(residual, target_range): what predictions are compared with to flag them.

    residual: the model's RMS residual on its training rows, per target (models with a
    calibrated std that keep ``residual_rms_``), else None. target_range: ``(low, high)``
    per target from `target_ranges` (target name → ``[low, high]``, as a model file's
    manifest keeps them), or None when it does not name every target.
    """
    residual = None
    if std is not None and getattr(model, "std_includes_noise", False):
        value = getattr(model, "residual_rms_", None)
        if value is not None and np.size(value) == len(target_names):
            residual = np.asarray(value, dtype=float)
    target_range = None
    if isinstance(target_ranges, Mapping) and all(n in target_ranges for n in target_names):
        target_range = tuple(np.array([target_ranges[n][i] for n in target_names],
                                      dtype=float) for i in (0, 1))
    return residual, target_range


def assess_trust(target_names, prediction, std, outside, residual=None,
                 target_range=None, inputs_flag: bool | None = None) -> dict:
    """Per target, the share of rows whose prediction should not be trusted, and why.

    prediction, std: (N, k) (std None for a model without one); outside: (N,) bool, rows
    with a used input outside its training range; residual, target_range: from
    :func:`trust_references`. `inputs_flag`: whether inputs outside the range flag every
    target (None: only when there is no calibrated std to decide per target). Returns a
    JSON-ready dict: ``untrusted_fraction`` and ``by_cause`` (per target, 0–1),
    ``flagging_causes`` (the causes that flag), ``explanation`` (the rule in words), the
    factors used, ``residual_rms`` and ``warnings`` (lines a user reads; empty when nothing
    crosses :data:`UNTRUSTED_WARN_FRACTION`).
    """
    names = list(target_names)
    k = len(names)
    causes = {"inputs_outside_range": np.repeat(outside[:, None], k, axis=1)}
    if std is not None and residual is not None:
        causes["std_above_factor_x_residual"] = std > UNCERTAIN_STD_FACTOR * residual
    if target_range is not None:
        lo, hi = target_range
        pad = TARGET_RANGE_MARGIN * (hi - lo)
        causes["prediction_outside_target_range"] = ((prediction < lo - pad)
                                                     | (prediction > hi + pad))
    if inputs_flag is None:
        inputs_flag = "std_above_factor_x_residual" not in causes
    flagging = [c for c in causes if inputs_flag or c != "inputs_outside_range"]
    flagged = np.logical_or.reduce([causes[c] for c in flagging] + [np.zeros((len(outside), k),
                                                                            bool)])
    share = {cause: dict(zip(names, np.round(rows.mean(axis=0), 4).tolist(), strict=True))
             for cause, rows in causes.items()}
    return {
        "flagging_causes": flagging,
        "explanation": _explanation(flagging, inputs_flag),
        "uncertain_std_factor": UNCERTAIN_STD_FACTOR if "std_above_factor_x_residual" in causes
        else None,
        "target_range_margin": TARGET_RANGE_MARGIN,
        "residual_rms": None if residual is None else dict(
            zip(names, residual.round(6).tolist(), strict=True)),
        "untrusted_fraction": dict(zip(names, np.round(flagged.mean(axis=0), 4).tolist(),
                                       strict=True)),
        "by_cause": share,
        "warnings": _warnings(outside, share, inputs_flag),
    }


def _explanation(flagging, inputs_flag) -> str:
    said = "; ".join(_SAID[c] for c in flagging)
    text = f"a row's prediction of a target is flagged for: {said}"
    if not inputs_flag:
        text += (" (inputs outside the training range are counted but flag nothing on their "
                 "own: the model's predictive std says per target whether it lacks data "
                 "there)")
    return text


def _warnings(outside, share, inputs_flag=True) -> list[str]:
    warnings = []
    if outside.mean() > UNTRUSTED_WARN_FRACTION:
        warnings.append(f"warning: {_SAID['inputs_outside_range']} on "
                        f"{100 * outside.mean():.0f} % of rows"
                        + ("" if inputs_flag else "; each target's predictive std decides "
                           "whether its predictions there are trusted"))
    for cause, per_target in list(share.items())[1:]:
        worst = {n: v for n, v in per_target.items() if v > UNTRUSTED_WARN_FRACTION}
        if worst:
            listed = ", ".join(f"{n} {100 * v:.0f} %" for n, v in worst.items())
            warnings.append(f"warning: {_SAID[cause]} on {listed} of rows")
    if len(warnings) > (0 if inputs_flag else int(outside.mean() > UNTRUSTED_WARN_FRACTION)):
        warnings.append("warning: predictions on flagged rows cannot be trusted; see "
                        "'trust' in --json (share of rows flagged per target and cause)")
    return warnings
