"""Scoring a fitted compensator on a dataset: what ``ftdrake evaluate`` reports.

:func:`evaluate_model` predicts every row, scores the prediction per target
(:func:`~.metrics.report`: MSE, NMSE, variance score, and the predictive std's coverage) on
all rows, on the rows inside the training range of every used input and on the rows outside
it, and flags the predictions not to trust (:mod:`.trust`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..features import feature_names
from .metrics import report
from .trust import assess_trust, trust_references


def target_ranges(Y, target_names) -> dict[str, list[float]]:
    """Target name → ``[min, max]`` of its training values (as a model file keeps them)."""
    Y = np.asarray(Y, dtype=float).reshape(len(Y), -1)
    return {n: [float(lo), float(hi)]
            for n, lo, hi in zip(target_names, Y.min(axis=0), Y.max(axis=0), strict=True)}


#: The in-domain and out-of-domain scores are not given on fewer rows than this (a variance
#: score on 10 rows said −4671).
MIN_SUBSET_ROWS = 30
#: Resting rows: |q̇| below this (rad/s) on every joint, in runs of at least
#: :data:`MIN_REST_RUN` rows; the wrench's spread about each run's mean is the noise.
REST_SPEED = 1e-3
#: A residual whose mean is more than this many of its own standard deviations from zero is
#: an offset (a sensor bias, a re-tare, a payload change since training), not scatter.
OFFSET_STDS = 2.0
MIN_REST_RUN = 20


def noise_from_resting_rows(X, Y, n_joints: int) -> np.ndarray | None:
    """Per-target noise std (target units) from the rows where the robot rests: runs of at
    least :data:`MIN_REST_RUN` consecutive rows with every |q̇| < :data:`REST_SPEED` rad/s
    the spread of each target about its run's mean, pooled over the runs. None when there
    are fewer than 2 × :data:`MIN_REST_RUN` such rows, or when every row rests (a table of
    static poses: its rows are different poses, not a robot held still)."""
    X, Y = np.asarray(X, float), np.asarray(Y, float)
    rest = np.all(np.abs(X[:, n_joints:2 * n_joints]) < REST_SPEED, axis=1)
    if rest.all() or rest.sum() < 2 * MIN_REST_RUN:
        return None
    edges = np.flatnonzero(np.diff(np.r_[0, rest.astype(int), 0]))
    squares, dof = np.zeros(Y.shape[1]), 0
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start >= MIN_REST_RUN:
            run = Y[start:stop]
            squares += np.sum((run - run.mean(axis=0)) ** 2, axis=0)
            dof += stop - start - 1
    if dof < 2 * MIN_REST_RUN:
        return None
    sigma = np.sqrt(squares / dof)
    return sigma if np.all(sigma > 0) else None


def evaluate_model(model, X, Y, *, target_names, training_ranges: Mapping | None = None,
                   noise_std=None) -> dict:
    """Scores fitted `model` on rows `X` (N × 3n, ``[q, q̇, q̈]`` [, T]) against targets `Y`
    (N × k) named `target_names`.

    `training_ranges`: target name → ``[min, max]`` on the training data
    (:func:`target_ranges`, or a model file's ``extra.training_range.targets``), for the
    trust analysis; None leaves that cause out.

    Returns a JSON-ready dict: ``in_domain_rows``, ``out_of_domain_rows``,
    ``out_of_domain_fraction``, ``out_of_domain_by_input`` (rows outside, per used input
    column with any), ``std`` ("calibrated", "not calibrated" or None), ``metrics``
    (``all``, ``in_domain``, ``out_of_domain``: per-target tables, None with fewer than 2
    rows, or on fewer than :data:`MIN_SUBSET_ROWS` for the in- and out-of-domain subsets)
    and ``trust`` (:func:`~.trust.assess_trust`). With the sensor's noise std per target
    (`noise_std`: a scalar or one per target, in the targets' units; or None to estimate it
    from resting rows, :func:`noise_from_resting_rows`) every table also has
    ``rms_over_sigma`` (RMS error in noise σ: ≈ 1 at the noise floor), and ``noise`` says
    the σ used and where it came from (None when unknown).
    """
    Y = np.asarray(Y, dtype=float)
    prediction = np.asarray(model.predict(X)).reshape(Y.shape)
    has_std = getattr(model, "provides_std", False)
    std = np.asarray(model.predict_std(X)).reshape(Y.shape) if has_std else None
    outside = model.out_of_domain(X)
    names = list(target_names)
    noise = _noise(noise_std, X, Y, model)
    sigma = None if noise is None else np.asarray(noise["std"], float)
    metrics = {"all": _scores(Y, prediction, names, std, sigma)}
    for key, rows in (("in_domain", ~outside), ("out_of_domain", outside)):
        metrics[key] = (_scores(Y[rows], prediction[rows], names,
                                None if std is None else std[rows], sigma)
                        if rows.sum() >= MIN_SUBSET_ROWS else None)
    trust = assess_trust(names, prediction, std, outside,
                         *trust_references(model, names, std, training_ranges))
    return {
        "in_domain_rows": int((~outside).sum()),
        "out_of_domain_rows": int(outside.sum()),
        "out_of_domain_fraction": float(outside.mean()),
        "out_of_domain_by_input": outside_by_input(model, X),
        "std": (None if std is None else "calibrated" if getattr(model, "std_includes_noise",
                                                                   False) else "not calibrated"),
        "metrics": metrics,
        "min_subset_rows": MIN_SUBSET_ROWS,
        "noise": noise,
        "trust": trust,
        "offsets": residual_offsets(Y, prediction, names),
    }


def residual_offsets(Y, prediction, names) -> dict:
    """Per target whose residual e = Y − prediction has a mean more than :data:`OFFSET_STDS`
    of its own standard deviation from zero: ``{"mean": …, "std": …}`` (targets' units).
    Such a residual is a constant offset, not the model's scatter: a sensor bias or re-tare,
    or a payload changed since the training data. Empty on fewer than 2 rows."""
    e = np.asarray(Y, float) - np.asarray(prediction, float)
    if len(e) < 2:
        return {}
    mean, std = e.mean(axis=0), e.std(axis=0)
    return {name: {"mean": float(m), "std": float(sd)}
            for name, m, sd in zip(names, mean, std, strict=True)
            if abs(m) > OFFSET_STDS * sd}


def _noise(noise_std, X, Y, model) -> dict | None:
    k = Y.shape[1]
    if noise_std is not None:
        sigma = np.broadcast_to(np.asarray(noise_std, float).reshape(-1), (k,))
        if not np.all(np.isfinite(sigma) & (sigma > 0)):
            raise ValueError(f"noise_std must be positive (one value, or one per target); "
                             f"got {noise_std!r}")
        return {"std": sigma.tolist(), "source": "given"}
    sigma = noise_from_resting_rows(X, Y, int(model.n_joints_))
    if sigma is None:
        return None
    return {"std": sigma.tolist(), "source": "resting rows (the spread about each run's mean)"}


def _scores(Y, prediction, names, std, sigma) -> dict:
    table = report(Y, prediction, target_names=names, std=std)
    if sigma is not None:
        rms = np.sqrt(np.mean((Y - prediction) ** 2, axis=0))
        for name, value in zip(names, rms / sigma, strict=True):
            table[name]["rms_over_sigma"] = float(value)
    return table


def outside_by_input(model, X) -> dict[str, int]:
    """Rows outside the training range, per used input column (only columns with any)."""
    used = feature_names(model.features, model.n_joints_)
    Z = np.asarray(X)[:, : len(used)]
    counts = ((Z < model.input_min_[: len(used)]) | (Z > model.input_max_[: len(used)])).sum(0)
    return {n: int(c) for n, c in zip(used, counts, strict=True) if c}
