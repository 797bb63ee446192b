"""Per-axis quality of a compensator: the study's metrics plus noise-referenced residuals.

Every function takes N × k arrays (one column per target axis; a 1-D array is one axis) and
returns one value per axis, in the units noted. Shape mismatches and NaN/inf are refused:
a metric silently computed over misaligned or corrupt rows is worse than none.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ...conventions import WRENCH_AXES
from ..features import describe_nonfinite


def _as_columns(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty N × k array; got shape {a.shape}")
    message = describe_nonfinite(a, name)
    if message:
        raise ValueError(message.replace("before fitting", "before scoring"))
    return a


def _pair(y_true, y_pred, names=("y_true", "y_pred")) -> tuple[np.ndarray, np.ndarray]:
    a, b = _as_columns(y_true, names[0]), _as_columns(y_pred, names[1])
    if a.shape != b.shape:
        raise ValueError(f"{names[0]} has shape {a.shape} but {names[1]} has shape {b.shape}")
    return a, b


def mse(y_true, y_pred) -> np.ndarray:
    """Mean squared error per axis, in the target's units squared (N², (N·m)²)."""
    a, b = _pair(y_true, y_pred)
    return np.mean((a - b) ** 2, axis=0)


def nmse(y_true, y_pred) -> np.ndarray:
    """Normalised MSE per axis: ``MSE / var(y_true)`` (dimensionless; 0 is perfect, 1 is no
    better than predicting the mean).

    The study's Eq. 8 is garbled in print: it reads ``N·Σ(p - y) / (Σp·Σy)``, i.e. the
    "mean-product" NMSE of air-quality modelling with its square lost, which is in any case
    undefined for a wrench axis whose mean is near zero. This is the standard definition
    instead. An axis whose truth is constant gives NaN.
    """
    a, b = _pair(y_true, y_pred)
    return _ratio(np.mean((a - b) ** 2, axis=0), np.var(a, axis=0))


def variance_score(y_true, y_pred) -> np.ndarray:
    """Explained variance per axis, the study's Eq. 9: ``1 - var(y - ŷ) / var(y)``.

    Dimensionless; 1 is perfect. Unlike NMSE it ignores a constant offset of the prediction.
    An axis whose truth is constant gives NaN.
    """
    a, b = _pair(y_true, y_pred)
    return 1.0 - _ratio(np.var(a - b, axis=0), np.var(a, axis=0))


def residual_rms(truth, estimate) -> np.ndarray:
    """RMS of ``estimate - truth`` per axis, in the target's units (N, N·m).

    E.g. the compensator's prediction against the noise-free internal wrench of a simulation,
    or the compensated signal against the true contact wrench.
    """
    a, b = _pair(truth, estimate, ("truth", "estimate"))
    return np.sqrt(np.mean((b - a) ** 2, axis=0))


def rms_over_noise(truth, estimate, noise_std) -> np.ndarray:
    """:func:`residual_rms` divided by the sensor's white-noise σ per axis (dimensionless).

    About 1 means the compensation error is as small as the sensor's own noise.
    `noise_std` is a scalar or one positive value per axis, in the target's units.
    """
    rms = residual_rms(truth, estimate)
    if np.ndim(noise_std) > 1 or np.size(noise_std) not in (1, rms.size):
        raise ValueError(f"noise_std must be a scalar or {rms.size} values; got {noise_std!r}")
    sigma = np.broadcast_to(np.asarray(noise_std, dtype=float), rms.shape)
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise ValueError(f"noise_std must be finite and positive; got {noise_std!r}")
    return rms / sigma


#: The central intervals ``evaluate`` reports the coverage of (fraction of probability).
COVERAGE_LEVELS = (0.68, 0.95)


def coverage(y_true, y_pred, std, level: float = 0.95) -> np.ndarray:
    """Fraction per axis of rows with ``|y_true − y_pred| ≤ z·std``, ``z`` the normal
    quantile of the central `level` interval (1.96 for 0.95, 0.994 for 0.68).

    A calibrated predictive std (of a reading, noise included) gives about `level`; less
    means the std is too small (over-confident). Rows with ``std = 0`` count as covered only
    when the error is exactly 0.
    """
    a, b = _pair(y_true, y_pred)
    s = _as_columns(std, "std")
    if s.shape != a.shape:
        raise ValueError(f"std has shape {s.shape} but y_true has shape {a.shape}")
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1); got {level!r}")
    z = norm.ppf(0.5 + level / 2)
    return np.mean(np.abs(a - b) <= z * s, axis=0)


#: A row's prediction is "uncertain" when its predictive std exceeds this many times the
#: model's residual on its own training rows (``residual_rms_``): where the model has data
#: its std is about that residual, so a doubling says it is extrapolating or interpolating
#: across a gap. Used by :func:`uncertain_fraction` and ``ftdrake evaluate``.
UNCERTAIN_STD_FACTOR = 2.0
#: A prediction is "outside the training targets" when it lies beyond the training
#: [min, max] of its target widened by this fraction of the range on either side.
TARGET_RANGE_MARGIN = 0.1


def uncertain_fraction(std, residual_rms, factor: float = UNCERTAIN_STD_FACTOR) -> np.ndarray:
    """Fraction per axis of rows whose predictive `std` exceeds ``factor · residual_rms``.

    `std` is N × k (a 1-D array is one axis), `residual_rms` one positive value per axis (the
    model's RMS residual on its training rows, in the target's units). Dimensionless, 0–1.
    """
    s = _as_columns(std, "std")
    ref = np.broadcast_to(np.asarray(residual_rms, dtype=float), (s.shape[1],))
    if not np.all(np.isfinite(ref) & (ref >= 0)) or factor <= 0:
        raise ValueError(f"need finite residual_rms >= 0 and factor > 0; got {residual_rms!r}, "
                         f"{factor!r}")
    return np.mean(s > factor * ref, axis=0)


def outside_range_fraction(y_pred, low, high, margin: float = TARGET_RANGE_MARGIN) -> np.ndarray:
    """Fraction per axis of predictions beyond ``[low, high]`` widened by `margin` × its width.

    `low`, `high`: the training minimum and maximum per axis (target units). A model that
    predicts a torque the robot never produced while it was recorded is extrapolating.
    """
    p = _as_columns(y_pred, "y_pred")
    lo = np.broadcast_to(np.asarray(low, dtype=float), (p.shape[1],))
    hi = np.broadcast_to(np.asarray(high, dtype=float), (p.shape[1],))
    if np.any(hi < lo) or margin < 0:
        raise ValueError(f"need high >= low and margin >= 0; got {low!r}, {high!r}, {margin!r}")
    pad = margin * (hi - lo)
    return np.mean((p < lo - pad) | (p > hi + pad), axis=0)


def report(y_true, y_pred, *, target_names=None, truth=None, noise_std=None,
           std=None, train_residual_rms=None, target_range=None) -> dict:
    """JSON-ready metrics keyed by target name.

    ``{"Fx": {"mse": ..., "nmse": ..., "variance_score": ...}, ...}``; with `truth` (e.g. the
    noise-free internal wrench) also ``"rms_vs_truth"`` of `y_pred`, and with `noise_std` as
    well ``"rms_over_noise"``; with a predictive `std` (N × k) ``"coverage_68"`` and
    ``"coverage_95"`` (:func:`coverage`), and with the model's `train_residual_rms` (k)
    too ``"uncertain_fraction"`` (:func:`uncertain_fraction`); with the training
    `target_range` ``(low (k,), high (k,))`` ``"outside_target_range_fraction"``
    (:func:`outside_range_fraction`). Default names are ``Fx..Tz`` for 6 columns, else
    ``y0, y1, …``. NaN (constant axis) becomes None so the dict dumps as strict JSON.
    """
    a, b = _pair(y_true, y_pred)
    names = _names(target_names, a.shape[1])
    table = {"mse": mse(a, b), "nmse": nmse(a, b), "variance_score": variance_score(a, b)}
    if std is not None:
        for level in COVERAGE_LEVELS:
            table[f"coverage_{round(100 * level)}"] = coverage(a, b, std, level)
        if train_residual_rms is not None:
            table["uncertain_fraction"] = uncertain_fraction(std, train_residual_rms)
    if target_range is not None:
        table["outside_target_range_fraction"] = outside_range_fraction(b, *target_range)
    if truth is not None:
        table["rms_vs_truth"] = residual_rms(_pair(a, truth, ("y_true", "truth"))[1], b)
        if noise_std is not None:
            table["rms_over_noise"] = rms_over_noise(truth, b, noise_std)
    elif noise_std is not None:
        raise ValueError("noise_std needs truth: the residual is measured against the truth")
    return {
        name: {metric: _json_float(values[j]) for metric, values in table.items()}
        for j, name in enumerate(names)
    }


def _names(target_names, k: int) -> list[str]:
    if target_names is None:
        return list(WRENCH_AXES) if k == len(WRENCH_AXES) else [f"y{j}" for j in range(k)]
    names = [str(n) for n in target_names]
    if len(names) != k or len(set(names)) != k:
        raise ValueError(f"need {k} distinct target names; got {target_names!r}")
    return names


def _ratio(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    out = np.full(num.shape, np.nan)
    np.divide(num, den, out=out, where=den > 0)
    return out


def _json_float(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None
