"""The study's time estimate: a cost model of collection and tuning, for the command line's
"estimated time" and results.json."""

from __future__ import annotations

import os

import numpy as np
from sklearn.model_selection import ParameterGrid

from ... import conventions as col
from ...compensation.estimators.tuning import param_grid
from ...compensation.features import FEATURE_SETS
from ...sim.trajectories import STUDY_DURATION_S
from .layout import AXES
from .protocols import HELDOUT, HELDOUT_S, QUICK_TRAIN_ROWS
from .settings import (
    DURATION_S,
    HYBRID_RESIDUAL,
    N_SPLITS,
    SVR_MAX_ROWS,
    TEST_TRAJECTORIES,
    TRAIN_HZ,
    TRAJECTORIES,
    method_grid,
)

#: Cost model of the time estimate, fitted on the 2-core development machine.
_SIM_S_PER_S = 0.2  # wall s per simulated s, per worker
_RF_S = 2.4e-8  # s per tree · row · log2(row) · (features tried + 2)
_SVR_S = 5e-8  # s per row² per fit (rbf, C ≤ 100; large C and poly take far longer)
_FIXED_S = 25.0  # imports, physics fits, predictions, trajectory planning, figures


def estimate_seconds(preset, *, trajectories=TRAJECTORIES, duration=DURATION_S,
                     test_trajectories=TEST_TRAJECTORIES, train_hz=TRAIN_HZ,
                     svr_max_rows=SVR_MAX_ROWS, n_splits=N_SPLITS, n_repeats=1, n_jobs=-1,
                     collect=True, faithful=True) -> float:
    """Rough wall time (s) of :func:`run_study` on an idle machine, from a cost model fitted
    on the 2-core development machine; `faithful`: with the study trajectory's part (its
    collection and both protocols). SVR with large C or a poly kernel (the paper grid) can
    take far longer: read it as a lower bound there."""
    workers = (os.cpu_count() or 1) if n_jobs == -1 else max(1, n_jobs)
    extra = (_faithful_seconds(preset, workers, n_splits=n_splits, collect=collect)
             if faithful else 0.0)
    sim = 2 * trajectories * duration * _SIM_S_PER_S / workers if collect else 0.0
    rows = (trajectories - test_trajectories) * duration * train_hz * (n_splits - 1) / n_splits
    svr_rows = min(rows, svr_max_rows)
    # Every tuned problem: axes × folds × repeats fits, plus the refit and the timed fit.
    fits = len(AXES) * (n_splits * n_repeats + 2)
    per_set = {}
    for features, blocks in FEATURE_SETS.items():
        n = blocks * col.N_JOINTS
        rf = sum(_rf_fit_s(p["n_estimators"], p["max_features"], n, rows)
                 for p in _candidates(preset, "rf", n))
        svr = _SVR_S * svr_rows**2 * len(_candidates(preset, "svr", n))
        hybrid = len(AXES) * _rf_fit_s(HYBRID_RESIDUAL["n_estimators"], 1.0, n, rows)
        per_set[features] = fits * (rf + svr) + hybrid
    other_cv = per_set["q"]  # RF on q tuned with the other fold scheme (an over-estimate)
    learn = 2 * (sum(per_set.values()) + other_cv) / workers  # both datasets
    return round(sim + learn + extra + _FIXED_S, 0)


def _faithful_seconds(preset, workers: int, *, n_splits: int, collect: bool) -> float:
    """The study trajectory's part: its collection (the long trajectory is the critical
    path) and the searches of both protocols (one when --quick reuses the parameters)."""
    sim = (max(STUDY_DURATION_S, (STUDY_DURATION_S + HELDOUT * HELDOUT_S) / workers)
           * _SIM_S_PER_S if collect else 0.0)
    rows = QUICK_TRAIN_ROWS * (n_splits - 1) / n_splits
    fits = len(AXES) * (n_splits + 1)
    searches = 1 if preset == "quick" else 2
    learn = 0.0
    for blocks in FEATURE_SETS.values():
        n = blocks * col.N_JOINTS
        rf = sum(_rf_fit_s(p["n_estimators"], p["max_features"], n, rows)
                 for p in _candidates(preset, "rf", n))
        svr = _SVR_S * rows**2 * len(_candidates(preset, "svr", n))
        learn += searches * fits * (rf + svr)
    return sim + learn / workers


def _rf_fit_s(trees, max_features, n_features, rows) -> float:
    tried = max_features * n_features if isinstance(max_features, float) else max_features
    return _RF_S * trees * rows * np.log2(max(rows, 2)) * (tried + 2)


def _candidates(preset, name, n_features):
    return list(ParameterGrid(param_grid(method_grid(preset, name), name, n_features)))
