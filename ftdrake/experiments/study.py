"""The RF-vs-SVR study of F/T compensation, repeated on simulated data (issue 3 item 5).

The study (Motoman SDA10D, one pre-defined slow trajectory, 13,745 rows) trained one random
forest (RF) and one SVR per wrench axis on three feature sets — ``q``, ``q,qd``, ``q,qd,qdd``
with q̇, q̈ numerically differentiated — and claimed: (a) RF beats SVR on every axis; (b) RF
barely changes when q̇, q̈ are added while SVR does; (c) Fz and Tz are worst, because the
trajectory hardly moves in Z — (e) more Z motion would help; (d) the RF relies on the joint
positions. :func:`findings` checks each against the numbers.

Here the same is done on two simulated datasets: ``reference`` (the study-like motion, little
Z) and ``z_rich`` (pitch joints moving, tool height and tilt changing). Differences from the
study, on purpose:

* Test rows come from *held-out trajectories*; no row of a test trajectory is trained on.
* Hyper-parameters are tuned with folds grouped by trajectory segment (``cv="grouped"``); the
  study's shuffled K-fold is ``cv="shuffled"``. Both are always run for RF on ``q`` to show how
  much they disagree with the held-out error.
* Three extra rows: SVR with standardised targets (ftdrake's default; the study's SVR has its
  ε-tube in N or N·m, wider than the whole signal of a small torque axis), the physics
  payload model alone, and physics + RF residual (hybrid, its residual forest not tuned).
  For the physics rows a feature set means the joint-state blocks the model may read: ``q`` is
  the static payload model (gravity, CoM, biases), ``q,qd`` the dynamic model with q̈ = 0,
  ``q,qd,qdd`` the full Newton-Euler model.
* Logs are 1 kHz; training rows are taken at ``train_hz`` (default 12.5 Hz: the motion is
  below 1 Hz, so denser rows are near copies, and it keeps the quick study within 5 minutes on
  2 cores), test rows at ``test_hz`` (100 Hz). SVR trains on at most ``svr_max_rows`` rows,
  evenly spaced in time (the quick defaults stay below it).

Metrics per axis on the test rows: MSE (N², (N·m)²), NMSE = MSE / var(measured), variance score
(the study's three, against the *measured* wrench), and — what simulation adds — the RMS of the
prediction against the true internal wrench (N, N·m) and that over the sensor's noise σ.

Typical use::

    results = run_study("out/study")          # ~3 min on 2 cores with the quick grid
    for f in results["findings"]:
        print(f["claim"], f["reproduced"], f["evidence"])
"""

from __future__ import annotations

import json
import os
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.base import clone
from threadpoolctl import threadpool_limits

from .. import conventions as col
from ..compensation.features import FEATURE_SETS, check_feature_set, feature_names
from ..compensation.forest import RandomForestCompensator
from ..compensation.hybrid import HybridCompensator
from ..compensation.metrics import report
from ..compensation.physics import ExcitationWarning, PhysicsPayloadCompensator
from ..compensation.svr import SVRCompensator
from ..compensation.tuning import grid_size, param_grid, segment_groups, tune
from ..config import ScenarioConfig
from ..data.dataset import joint_state_layout, wrench_targets
from ..io import atomic_path, staged_outputs
from ..sim.collection import collect, trajectory_config

DATASETS = ("reference", "z_rich")
METHODS = ("rf", "svr", "svr_scaled", "hybrid", "physics")
METHOD_LABELS = {"rf": "RF", "svr": "SVR", "svr_scaled": "SVR, scaled targets",
                 "hybrid": "hybrid (physics + RF)", "physics": "physics"}
METRICS = ("mse", "nmse", "variance_score", "rms_vs_truth", "rms_over_noise")
FEATURES = tuple(FEATURE_SETS)  # "q", "q,qd", "q,qd,qdd"
AXES = col.WRENCH_AXES
TUNED = {"rf": "RandomForestCompensator", "svr": "SVRCompensator",
         "svr_scaled": "SVRCompensator"}
PHYSICS_MODE = {"q": "static", "q,qd": "dynamic", "q,qd,qdd": "dynamic"}

SEGMENT_S = 4.0  # length of a grouped-CV segment (s): longer than a row's near copies
#: The hybrid's residual forest is not tuned (its grid would double the run time); these
#: settings smooth over the sensor noise that the residual mostly is.
HYBRID_RESIDUAL = {"n_estimators": 40, "max_features": 1.0, "min_samples_leaf": 5}

# Claims (b) and (d): thresholds, stated once.
UNCHANGED_VS = 0.05  # "unchanged": variance score moves by less than this on every axis
Q_SHARE = 0.8  # "concentrated on q": the q block holds at least this share of importance

# Defaults: `ftdrake study --quick` in under 5 minutes on 2 cores (see the module docstring).
TRAJECTORIES = 6  # per dataset
TEST_TRAJECTORIES = 2  # of those, held out whole
DURATION_S = 20.0  # per trajectory: one period of the reference motion's base frequency
TRAIN_HZ = 12.5  # training rows per second of log (the motion is below 1 Hz)
TEST_HZ = 100.0
SVR_MAX_ROWS = 2000
N_SPLITS = 5  # the study's 5-fold CV

# Cost model of the time estimate, fitted on the 2-core development machine.
_SIM_S_PER_S = 0.2  # wall s per simulated s, per worker
_RF_S = 2.4e-8  # s per tree · row · log2(row) · (features tried + 2)
_SVR_S = 5e-8  # s per row² per fit (rbf, C ≤ 100; large C and poly take far longer)
_FIXED_S = 25.0  # imports, physics fits, predictions, trajectory planning, figures


# ----------------------------------------------------------------------------------------------
# The run.
# ----------------------------------------------------------------------------------------------
def run_study(out_dir, *, preset="quick", trajectories: int = TRAJECTORIES,
              duration: float = DURATION_S, cv: str = "grouped", n_repeats: int = 1,
              n_jobs: int = -1, progress: bool = True, seed: int = 0,
              test_trajectories: int = TEST_TRAJECTORIES, train_hz: float = TRAIN_HZ,
              test_hz: float = TEST_HZ, svr_max_rows: int = SVR_MAX_ROWS,
              n_splits: int = N_SPLITS, config: ScenarioConfig | None = None,
              data: dict[str, pd.DataFrame] | None = None) -> dict:
    """Collects both datasets, trains and tests every method × feature set, writes the outputs.

    `preset` is a name in :data:`~ftdrake.compensation.tuning.PRESET_NAMES` or a dict
    ``{"RandomForestCompensator": grid, "SVRCompensator": grid}``. Each dataset has
    `trajectories` free-motion runs of `duration` s, the last `test_trajectories` held out.
    `data` maps each dataset name to an already collected frame (as
    :func:`ftdrake.data.collect` returns) and skips collection. Writes ``results.json``,
    ``results.md`` and PNG figures into `out_dir`, all or nothing; returns the results.
    """
    started = time.perf_counter()
    config = config or ScenarioConfig()
    say = print if progress else _quiet
    if not 1 <= test_trajectories < trajectories:
        raise ValueError(f"test_trajectories must be in [1, trajectories - 1]; got "
                         f"{test_trajectories} of {trajectories}")
    settings = {
        "preset": preset if isinstance(preset, str) else "custom", "cv": cv,
        "n_splits": n_splits, "n_repeats": n_repeats, "trajectories": trajectories,
        "test_trajectories": test_trajectories, "duration_s": duration, "train_hz": train_hz,
        "test_hz": test_hz, "svr_max_rows": svr_max_rows,
        "svr_epsilon": SVRCompensator().epsilon, "segment_s": SEGMENT_S, "seed": seed,
        "inputs": "joint_state_layout(frame, 'est'): q̇, q̈ numerically differentiated",
        "targets": "meas_* (noisy sensor reading)", "truth": "internal_*",
        "sensor_preset": config.sensor.preset,
        "noise_std": list(config.sensor.spec().noise_std),
        "hybrid_residual": {"features": "same as the row", **HYBRID_RESIDUAL},
        "physics_mode": PHYSICS_MODE,
    }
    results = {"settings": settings, "grid_sizes": grid_sizes(preset)}
    results["estimated_s"] = estimate_seconds(
        preset, trajectories=trajectories, duration=duration,
        test_trajectories=test_trajectories, train_hz=train_hz, svr_max_rows=svr_max_rows,
        n_splits=n_splits, n_repeats=n_repeats, n_jobs=n_jobs, collect=data is None)
    per_dataset = {}
    stage_s = {}
    for name in DATASETS:
        t0 = time.perf_counter()
        if data is not None:
            frame = data[name]
        else:
            say(f"[study] collecting {trajectories} × {duration:g} s of '{name}' motion …")
            frame = collect(config, trajectories, seed=seed, kind=name, duration=duration,
                            n_jobs=n_jobs, progress=progress)
        stage_s[f"collect_{name}"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        say(f"[study] training and testing on '{name}' …")
        per_dataset[name] = study_dataset(
            frame, preset=preset, cv=cv, n_splits=n_splits, n_repeats=n_repeats,
            test_trajectories=test_trajectories, train_hz=train_hz, test_hz=test_hz,
            svr_max_rows=svr_max_rows, noise_std=config.sensor.spec().noise_std, seed=seed,
            n_jobs=n_jobs, progress=progress)
        per_dataset[name]["tool_tip"] = tool_tip_extent(config, name, trajectories, duration,
                                                        seed)
        stage_s[f"study_{name}"] = time.perf_counter() - t0
    # Regroup as table → dataset → …, so each table of results.json reads on its own.
    for key in next(iter(per_dataset.values())):
        results[key] = {name: per_dataset[name][key] for name in DATASETS}
    results["findings"] = findings(results)
    say("[study] writing results and figures …")
    with staged_outputs(out_dir) as stage:
        t0 = time.perf_counter()
        write_figures(results, stage)
        stage_s["figures"] = time.perf_counter() - t0
        results["stage_s"] = {k: round(v, 2) for k, v in stage_s.items()}
        results["wall_time_s"] = round(time.perf_counter() - started, 2)
        with atomic_path(stage / "results.json") as tmp:
            tmp.write_text(json.dumps(results, indent=1))
        with atomic_path(stage / "results.md") as tmp:
            tmp.write_text(markdown(results))
    return results


@dataclass
class Split:
    """One dataset cut for the study: training rows (inputs X, measured Y, CV groups) from
    some trajectories, test rows (Xt, Yt and the true internal wrench) from the others."""

    X: np.ndarray
    Y: np.ndarray
    groups: np.ndarray
    Xt: np.ndarray
    Yt: np.ndarray
    truth: np.ndarray
    sizes: dict


def prepare_split(frame: pd.DataFrame, *, test_trajectories: int, train_hz: float,
                  test_hz: float, n_splits: int) -> Split:
    """Holds out the last `test_trajectories` runs whole and thins both sides' rows."""
    if frame[col.CONTACT].any():
        raise ValueError("the study needs free motion; the dataset has contact rows")
    train, test = split_trajectories(frame, test_trajectories)
    train, test = decimate(train, train_hz), decimate(test, test_hz)
    ids = train[col.TRAJECTORY].to_numpy()
    groups = segment_groups(ids, _segments_per_trajectory(train, n_splits))
    sizes = {"train_rows": len(train), "test_rows": len(test),
             "train_trajectories": sorted(int(i) for i in np.unique(ids)),
             "test_trajectories": sorted(int(i) for i in test[col.TRAJECTORY].unique()),
             "cv_groups": len(np.unique(groups))}
    return Split(X=joint_state_layout(train, "est"), Y=wrench_targets(train, col.MEASURED),
                 groups=groups, Xt=joint_state_layout(test, "est"),
                 Yt=wrench_targets(test, col.MEASURED),
                 truth=wrench_targets(test, col.INTERNAL), sizes=sizes)


def study_dataset(frame: pd.DataFrame, *, preset, cv, n_splits, n_repeats, test_trajectories,
                  train_hz, test_hz, svr_max_rows, noise_std, seed, n_jobs, progress) -> dict:
    """Every method × feature set on one dataset; a dict of tables keyed as in results.json."""
    split = prepare_split(frame, test_trajectories=test_trajectories, train_hz=train_hz,
                          test_hz=test_hz, n_splits=n_splits)
    svr_rows = _even_rows(len(split.X), svr_max_rows)
    tuning = {"preset": preset, "cv": cv, "n_splits": n_splits, "n_repeats": n_repeats,
              "n_jobs": n_jobs, "progress": progress, "seed": seed}
    out = {table: {m: {} for m in METHODS}
           for table in ("metrics", "best_params", "cv_mse", "timings")}
    rf = {}
    # One BLAS thread: the parallelism is in the CV folds (joblib workers).
    with threadpool_limits(limits=1), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ExcitationWarning)
        for features in FEATURES:
            for method in TUNED:
                rows = slice(None) if method == "rf" else svr_rows
                model = _tuned_row(out, method, features, split, rows, noise_std, tuning)
                if method == "rf":
                    rf[features] = model
            for method in ("physics", "hybrid"):
                _physical_row(out, method, features, split, noise_std, seed)
        out["cv_disagreement"] = _both_schemes(out, split, tuning)
    out["warnings"] = _excitation_messages(caught)
    out["feature_importances"] = {f: fx_importances(rf[f], f) for f in FEATURES}
    out["sizes"] = {**split.sizes, "svr_train_rows": len(svr_rows)}
    out["wrench_stats"] = {axis: _stats(split.Yt[:, j]) for j, axis in enumerate(AXES)}
    return out


def _tuned_row(out, method, features, split, rows, noise_std, tuning):
    """Tunes, times a refit, and scores RF or SVR on `features`; returns the tuned model."""
    X, Y = split.X[rows], split.Y[rows]
    model, search, tune_s = _tune(method, features, X, Y, split.groups[rows], **tuning)
    fit_s = _timed_fit(clone(model), X, Y)
    _score(out, method, features, model, fit_s, split.Xt, split, noise_std)
    out["timings"][method][features]["tune_s"] = round(tune_s, 2)
    out["best_params"][method][features] = dict(zip(AXES, search.best_params, strict=True))
    out["cv_mse"][method][features] = _cv_mse(search)
    return model


def _physical_row(out, method, features, split, noise_std, seed):
    model = physical_model(method, features, seed)
    fit_s = _timed_fit(model, only(split.X, features), split.Y)
    _score(out, method, features, model, fit_s, only(split.Xt, features), split, noise_std)
    if method == "physics":
        out["best_params"][method][features] = {"mode": PHYSICS_MODE[features],
                                                "condition_number": model.condition_number_}


def _score(out, method, features, model, fit_s, X_test, split, noise_std):
    """Test metrics (against the measured wrench, and the truth) and timings of one row."""
    t0 = time.perf_counter()
    prediction = model.predict(X_test)
    predict_s = time.perf_counter() - t0
    out["metrics"][method][features] = report(split.Yt, prediction, target_names=AXES,
                                              truth=split.truth, noise_std=noise_std)
    out["timings"][method][features] = {"fit_s": round(fit_s, 4),
                                        "predict_s": round(predict_s, 4),
                                        "predict_us_per_row": 1e6 * predict_s / len(X_test)}


def _both_schemes(out, split, tuning) -> dict:
    """RF on q tuned with the other fold scheme too; CV against test for both."""
    cv = tuning["cv"]
    other = "shuffled" if cv == "grouped" else "grouped"
    model, search, _ = _tune("rf", "q", split.X, split.Y, split.groups,
                             **{**tuning, "cv": other})
    other_test = report(split.Yt, model.predict(split.Xt), target_names=AXES)
    return cv_disagreement({cv: out["cv_mse"]["rf"]["q"], other: _cv_mse(search)},
                           {cv: out["metrics"]["rf"]["q"], other: other_test})


def _cv_mse(search) -> dict:
    return {a: -score for a, score in zip(AXES, search.mean_score, strict=True)}


def _excitation_messages(caught) -> list[str]:
    """The payload fits' excitation warnings (kept for results.json); others are re-issued."""
    for w in caught:
        if not issubclass(w.category, ExcitationWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return sorted({str(w.message) for w in caught if issubclass(w.category, ExcitationWarning)})


def _tune(method, features, X, Y, groups, *, preset, cv, n_splits, n_repeats, n_jobs, progress,
          seed):
    """Per-axis grid search of RF or SVR; returns (model, TuneResult, seconds)."""
    estimator = (RandomForestCompensator(features=features, random_state=seed)
                 if method == "rf" else
                 SVRCompensator(features=features, scale_targets=method == "svr_scaled"))
    t0 = time.perf_counter()
    model, search = tune(estimator, X, Y, groups=groups, preset=_grid(preset, TUNED[method]),
                         cv=cv, n_splits=n_splits, n_repeats=n_repeats, per_output=True,
                         target_names=AXES, n_jobs=n_jobs, progress=progress,
                         random_state=seed)
    return model, search, time.perf_counter() - t0


def physical_model(method: str, features: str, seed: int = 0):
    """The physics payload model (or physics + RF residual) that reads only `features`.

    Feed it :func:`only`\\ (X, features): the blocks it may not read are zeroed, so the
    dynamic model with ``"q,qd"`` sees q̈ = 0.
    """
    physics = PhysicsPayloadCompensator(mode=PHYSICS_MODE[features])
    if method == "physics":
        return physics
    residual = RandomForestCompensator(features=features, random_state=seed, **HYBRID_RESIDUAL)
    return HybridCompensator(physics=physics, residual=residual)


def only(X: np.ndarray, features: str) -> np.ndarray:
    """``X = [q, q̇, q̈]`` with the blocks outside `features` set to zero."""
    keep = check_feature_set(features) * (X.shape[1] // 3)
    Z = np.zeros_like(X)
    Z[:, :keep] = X[:, :keep]
    return Z


def _timed_fit(model, X, Y) -> float:
    t0 = time.perf_counter()
    model.fit(X, Y)
    return time.perf_counter() - t0


def _grid(preset, estimator_name: str):
    return param_grid(preset, estimator_name) if isinstance(preset, str) else preset[
        estimator_name]


def grid_sizes(preset) -> dict:
    """Candidates per tuned estimator and feature set (max_features is clipped to the set)."""
    n = col.N_JOINTS
    return {name: {f: grid_size(_grid(preset, name), name, FEATURE_SETS[f] * n)
                   for f in FEATURES} for name in sorted(set(TUNED.values()))}


# -- data -------------------------------------------------------------------------------------
def split_trajectories(frame: pd.DataFrame, n_test: int):
    """(train, test): the last `n_test` trajectory ids are the test set, whole."""
    ids = np.sort(frame[col.TRAJECTORY].unique())
    if not 1 <= n_test < len(ids):
        raise ValueError(f"cannot hold out {n_test} of {len(ids)} trajectories")
    is_test = frame[col.TRAJECTORY].isin(ids[-n_test:]).to_numpy()
    return frame[~is_test], frame[is_test]


def decimate(frame: pd.DataFrame, hz: float) -> pd.DataFrame:
    """Every k-th row of each trajectory so that rows are ~`hz` apart (logs are 1 kHz)."""
    dt = float(np.median(np.diff(frame[col.TIME].to_numpy()[:100])))
    step = max(1, round(1.0 / (hz * dt)))
    keep = frame.groupby(col.TRAJECTORY).cumcount().to_numpy() % step == 0
    return frame[keep]


def _segments_per_trajectory(train: pd.DataFrame, n_splits: int) -> int:
    """SEGMENT_S-long segments, but at least enough groups for `n_splits` folds."""
    n_traj = train[col.TRAJECTORY].nunique()
    times = train.groupby(col.TRAJECTORY)[col.TIME]
    duration = float((times.max() - times.min()).mean())
    return max(round(duration / SEGMENT_S), -(-n_splits // n_traj), 1)


def _even_rows(n: int, at_most: int) -> np.ndarray:
    return np.arange(n) if n <= at_most else np.linspace(0, n - 1, at_most).round().astype(int)


def _stats(v) -> dict:
    v = np.asarray(v, dtype=float)
    return {"max": float(v.max()), "min": float(v.min()), "mean": float(v.mean()),
            "std": float(v.std())}


def tool_tip_extent(config: ScenarioConfig, kind: str, trajectories: int, duration: float,
                    seed: int) -> dict:
    """The study's Table 3 for a dataset: tool-tip x, y, z (m) and tilt (rad) over all of its
    trajectories (max, min, mean, std), from the planned motions."""
    import dataclasses as dc

    from ..sim.station import plan_trajectory, robot_geometry
    from ..sim.trajectories import trajectory_extent

    base = dc.replace(config, trajectory=dc.replace(config.trajectory, kind=kind,
                                                    duration_s=duration))
    robot = robot_geometry(base)
    parts = [trajectory_extent(plan_trajectory(trajectory_config(base, i, seed)), robot)
             for i in range(trajectories)]
    table = {}
    for axis in parts[0]:
        mean = float(np.mean([p[axis]["mean"] for p in parts]))  # equal durations
        second = np.mean([p[axis]["std"] ** 2 + p[axis]["mean"] ** 2 for p in parts])
        table[axis] = {"max": max(p[axis]["max"] for p in parts),
                       "min": min(p[axis]["min"] for p in parts), "mean": mean,
                       "std": float(np.sqrt(max(second - mean**2, 0.0)))}
    return table


# -- derived tables ---------------------------------------------------------------------------
def cv_disagreement(cv_mse: dict, test_report: dict) -> dict:
    """RF on q: CV MSE of each fold scheme against the held-out test MSE of its model.

    ``test_over_cv`` > 1 means the CV was optimistic; the study's shuffled folds put near
    copies of a validation row in training, so they should be far more optimistic.
    """
    out = {"method": "rf", "features": "q"}
    for scheme, cv in cv_mse.items():
        test = {a: test_report[scheme][a]["mse"] for a in AXES}
        ratio = {a: test[a] / cv[a] for a in AXES}
        out[scheme] = {"cv_mse": cv, "test_mse": test, "test_over_cv": ratio,
                       "median_test_over_cv": float(np.median(list(ratio.values())))}
    return out


def fx_importances(model, features: str) -> dict:
    """Impurity importances of the tuned Fx forest, by input name (they sum to 1)."""
    values = model.estimators_[0].feature_importances_[0]
    return dict(zip(feature_names(features, col.N_JOINTS), map(float, values)))


def estimate_seconds(preset, *, trajectories=TRAJECTORIES, duration=DURATION_S,
                     test_trajectories=TEST_TRAJECTORIES, train_hz=TRAIN_HZ,
                     svr_max_rows=SVR_MAX_ROWS, n_splits=N_SPLITS, n_repeats=1, n_jobs=-1,
                     collect=True) -> float:
    """Rough wall time (s) of :func:`run_study` on an idle machine, from a cost model fitted
    on the 2-core development machine. SVR with large C or a poly kernel (the paper grid)
    can take far longer: read it as a lower bound there."""
    workers = (os.cpu_count() or 1) if n_jobs == -1 else max(1, n_jobs)
    sim = 2 * trajectories * duration * _SIM_S_PER_S / workers if collect else 0.0
    rows = (trajectories - test_trajectories) * duration * train_hz * (n_splits - 1) / n_splits
    svr_rows = min(rows, svr_max_rows)
    # Every tuned problem: axes × folds × repeats fits, plus the refit and the timed fit.
    fits = len(AXES) * (n_splits * n_repeats + 2)
    per_set = {}
    for features, blocks in FEATURE_SETS.items():
        n = blocks * col.N_JOINTS
        rf = sum(_rf_fit_s(p["n_estimators"], p["max_features"], n, rows)
                 for p in _candidates(preset, "RandomForestCompensator", n))
        svr = _SVR_S * svr_rows**2 * len(_candidates(preset, "SVRCompensator", n))
        hybrid = len(AXES) * _rf_fit_s(HYBRID_RESIDUAL["n_estimators"], 1.0, n, rows)
        per_set[features] = fits * (rf + svr) + hybrid
    other_cv = per_set["q"]  # RF on q tuned with the other fold scheme (an over-estimate)
    learn = 2 * (sum(per_set.values()) + other_cv) / workers  # both datasets
    return round(sim + learn + _FIXED_S, 0)


def _rf_fit_s(trees, max_features, n_features, rows) -> float:
    tried = max_features * n_features if isinstance(max_features, float) else max_features
    return _RF_S * trees * rows * np.log2(max(rows, 2)) * (tried + 2)


def _candidates(preset, name, n_features):
    from sklearn.model_selection import ParameterGrid

    from ..compensation.tuning import param_grid

    return list(ParameterGrid(param_grid(_grid(preset, name), name, n_features)))


# ----------------------------------------------------------------------------------------------
# Findings: the study's claims checked against the numbers.
# ----------------------------------------------------------------------------------------------
def findings(results: dict) -> list[dict]:
    """The study's claims (a)-(e), and ftdrake's own (f), checked against the numbers.

    One dict per claim: ``id``, ``claim``, ``dataset`` (where it is judged: the study's claims
    on ``reference``), ``reproduced`` (bool), ``evidence`` (text with the numbers),
    ``numbers`` and ``why`` (a likely reason when not reproduced, else None).
    """
    return [check(results) for check in (_claim_a, _claim_b, _claim_c, _claim_d, _claim_e,
                                          _claim_f)]


def _metric(results, dataset, method, features, metric) -> np.ndarray:
    cell = results["metrics"][dataset][method][features]
    return np.array([cell[a][metric] for a in AXES], dtype=float)


def _finding(id_, claim, ok, evidence, numbers, why, source="study") -> dict:
    return {"id": id_, "claim": claim, "source": source, "dataset": "reference",
            "reproduced": bool(ok), "evidence": evidence, "numbers": numbers,
            "why": None if ok else why}


def _rf_wins(results, d, svr="svr") -> tuple[int, list[str]]:
    """Cells (axis × feature set) where RF's test MSE is below `svr`'s, and the others."""
    wins, losses = 0, []
    for f in FEATURES:
        rf, other = (_metric(results, d, m, f, "mse") for m in ("rf", svr))
        wins += int(np.sum(rf < other))
        losses += [f"{a} ({f}) {r:.3g} vs {v:.3g}"
                   for a, r, v in zip(AXES, rf, other, strict=True) if r >= v]
    return wins, losses


def _claim_a(results) -> dict:
    wins = {d: _rf_wins(results, d)[0] for d in DATASETS}
    losses = _rf_wins(results, "reference")[1]
    scaled = {d: _rf_wins(results, d, "svr_scaled")[0] for d in DATASETS}
    total = len(FEATURES) * len(AXES)
    shuffled = results["cv_disagreement"]["reference"]["shuffled"]["median_test_over_cv"]
    stats, eps = results["wrench_stats"]["reference"], results["settings"]["svr_epsilon"]
    narrow = [a for a in AXES if stats[a]["std"] < eps]
    why = ("we test on held-out trajectories, the study on rows of its one trajectory. A new "
           "trajectory asks for interpolation between the training trajectories, where a "
           "forest is piecewise constant and an RBF kernel is smooth; on rows of the training "
           f"trajectories (shuffled CV) RF's MSE is {shuffled:.0f}× lower than on new ones")
    if narrow:
        why += (f". Where RF does win, it is partly the study's unscaled SVR targets: SVR's "
                f"ε = {eps:g} is wider than the whole signal of {', '.join(narrow)} (std "
                + ", ".join(f"{stats[a]['std']:.2g}" for a in narrow)
                + "), so SVR predicts little more than their mean there")
    return _finding(
        "a", "RF has a lower test MSE than SVR on every axis", wins["reference"] == total,
        f"RF wins {wins['reference']}/{total} (axis × feature set) cells on reference, "
        f"{wins['z_rich']}/{total} on z_rich; against SVR with scaled targets "
        f"{scaled['reference']}/{total} and {scaled['z_rich']}/{total}"
        + (f"; SVR wins on reference (RF vs SVR MSE) {', '.join(losses)}" if losses else ""),
        {"rf_wins": wins, "rf_wins_vs_scaled_svr": scaled, "cells": total}, why,
    )


def _claim_b(results) -> dict:
    def change(d, m):
        delta = (_metric(results, d, m, "q,qd,qdd", "variance_score")
                 - _metric(results, d, m, "q", "variance_score"))
        j = int(np.argmax(np.abs(delta)))
        return float(delta[j]), AXES[j]

    numbers = {d: {m: change(d, m)[0] for m in ("rf", "svr")} for d in DATASETS}
    (rf, rf_axis), (svr, svr_axis) = change("reference", "rf"), change("reference", "svr")
    ok = abs(rf) < UNCHANGED_VS <= abs(svr)
    why = []
    if abs(rf) >= UNCHANGED_VS:
        why.append("RF changes (its variance score drops): along a few training trajectories "
                   "q̇ and q̈ are nearly functions of q, so trees split on them as a proxy "
                   "for where on the trajectory they are — splits that do not carry over to "
                   "a new trajectory")
    if abs(svr) < UNCHANGED_VS:
        why.append("SVR barely changes: inputs are scaled to [-1, 1] and the kernel width is "
                   "tuned, so extra weakly relevant columns cost it little")
    return _finding(
        "b", "RF is ~unchanged when q̇, q̈ are added, SVR changes", ok,
        f"largest change of the variance score from q to q,qd,qdd on reference: RF "
        f"{rf:+.3f} ({rf_axis}), SVR {svr:+.3f} ({svr_axis}); on z_rich RF "
        f"{numbers['z_rich']['rf']:+.3f}, SVR {numbers['z_rich']['svr']:+.3f} (unchanged: "
        f"|change| < {UNCHANGED_VS})",
        {"largest_change": numbers, "threshold": UNCHANGED_VS}, "; ".join(why),
    )


def _mean_nmse(results, d) -> np.ndarray:
    return np.mean([_metric(results, d, m, f, "nmse") for m in ("rf", "svr")
                    for f in FEATURES], axis=0)


def _claim_c(results) -> dict:
    nmse = _mean_nmse(results, "reference")
    order = [AXES[j] for j in np.argsort(-nmse)]
    other = order[1] if order[0] == "Fz" else order[0]
    physics = _metric(results, "reference", "physics", "q,qd,qdd", "nmse")[AXES.index(other)]
    stats = results["wrench_stats"]["reference"]
    sigma = dict(zip(AXES, results["settings"]["noise_std"], strict=True))
    floor = {a: sigma[a] ** 2 / stats[a]["std"] ** 2 for a in AXES}
    return _finding(
        "c", "Fz and Tz are the worst axes on the reference trajectory",
        set(order[:2]) == {"Fz", "Tz"},
        "mean NMSE of RF and SVR over the feature sets, worst first: "
        + ", ".join(f"{a} {nmse[AXES.index(a)]:.3g}" for a in order),
        {"mean_nmse": dict(zip(AXES, map(float, nmse), strict=True)),
         "noise_floor_nmse": floor},
        f"the worst axes here are {order[0]} and {order[1]}. Fz is hard for the study's "
        f"reason (σ²/var, the NMSE of a perfect model: Fz {floor['Fz']:.2g}), but our Tz "
        f"varies well above the noise (σ²/var {floor['Tz']:.2g}; the tool's centre of mass "
        f"is off the sensor axis), while the black boxes interpolate {other} poorly between "
        f"trajectories (the physics model's {other} NMSE is {physics:.2g})",
    )


def _claim_d(results) -> dict:
    imp = results["feature_importances"]
    share = {d: float(sum(v for k, v in imp[d]["q,qd,qdd"].items() if k.startswith("q_")))
             for d in DATASETS}
    full, q_only = imp["reference"]["q,qd,qdd"], imp["reference"]["q"]
    top = sorted(full, key=full.get, reverse=True)[:3]
    top_q = sorted(q_only, key=q_only.get, reverse=True)[:3]
    fx = [_metric(results, "reference", "rf", f, "nmse")[0] for f in ("q", "q,qd,qdd")]
    return _finding(
        "d", "The RF Fx model relies on the joint positions q", share["reference"] >= Q_SHARE,
        f"q holds {share['reference']:.0%} of the Fx forest's importance with q,qd,qdd on "
        f"reference ({share['z_rich']:.0%} on z_rich; concentrated: ≥ {Q_SHARE:.0%}); top 3: "
        f"{', '.join(top)}; top 3 of the q-only forest: {', '.join(top_q)}",
        {"q_share": share, "top3": top, "top3_q_only": top_q},
        "with few training trajectories q̇ and q̈ stand in for position along a trajectory "
        "(see b), so the forest spends splits on them; they do not help on new trajectories: "
        f"RF's Fx NMSE is {fx[0]:.3g} with q and {fx[1]:.3g} with q,qd,qdd",
    )


def _claim_e(results) -> dict:
    ref, rich = _mean_nmse(results, "reference"), _mean_nmse(results, "z_rich")
    z = [AXES.index("Fz"), AXES.index("Tz")]
    tip = {d: results["tool_tip"][d]["z"]["std"] * 1000 for d in DATASETS}
    return _finding(
        "e", "More Z motion makes Fz and Tz easier to learn (the study's explanation of c)",
        all(rich[j] < ref[j] for j in z),
        f"mean NMSE of RF and SVR, reference → z_rich: Fz {ref[z[0]]:.3g} → {rich[z[0]]:.3g}, "
        f"Tz {ref[z[1]]:.3g} → {rich[z[1]]:.3g}; tool-tip z std {tip['reference']:.0f} → "
        f"{tip['z_rich']:.0f} mm",
        {"reference": {a: float(ref[j]) for a, j in zip(("Fz", "Tz"), z, strict=True)},
         "z_rich": {a: float(rich[j]) for a, j in zip(("Fz", "Tz"), z, strict=True)}},
        "z_rich also covers a larger joint space than reference, so its test trajectories "
        "ask for more interpolation",
    )


def _claim_f(results) -> dict:
    better = {}
    for d in DATASETS:
        hybrid = _metric(results, d, "hybrid", "q,qd,qdd", "mse")
        best = np.min([_metric(results, d, m, f, "mse") for m in TUNED
                       for f in FEATURES], axis=0)
        better[d] = {"axes": int(np.sum(hybrid < best)),
                     "median_ratio": float(np.median(best / hybrid))}
    r = better["reference"]
    return _finding(
        "f", "Physics + RF residual beats the best tuned RF or SVR on every axis",
        r["axes"] == len(AXES),
        f"hybrid (q,qd,qdd) has the lower test MSE on {r['axes']}/6 axes on reference, median "
        f"{r['median_ratio']:.0f}× lower; on z_rich {better['z_rich']['axes']}/6, "
        f"{better['z_rich']['median_ratio']:.0f}× lower",
        better,
        "the physics part fits poorly where the data excites the payload parameters poorly "
        "(see the warnings)",
        source="ftdrake",
    )


# ----------------------------------------------------------------------------------------------
# Outputs.
# ----------------------------------------------------------------------------------------------
def markdown(results: dict) -> str:
    """results.md: settings, findings, CV disagreement, then per-dataset tables."""
    lines = ["# RF vs SVR for F/T compensation — the study repeated in simulation", "",
             _settings_text(results), "", "## Findings", ""]
    for f in results["findings"]:
        words = ("reproduced", "not reproduced") if f["source"] == "study" else (
            "holds", "does not hold")
        mark = words[0] if f["reproduced"] else f"**{words[1]}**"
        source = "" if f["source"] == "study" else f" ({f['source']}'s claim, not the study's)"
        lines.append(f"* ({f['id']}) {f['claim']}{source} — {mark}. {_sentence(f['evidence'])}")
        if f["why"]:
            lines.append(f"  *Why:* {_sentence(f['why'])}")
    lines += ["", "## Grouped vs shuffled CV (RF on q)", "",
              "CV MSE of each fold scheme against the held-out test MSE of the model it "
              + "chose; test/CV ≫ 1 means the CV was optimistic.", "",
              "| dataset | scheme | " + " | ".join(f"{a} CV" for a in AXES)
              + " | median test/CV |", "|---" * (len(AXES) + 3) + "|"]
    for d in DATASETS:
        dis = results["cv_disagreement"][d]
        for scheme in ("grouped", "shuffled"):
            row = dis[scheme]
            lines.append(f"| {d} | {scheme} | " + " | ".join(
                f"{row['cv_mse'][a]:.3g} → {row['test_mse'][a]:.3g}" for a in AXES)
                + f" | {row['median_test_over_cv']:.2f} |")
    lines += ["", "Cells: CV MSE → test MSE (N², (N·m)²).", ""]
    for d in DATASETS:
        lines += _dataset_markdown(results, d)
    lines += ["## Grid sizes", "", "| estimator | " + " | ".join(FEATURES) + " |",
              "|---" * (len(FEATURES) + 1) + "|"]
    for name, sizes in results["grid_sizes"].items():
        lines.append(f"| {name} | " + " | ".join(str(sizes[f]) for f in FEATURES) + " |")
    lines.append("")
    return "\n".join(lines)


def _dataset_markdown(results, d) -> list[str]:
    size, tip = results["sizes"][d], results["tool_tip"][d]
    lines = [f"## Dataset `{d}`", "",
             f"{size['train_rows']} training rows ({size['svr_train_rows']} for SVR) from "
             + f"trajectories {size['train_trajectories']}, {size['cv_groups']} CV groups; "
             + f"{size['test_rows']} test rows from trajectories {size['test_trajectories']}.",
             "", "Tool tip in the world frame (mm; tilt of the tool axis from vertical in °), "
             + "like the study's Table 3:", "", "| | x | y | z | tilt |", "|---|---|---|---|---|"]
    for stat in ("max", "min", "mean", "std"):
        mm = " | ".join(f"{tip[a][stat] * 1000:.0f}" for a in "xyz")
        lines.append(f"| {stat} | {mm} | {np.degrees(tip['tilt'][stat]):.1f} |")
    ws = results["wrench_stats"][d]
    lines += ["", "Measured wrench on the test rows (N, N·m), like the study's Table 2:", "",
              "| | " + " | ".join(AXES) + " |", "|---" * (len(AXES) + 1) + "|"]
    for stat in ("max", "min", "mean", "std"):
        lines.append(f"| {stat} | " + " | ".join(f"{ws[a][stat]:.3g}" for a in AXES) + " |")
    for metric, title in (("nmse", "NMSE (MSE / var of the measured wrench)"),
                          ("variance_score", "Variance score"),
                          ("mse", "MSE (N², (N·m)²)"),
                          ("rms_over_noise", "RMS against the true internal wrench / noise σ")):
        lines += ["", f"**{title}**", "", "| method | features | " + " | ".join(AXES) + " |",
                  "|---" * (len(AXES) + 2) + "|"]
        for method in METHODS:
            for f in FEATURES:
                cell = results["metrics"][d][method][f]
                lines.append(f"| {METHOD_LABELS[method]} | {f} | "
                             + " | ".join(f"{cell[a][metric]:.3g}" for a in AXES) + " |")
    lines += ["", "**Timings** (s; tune = grid search with refit, fit = one refit)", "",
              "| method | features | tune | fit | predict | µs/row |", "|---|---|---|---|---|---|"]
    for method in METHODS:
        for f in FEATURES:
            t = results["timings"][d][method][f]
            lines.append(f"| {METHOD_LABELS[method]} | {f} | {t.get('tune_s', '–')} | "
                         f"{t['fit_s']:.2f} | {t['predict_s']:.3f} | "
                         f"{t['predict_us_per_row']:.1f} |")
    lines += ["", "**Best parameters** (per axis, Fx first)", ""]
    for method in TUNED:
        for f in FEATURES:
            params = results["best_params"][d][method][f]
            lines.append(f"* {METHOD_LABELS[method]} {f}: " + "; ".join(
                f"{a} " + ", ".join(f"{k}={v}" for k, v in sorted(params[a].items()))
                for a in AXES))
    figs = ", ".join(f"[{n}]({n}_{d}.png)" for n in _FIGURES)
    lines += ["", f"Figures: {figs}.", ""]
    if results["warnings"][d]:
        lines += ["Warnings: " + " / ".join(results["warnings"][d]), ""]
    return lines


def _settings_text(results) -> str:
    s = results["settings"]
    return (
        f"Preset `{s['preset']}`, cv `{s['cv']}` ({s['n_splits']} folds × {s['n_repeats']}), "
        f"{s['trajectories']} trajectories × {s['duration_s']:g} s per dataset, the last "
        f"{s['test_trajectories']} held out whole. Training rows at {s['train_hz']:g} Hz, "
        f"test rows at {s['test_hz']:g} Hz; SVR trained on at most {s['svr_max_rows']} rows "
        f"(evenly spaced). SVR is the study's (targets in N, N·m, so its ε = "
        f"{s['svr_epsilon']:g} is in N or N·m); 'SVR, scaled targets' standardises each axis "
        f"first (ε = {s['svr_epsilon']:g} σ of the axis). Inputs: {s['inputs']}. "
        f"Targets: {s['targets']}; "
        f"truth: {s['truth']}. Sensor `{s['sensor_preset']}`, noise σ = "
        f"{_fmt_list(s['noise_std'])} (N, N·m). Wall time "
        f"{results.get('wall_time_s', float('nan')):.0f} s."
    )


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:] + "."


def _fmt_list(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in values) + "]"


# -- figures ----------------------------------------------------------------------------------
_FIGURES = ("nmse", "mse", "variance_forces", "variance_torques", "importances")
_COLORS = {"rf": ("#9ecae1", "#4292c6", "#08519c"), "svr": ("#fdae6b", "#f16913", "#a63603")}


def write_figures(results: dict, out_dir: Path) -> list[Path]:
    """The study's figures for every dataset: ``<figure>_<dataset>.png`` in `out_dir`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for d in DATASETS:
        for name in _FIGURES:
            fig = _FIGURE_MAKERS[name](plt, results, d)
            path = Path(out_dir) / f"{name}_{d}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=100, format="png")
            plt.close(fig)
            paths.append(path)
    return paths


def _bars(ax, results, d, metric, axes, log=False):
    """Grouped bars: per wrench axis, RF and SVR × the three feature sets."""
    width = 0.8 / (2 * len(FEATURES))
    x = np.arange(len(axes))
    for i, method in enumerate(("rf", "svr")):
        for k, f in enumerate(FEATURES):
            cell = results["metrics"][d][method][f]
            values = [cell[a][metric] for a in axes]
            offset = (i * len(FEATURES) + k - (2 * len(FEATURES) - 1) / 2) * width
            ax.bar(x + offset, values, width, color=_COLORS[method][k],
                   label=f"{METHOD_LABELS[method]} {f}")
    ax.set_xticks(x, axes)
    if log:
        ax.set_yscale("log")
    ax.grid(axis="y", alpha=0.3, which="both")


def _legend_right(fig, ax):
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)


def _fig_nmse(plt, results, d):
    fig, ax = plt.subplots(figsize=(9, 4.2))
    _bars(ax, results, d, "nmse", AXES, log=True)
    ax.axhline(1.0, color="k", lw=0.8, ls="--")  # NMSE 1: no better than the mean
    ax.set_ylabel("NMSE (MSE / var)  [1 = predicting the mean]")
    ax.set_title(f"NMSE per axis, held-out trajectories — {d}")
    _legend_right(fig, ax)
    fig.tight_layout()
    return fig


def _fig_mse(plt, results, d):
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    _bars(left, results, d, "mse", AXES[:3], log=True)
    _bars(right, results, d, "mse", AXES[3:], log=True)
    left.set_ylabel("MSE [N²]")
    right.set_ylabel("MSE [(N·m)²]")
    _legend_right(fig, right)
    fig.suptitle(f"MSE per axis, held-out trajectories — {d}")
    fig.tight_layout()
    return fig


def _fig_variance(axes, kind):
    def make(plt, results, d):
        fig, ax = plt.subplots(figsize=(8, 4.2))
        _bars(ax, results, d, "variance_score", axes)
        bottom = -1.0  # a worse-than-mean model is clipped here, its value written on it
        values = [results["metrics"][d][m][f][a]["variance_score"] for m in ("rf", "svr")
                  for f in FEATURES for a in axes]
        ax.set_ylim(max(min(0.0, min(values)) - 0.05, bottom), 1.02)
        for bar in ax.patches:
            if bar.get_height() < bottom:
                ax.text(bar.get_x() + bar.get_width() / 2, bottom + 0.02,
                        f"{bar.get_height():.1f}", rotation=90, ha="center", va="bottom",
                        fontsize=7, bbox={"facecolor": "w", "alpha": 0.8, "lw": 0, "pad": 1})
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("variance score  [1 = perfect]")
        ax.set_title(f"Variance score of the {kind} models — {d}")
        _legend_right(fig, ax)
        fig.tight_layout()
        return fig

    return make


def _fig_importances(plt, results, d):
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6))
    block_color = {"q": "#08519c", "qd": "#6baed6", "qdd": "#c6dbef"}
    for ax, f in ((top, "q,qd,qdd"), (bottom, "q")):
        imp = results["feature_importances"][d][f]
        names = list(imp)
        ax.bar(range(len(names)), list(imp.values()),
               color=[block_color[n.rsplit("_", 1)[0]] for n in names])
        ax.set_xticks(range(len(names)), names, rotation=90 if len(names) > 7 else 0,
                      fontsize=8)
        ax.set_ylabel("importance")
        ax.set_title(f"Fx random forest on {f}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in block_color.values()]
    top.legend(handles, ["q (rad)", "q̇ (rad/s)", "q̈ (rad/s²)"], fontsize=8, loc="upper right")
    fig.suptitle(f"Feature importances of the Fx RF model — {d}")
    fig.tight_layout()
    return fig


_FIGURE_MAKERS = {"nmse": _fig_nmse, "mse": _fig_mse,
                  "variance_forces": _fig_variance(AXES[:3], "force"),
                  "variance_torques": _fig_variance(AXES[3:], "torque"),
                  "importances": _fig_importances}


def _quiet(*args, **kwargs):
    pass


# ----------------------------------------------------------------------------------------------
# Command line.
# ----------------------------------------------------------------------------------------------
def register(subparsers) -> None:
    """Adds ``ftdrake study [--quick|--paper] [--out DIR] ...`` to an argparse subparsers."""
    p = subparsers.add_parser("study", help="RF vs SVR (+ physics, hybrid): the study repeated")
    grid = p.add_mutually_exclusive_group()
    grid.add_argument("--quick", dest="preset", action="store_const", const="quick",
                      help="small grids, ~3 min on 2 cores (default)")
    grid.add_argument("--paper", dest="preset", action="store_const", const="paper",
                      help="the study's full grids (days; not for CI)")
    p.add_argument("--out", type=Path, default=Path("out/study"))
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--trajectories", type=int, default=TRAJECTORIES, help="runs per dataset")
    p.add_argument("--test-trajectories", type=int, default=TEST_TRAJECTORIES,
                   help="of those, held out whole for testing")
    p.add_argument("--duration", type=float, default=DURATION_S, help="seconds per run")
    p.add_argument("--train-hz", type=float, default=TRAIN_HZ,
                   help="training rows per second of log (logs are 1 kHz)")
    p.add_argument("--cv", choices=["grouped", "shuffled"], default="grouped")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=-1, help="worker processes (-1: all cores)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(preset="quick", run=run_command)


def run_command(args) -> int:
    """``ftdrake study``: prints the grid and time estimate, runs, prints the findings."""
    from ..config import load_config

    sizes = grid_sizes(args.preset)
    estimate = estimate_seconds(args.preset, trajectories=args.trajectories,
                                duration=args.duration, test_trajectories=args.test_trajectories,
                                train_hz=args.train_hz, n_jobs=args.jobs)
    print(f"study, preset {args.preset}: grid sizes per feature set "
          + "; ".join(f"{k} {_fmt_sizes(v)}" for k, v in sizes.items())
          + f"; estimated time {_fmt_duration(estimate)} on an idle machine"
          + (" (a lower bound: large-C SVR fits are slow)" if args.preset == "paper" else ""),
          flush=True)
    results = run_study(args.out, preset=args.preset, trajectories=args.trajectories,
                        test_trajectories=args.test_trajectories, duration=args.duration,
                        train_hz=args.train_hz, cv=args.cv, n_jobs=args.jobs,
                        progress=not args.quiet, seed=args.seed, config=load_config(args.config))
    print(f"wrote {args.out}/results.json, results.md and {2 * len(_FIGURES)} figures "
          f"in {results['wall_time_s']:.0f} s")
    for f in results["findings"]:
        print(f"  ({f['id']}) {'yes' if f['reproduced'] else 'NO '} {f['claim']}: "
              f"{f['evidence']}")
    return 0


def _fmt_sizes(sizes: dict) -> str:
    return "/".join(str(sizes[f]) for f in FEATURES)


def _fmt_duration(seconds: float) -> str:
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= 2 * size:
            return f"~{seconds / size:.0f} {unit}"
    return f"~{seconds:.0f} s"
