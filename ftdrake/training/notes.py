"""What training tells its user about the model it made, beyond the fit itself: rows a model
kept of those it was given, and what a hybrid's residual adds to its physics part."""

from __future__ import annotations

import numpy as np

from ..errors import option_name

#: A hybrid's residual that lowers no axis' held-out RMS error by more than this share of the
#: physics part's adds nothing worth its cost: physics alone is as good.
NO_GAIN = 0.05


def kept_rows(model, n_rows: int) -> str | None:
    """A model that keeps a subset of its training rows (a GP: ``subset_indices_``, at most
    ``max_points``), fitted on `n_rows`: how many it kept and what they weigh (one m × m
    Cholesky factor per kernel, ``L_``, 8 bytes an entry, in its file before compression);
    None for other models or when it kept every row."""
    model = getattr(model, "estimator_", model)
    parts = [model, getattr(model, "residual_", None)]
    for part in parts:
        subset = getattr(part, "subset_indices_", None)
        if subset is None or len(subset) >= n_rows:
            continue
        factor = getattr(part, "L_", None)
        megabytes = 0.0 if factor is None else np.asarray(factor).nbytes / 1e6
        return (f"the GP keeps {len(subset)} of the {n_rows} rows (max_points "
                f"{part.get_params()['max_points']}: its fit costs m³, its file m² a kernel); "
                f"its {len(factor) if factor is not None else 0} Cholesky factors of "
                f"{len(subset)} × {len(subset)} take {megabytes:.1f} MB before compression")
    return None


def residual_gain(model) -> dict | None:
    """A hybrid's residual against its physics part alone, per target, from the fit's
    cross-fit (the residual fitted on alternate blocks of rows and scored on the others):
    ``physics_rms`` (the physics part's RMS error on the training rows), ``hybrid_rms`` (the
    physics part plus the residual, RMS error on the rows of the cross-fit the residual was
    not fitted on) and ``gain`` (1 − hybrid_rms / physics_rms: the share of the physics
    part's error the residual removes on rows it has not seen). None for other models, for a
    residual that brings its own std (a GP: no cross-fit) and for model files from before
    the cross-fit's error was kept."""
    hybrid = getattr(model, "estimator_", model)
    far = getattr(hybrid, "domain_far_var_", None)
    held_out = getattr(hybrid, "residual_cross_fit_var_", None)
    if far is None or held_out is None or not np.all(np.isfinite(held_out)):
        return None
    physics, hybrid_rms = np.sqrt(np.asarray(far)), np.sqrt(np.asarray(held_out))
    gain = 1.0 - hybrid_rms / np.maximum(physics, 1e-300)
    return {"physics_rms": physics.tolist(), "hybrid_rms": hybrid_rms.tolist(),
            "gain": gain.tolist(), "physics_alone_as_good": bool(np.all(gain <= NO_GAIN))}


def residual_gain_text(found: dict, names: list[str]) -> str:
    """One paragraph on :func:`residual_gain`'s result for targets `names`."""
    per_target = ", ".join(f"{n} {p:.3g} → {h:.3g} ({100 * g:+.0f} %)" for n, p, h, g in zip(
        names, found["physics_rms"], found["hybrid_rms"], found["gain"], strict=True))
    text = ("the residual's held-out gain over the physics part (RMS error, physics → hybrid, "
            f"on rows the residual was not fitted on, by cross-fit): {per_target}")
    if found["physics_alone_as_good"]:
        text += (f"; physics alone is as good on these data (no target gains more than "
                 f"{100 * NO_GAIN:.0f} %): {option_name('kind')} physics makes a smaller, "
                 "faster model")
    return text
