"""Which predictions not to trust, and why: one meaning for every kind of model.

A row's prediction of a target is *untrusted* when the model cannot vouch that its error there
is like its error where it had training data:

* a model with a calibrated predictive std of a reading (physics, hybrid, GP, arm) says so
  itself: its std there exceeds :data:`~.metrics.UNCERTAIN_STD_FACTOR` × its *in-domain std*,
  its RMS error on its own training rows (:func:`in_domain_std`; the same quantity for every
  kind: a hybrid's is that of physics and residual together). An input outside the training
  range is counted but flags nothing on its own: the std says per target whether it
  matters (a physics part extrapolates by construction);
* a model without one (a forest's spread across trees, an SVR) cannot say how far it may
  extrapolate: a row with a used input outside its training range flags every target;
* for every model, a prediction beyond the training range of its target widened by
  :data:`~.metrics.TARGET_RANGE_MARGIN` is flagged (extrapolating).

:func:`assess_trust` gives the share of rows flagged per target and cause, the rule in words
(:data:`MEANING` and which branch applied), and one warning line per cause that flags more
than :data:`UNTRUSTED_WARN_FRACTION` of some target's rows.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .metrics import TARGET_RANGE_MARGIN, UNCERTAIN_STD_FACTOR

#: A cause flagging more than this share of some target's rows gets a warning line.
UNTRUSTED_WARN_FRACTION = 0.1

#: What "untrusted" means, the same for every model (the output prints it).
MEANING = ("untrusted: the model cannot vouch that its error on the row is like its error "
           "where it had training data — its predictive std of a reading exceeds "
           f"{UNCERTAIN_STD_FACTOR:g}× its RMS error on its training rows (models with a "
           "calibrated std), or, for a model without one, an input lies outside the training "
           "range; and, for every model, a prediction beyond the target's training range "
           f"(±{100 * TARGET_RANGE_MARGIN:.0f} %)")

_SAID = {
    "inputs_outside_range": "inputs outside the training range",
    "std_above_factor_x_residual": (f"predictive std > {UNCERTAIN_STD_FACTOR:g}× the "
                                    "RMS error on its training rows (the model lacks data "
                                    "there)"),
    "prediction_outside_target_range": (f"predictions beyond the training range of the "
                                        f"target (±{100 * TARGET_RANGE_MARGIN:.0f} %)"),
}


def in_domain_std(model, n_targets: int):
    """The std of a reading where `model` has training data, per target (k,), for a model
    whose predictive std is of a reading (``std_includes_noise``); else None.

    Its RMS error on its own training rows: ``residual_rms_`` (physics, GP, arm) or
    ``in_domain_std()`` (a hybrid: physics and residual together). None when the model keeps
    neither.
    """
    if not getattr(model, "std_includes_noise", False):
        return None
    own = getattr(model, "in_domain_std", None)
    value = own() if callable(own) else getattr(model, "residual_rms_", None)
    if value is None or np.size(value) != n_targets:
        return None
    value = np.asarray(value, dtype=float).reshape(-1)
    return value if np.all(np.isfinite(value)) else None


def trust_references(model, target_names, std, target_ranges: Mapping | None = None):
    """(reference, target_range): what predictions are compared with to flag them.

    reference: the model's in-domain std per target (:func:`in_domain_std`) when it gives a
    predictive std `std`, else None. target_range: ``(low, high)`` per target from
    `target_ranges` (target name → ``[low, high]``, as a model file's manifest keeps them),
    or None when it does not name every target.
    """
    residual = None if std is None else in_domain_std(model, len(target_names))
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
    ``flagging_causes`` (the causes that flag), ``meaning`` (:data:`MEANING`, the same for
    every model), ``explanation`` (the branch of it that applied), the factors used,
    ``residual_rms`` (the in-domain std compared with; the key keeps its old name) and
    ``warnings`` (lines a user reads; empty when nothing
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
        "meaning": MEANING,
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
    text = f"for this model a row's prediction of a target is flagged for: {said}"
    if inputs_flag and "std_above_factor_x_residual" not in flagging:
        text += (" (the model has no calibrated std to say where it lacks data: an input "
                 "outside the training range flags every target)")
    elif inputs_flag:
        text += " (an input outside the training range flags every target)"
    else:
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
