"""The faithful study's hyper-parameter search, per wrench axis as the study tuned: an
exhaustive grid (:func:`~ftdrake.compensation.estimators.tuning.tune`) or scikit-learn's successive
halving over the same grid (the ``--paper`` path), with the study's SVR capped in libsvm
iterations so that non-converging candidates end.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.experimental import enable_halving_search_cv  # noqa: F401 (enables the import below)
from sklearn.model_selection import GroupKFold, HalvingGridSearchCV, KFold

from ... import conventions as col
from ...compensation.estimators.registry import entry
from ...compensation.estimators.tuning import PerOutputCompensator, param_grid, tune
from ...compensation.features import feature_names
from .layout import AXES


def refit(method, features, best: dict, X, Y, seed):
    """Per-axis models with the given parameters (``best[axis]``), fitted on X, Y."""
    members = []
    for a in AXES:
        member = estimator_for(method, features, seed)
        keys = member.get_params().keys()
        members.append(member.set_params(**{k: v for k, v in best[a].items() if k in keys}))
    return PerOutputCompensator(members, features=features).fit(X, Y)


def estimator_for(method: str, features: str, seed: int, svr_max_iter: int = -1):
    cls = entry(method).cls
    if method == "rf":
        return cls(features=features, random_state=seed)
    if svr_max_iter > 0:
        return CappedSVR(features=features, scale_targets=False, max_iter=svr_max_iter)
    return cls(features=features, scale_targets=False)  # the study's SVR


class CappedSVR(entry("svr").cls):
    """The study's SVR with libsvm's iteration cap (``max_iter``; -1: none).

    The paper grid has C up to 1e5 with poly and sigmoid kernels of gamma up to 100 on
    unscaled targets; libsvm does not converge on many of those and, uncapped, one fit on a
    few thousand rows runs for many minutes. Capped, such a fit stops with a
    ``ConvergenceWarning`` and scores what it reached (badly), so halving drops it.
    """

    def __init__(self, features="q,qd,qdd", kernel="rbf", C=10.0, gamma="scale", epsilon=0.05,
                 degree=3, scale_targets=True, max_iter=-1):
        super().__init__(features=features, kernel=kernel, C=C, gamma=gamma, epsilon=epsilon,
                         degree=degree, scale_targets=scale_targets)
        self.max_iter = max_iter

    def _new_svr(self):
        return super()._new_svr().set_params(max_iter=self.max_iter)


def grid_of(preset, method: str, n_features: int) -> list[dict]:
    """`method`'s grid: from a preset name, or a dict {method: grid} (tests, custom runs)."""
    if isinstance(preset, dict) and method in preset:
        preset = preset[method]
    return param_grid(preset, method, n_features)


def search_per_axis(method, features, X, Y, *, cv, preset, search, n_splits, seed, n_jobs, progress,
            groups=None, halving=None):
    """Per-axis search; returns (model predicting 6 axes, best params per axis, CV MSE)."""
    if search == "grid":
        grid = grid_of(preset, method, len(feature_names(features, X.shape[1] // 3)))
        model, result = tune(estimator_for(method, features, seed), X, Y, groups=groups,
                             preset=grid, cv=cv, n_splits=n_splits, per_output=True,
                             target_names=AXES, n_jobs=n_jobs, progress=progress,
                             random_state=seed)
        return (model, dict(zip(AXES, result.best_params, strict=True)),
                {a: -s for a, s in zip(AXES, result.mean_score, strict=True)})
    if search != "halving":
        raise ValueError(f"unknown search {search!r}; expected 'grid' or 'halving'")
    return halving_search(method, features, X, Y, cv=cv, groups=groups, preset=preset,
                    n_splits=n_splits, seed=seed, n_jobs=n_jobs, **(halving or {}))


#: Successive halving's settings (see :func:`halving_search`); ``run_paper`` records what it used.
HALVING = {"factor": 3, "rf_resource": "n_estimators", "min_rows": 60, "svr_max_iter": 100_000}


def halving_search(method, features, X, Y, *, cv, groups, preset, n_splits, seed, n_jobs,
             factor=HALVING["factor"], rf_resource=HALVING["rf_resource"],
             min_rows=HALVING["min_rows"], svr_max_iter=HALVING["svr_max_iter"]):
    """scikit-learn's successive halving over the same grid, per axis: every candidate on a
    small budget, the best 1/`factor` on `factor` times as much, and so on.

    The budget is the rows (``n_samples``, at least `min_rows` in the first round), except
    for RF with ``rf_resource="n_estimators"``: there the grid's tree counts become the
    budget (first round its smallest count, then ×`factor` up to its largest) and the other
    parameters are searched; on a 2-core machine the first round of 720 candidates × 5 folds
    at ~1000 trees each is hours even on a few rows (trees cost ~1 ms each however few the
    rows). SVR fits stop after `svr_max_iter` libsvm iterations (:class:`CappedSVR`).
    """
    estimator = estimator_for(method, features, seed, svr_max_iter if method == "svr" else -1)
    grid = grid_of(preset, method, len(feature_names(features, X.shape[1] // 3)))
    budget = {"resource": "n_samples", "min_resources": max(min_rows, 2 * n_splits * 6)}
    if method == "rf" and rf_resource == "n_estimators":
        trees = sorted({n for g in grid for n in g.pop("n_estimators", [])})
        if not trees:
            raise ValueError("rf_resource='n_estimators' needs n_estimators in the grid")
        budget = {"resource": "n_estimators", "min_resources": trees[0],
                  "max_resources": trees[-1]}
    splitter = (KFold(n_splits, shuffle=True, random_state=seed) if cv == "shuffled"
                else GroupKFold(n_splits))
    best, scores, members = {}, {}, []
    for j, a in enumerate(AXES):
        halving = HalvingGridSearchCV(estimator, grid, factor=factor, cv=splitter,
                                      scoring="neg_mean_squared_error", n_jobs=n_jobs,
                                      random_state=seed, refit=False, **budget)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)  # capped SVR fits
            halving.fit(X, Y[:, j], groups=groups)
        best[a] = {k: _plain(v) for k, v in halving.best_params_.items()}
        if budget["resource"] == "n_estimators":  # the best candidate's last budget
            best[a]["n_estimators"] = int(halving.n_resources_[-1])
        scores[a] = -float(halving.best_score_)
        members.append(estimator.__class__(**{**estimator.get_params(), **best[a]}))
        r = halving.cv_results_
        best[a]["n_candidates_fitted"] = int(sum(halving.n_candidates_))
        best[a]["n_resources"] = [int(v) for v in halving.n_resources_]
        best[a]["resource"] = budget["resource"]
        # Fit time per round (s, summed over candidates × folds) and that round's mean fit.
        best[a]["round_fit_s"] = [round(float(n_splits * r["mean_fit_time"][r["iter"] == i]
                                              .sum()), 2) for i in range(halving.n_iterations_)]
        last = r["iter"] == halving.n_iterations_ - 1
        best[a]["last_round_mean_fit_s"] = round(float(r["mean_fit_time"][last].mean()), 4)
    model = PerOutputCompensator(members, features=features).fit(X, Y)
    return model, best, scores


def _plain(v):
    return v.item() if isinstance(v, np.generic) else v


def rf_importances(model, features: str) -> dict:
    values = model.estimators_[0].feature_importances_
    values = np.ravel(values[0] if np.ndim(values) > 1 else values)
    return dict(zip(feature_names(features, col.N_JOINTS), map(float, values), strict=True))
