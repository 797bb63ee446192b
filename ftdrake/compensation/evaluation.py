"""Scoring a fitted compensator on a dataset: what ``ftdrake evaluate`` reports.

:func:`evaluate_model` predicts every row, scores the prediction per target
(:func:`~.metrics.report`: MSE, NMSE, variance score, and the predictive std's coverage) on
all rows, on the rows inside the training range of every used input and on the rows outside
it, and flags the predictions not to trust (:mod:`.trust`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .features import feature_names
from .metrics import report
from .trust import assess_trust, trust_references


def target_ranges(Y, target_names) -> dict[str, list[float]]:
    """Target name → ``[min, max]`` of its training values (as a model file keeps them)."""
    Y = np.asarray(Y, dtype=float).reshape(len(Y), -1)
    return {n: [float(lo), float(hi)]
            for n, lo, hi in zip(target_names, Y.min(axis=0), Y.max(axis=0), strict=True)}


def evaluate_model(model, X, Y, *, target_names, training_ranges: Mapping | None = None
                   ) -> dict:
    """Scores fitted `model` on rows `X` (N × 3n, ``[q, q̇, q̈]`` [, T]) against targets `Y`
    (N × k) named `target_names`.

    `training_ranges`: target name → ``[min, max]`` on the training data
    (:func:`target_ranges`, or a model file's ``extra.training_range.targets``), for the
    trust analysis; None leaves that cause out.

    Returns a JSON-ready dict: ``in_domain_rows``, ``out_of_domain_rows``,
    ``out_of_domain_fraction``, ``out_of_domain_by_input`` (rows outside, per used input
    column with any), ``std`` ("calibrated", "not calibrated" or None), ``metrics``
    (``all``, ``in_domain``, ``out_of_domain``: per-target tables, None with fewer than 2
    rows) and ``trust`` (:func:`~.trust.assess_trust`).
    """
    Y = np.asarray(Y, dtype=float)
    prediction = np.asarray(model.predict(X)).reshape(Y.shape)
    has_std = getattr(model, "provides_std", False)
    std = np.asarray(model.predict_std(X)).reshape(Y.shape) if has_std else None
    outside = model.out_of_domain(X)
    names = list(target_names)
    metrics = {"all": report(Y, prediction, target_names=names, std=std)}
    for key, rows in (("in_domain", ~outside), ("out_of_domain", outside)):
        metrics[key] = (report(Y[rows], prediction[rows], target_names=names,
                               std=None if std is None else std[rows])
                        if rows.sum() >= 2 else None)
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
        "trust": trust,
    }


def outside_by_input(model, X) -> dict[str, int]:
    """Rows outside the training range, per used input column (only columns with any)."""
    used = feature_names(model.features, model.n_joints_)
    Z = np.asarray(X)[:, : len(used)]
    counts = ((Z < model.input_min_[: len(used)]) | (Z > model.input_max_[: len(used)])).sum(0)
    return {n: int(c) for n, c in zip(used, counts, strict=True) if c}
