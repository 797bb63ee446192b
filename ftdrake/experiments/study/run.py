"""The study's run: collection, the train/test split, tuning and scoring of every method, and
the cost model behind the time estimate.

:func:`run_study` ties the package together: it runs every method × feature set on each
dataset (:func:`study_dataset`), checks the claims (:mod:`.findings`) and writes the outputs
(:mod:`.report`). The protocol is described in the package docstring.
"""

from __future__ import annotations

import dataclasses
import json
import time
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from sklearn.base import clone
from threadpoolctl import threadpool_limits

from ... import conventions as col
from ...compensation.estimators.physics import ExcitationWarning
from ...compensation.estimators.registry import entry
from ...compensation.estimators.tuning import segment_groups, tune
from ...compensation.evaluation.metrics import report
from ...compensation.features import check_feature_set, feature_names
from ...config import ScenarioConfig, dump_config
from ...data.dataset import joint_state_layout, wrench_targets
from ...io import atomic_path, staged_outputs
from ...sim.collection import simulate_one, trajectory_config
from ...sim.station import plan_trajectory, robot_geometry
from ...sim.trajectories import trajectory_extent
from ...version import result_provenance
from . import protocols
from . import report as outputs
from .estimate import estimate_seconds
from .figures import write_figures
from .findings import check_findings
from .layout import AXES, DATASETS, FEATURES, METHODS
from .settings import (
    DURATION_S,
    HYBRID_RESIDUAL,
    N_SPLITS,
    PHYSICS_MODE,
    SEGMENT_S,
    SVR_MAX_ROWS,
    TEST_HZ,
    TEST_TRAJECTORIES,
    TRAIN_HZ,
    TRAJECTORIES,
    TUNED,
    grid_sizes,
    method_grid,
)


# ----------------------------------------------------------------------------------------------
# The run.
# ----------------------------------------------------------------------------------------------
def run_study(out_dir, *, preset="quick", trajectories: int = TRAJECTORIES,
              duration: float = DURATION_S, cv: str = "grouped", n_repeats: int = 1,
              n_jobs: int = -1, progress: bool = True, seed: int = 0,
              test_trajectories: int = TEST_TRAJECTORIES, train_hz: float = TRAIN_HZ,
              test_hz: float = TEST_HZ, svr_max_rows: int = SVR_MAX_ROWS,
              n_splits: int = N_SPLITS, config: ScenarioConfig | None = None,
              data: dict[str, pd.DataFrame] | None = None,
              faithful: bool | None = None) -> dict:
    """Collects both datasets, trains and tests every method × feature set, writes the outputs.

    `preset` is a name in :data:`~ftdrake.compensation.estimators.tuning.PRESET_NAMES` or a dict
    ``{"rf": grid, "svr": grid}`` (registry names; the class names
    ``"RandomForestCompensator"``, ``"SVRCompensator"`` work too). Each dataset has
    `trajectories` free-motion runs of `duration` s, the last `test_trajectories` held out.
    `data` maps each dataset name to an already collected frame (as
    :func:`ftdrake.sim.collection.collect` returns) and skips collection. Writes ``results.json``,
    ``results.md`` and PNG figures into `out_dir`, all or nothing; returns the results.

    `faithful` (default: unless `data` is given without a ``"study"`` frame) first runs the
    study's own trajectory, tool and protocol beside ftdrake's (:mod:`.protocols`), into
    ``results["study_protocols"]`` and ``study_tool.md``.
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
        "svr_epsilon": entry("svr").cls().epsilon, "segment_s": SEGMENT_S, "seed": seed,
        "inputs": "joint_state_layout(frame, 'est'): q̇ and the loop's causal q̈ estimate",
        "targets": "meas_* (noisy sensor reading)", "truth": "internal_true_*",
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
    faithful = faithful if faithful is not None else (data is None or "study" in data)
    if data is None:
        t0 = time.perf_counter()
        say(f"[study] collecting {trajectories} × {duration:g} s of each dataset's motion"
            + (" and the study's trajectory" if faithful else "") + " …")
        data = collect_all(config, trajectories=trajectories, duration=duration, seed=seed,
                           n_jobs=n_jobs, faithful=faithful)
        stage_s["collect"] = time.perf_counter() - t0
    if faithful:
        results["study_protocols"] = _faithful(config, data, stage_s, preset=preset, seed=seed,
                                               n_jobs=n_jobs, progress=progress, say=say)
    for name in DATASETS:
        frame = data[name]
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
    results["findings"] = outputs.finding_records(check_findings(results))
    say("[study] writing results and figures …")
    with staged_outputs(out_dir) as stage:
        t0 = time.perf_counter()
        write_figures(results, stage)
        stage_s["figures"] = time.perf_counter() - t0
        results["stage_s"] = {k: round(v, 2) for k, v in stage_s.items()}
        results["wall_time_s"] = round(time.perf_counter() - started, 2)
        results["provenance"] = result_provenance()
        with atomic_path(stage / "results.json") as tmp:
            tmp.write_text(json.dumps(results, indent=1))
        with atomic_path(stage / "results.md") as tmp:
            tmp.write_text(outputs.markdown(results))
        if "study_protocols" in results:
            sp = results["study_protocols"]
            with atomic_path(stage / "study_tool.md") as tmp:
                tmp.write_text(outputs.tool_markdown(sp["joints"], sp["sensor"], sp["table2"],
                                                     sp.get("tool_tip")))
    return results


def collect_all(config: ScenarioConfig, *, trajectories: int, duration: float, seed: int,
                n_jobs: int, faithful: bool = True) -> dict[str, pd.DataFrame]:
    """Every simulation of the study in one pool, longest first: each dataset's
    `trajectories` runs and (`faithful`) the study trajectories, whose long first run
    would otherwise leave the other workers idle. Returns {dataset: stacked logs}."""
    jobs = []  # (dataset, trajectory id, seconds, scenario YAML, runner)
    if faithful:
        study = protocols.study_scenario(config)
        for i, text in enumerate(protocols.study_jobs(study, seed=seed)):
            seconds = study.trajectory.duration_s if i == 0 else protocols.HELDOUT_S
            jobs.append(("study", i, seconds, text, protocols.one_at_rate))
    for name in DATASETS:
        base = dataclasses.replace(config, trajectory=dataclasses.replace(
            config.trajectory, kind=name, duration_s=duration))
        base.validate()
        jobs += [(name, i, duration, dump_config(trajectory_config(base, i, seed)),
                  simulate_one) for i in range(trajectories)]
    jobs.sort(key=lambda job: -job[2])
    logs = Parallel(n_jobs=n_jobs)(delayed(run)(text, i) for _, i, _, text, run in jobs)
    out = {}
    for name in dict.fromkeys(job[0] for job in jobs):
        parts = sorted((i, log) for (n, i, *_), log in zip(jobs, logs, strict=True)
                       if n == name)
        out[name] = pd.concat([log for _, log in parts], ignore_index=True)
    return out


def _faithful(config, data, stage_s, *, preset, seed, n_jobs, progress, say) -> dict:
    """The study's trajectory, tool and protocol beside ftdrake's."""
    frame = data["study"]
    t0 = time.perf_counter()
    say("[study] the study's protocol and ftdrake's …")
    with threadpool_limits(limits=1):
        # --quick: ftdrake's protocol reuses the study protocol's parameters (no second
        # search); the full run tunes it with its own grouped folds.
        res = protocols.run_protocols(frame, preset=preset, seed=seed, n_jobs=n_jobs,
                                      progress=progress, retune_heldout=preset != "quick")
    stage_s["study_protocols"] = time.perf_counter() - t0
    sensor = protocols.sensor_table(frame)
    study = protocols.study_scenario(config)
    study = dataclasses.replace(study, trajectory=dataclasses.replace(study.trajectory,
                                                                      seed=seed))
    tip = trajectory_extent(plan_trajectory(study), robot_geometry(study), dt=0.5)
    return {"results": res, "findings": protocols.protocol_findings(res),
            "joints": protocols.joint_table(frame), "sensor": sensor,
            "table2": protocols.table2_comparison(sensor), "tool_tip": tip}


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
    if frame[col.CONTACT_TRUE].any():
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
                 truth=wrench_targets(test, col.INTERNAL_TRUE), sizes=sizes)


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
    cls = entry(TUNED[method]).cls
    estimator = (cls(features=features, random_state=seed) if method == "rf" else
                 cls(features=features, scale_targets=method == "svr_scaled"))
    t0 = time.perf_counter()
    model, search = tune(estimator, X, Y, groups=groups, preset=method_grid(preset, TUNED[method]),
                         cv=cv, n_splits=n_splits, n_repeats=n_repeats, per_output=True,
                         target_names=AXES, n_jobs=n_jobs, progress=progress,
                         random_state=seed)
    return model, search, time.perf_counter() - t0


def physical_model(method: str, features: str, seed: int = 0):
    """The physics payload model (or physics + RF residual) that reads only `features`.

    Feed it :func:`only`\\ (X, features): the blocks it may not read are zeroed, so the
    dynamic model with ``"q,qd"`` sees q̈ = 0.
    """
    physics = entry("physics").cls(mode=PHYSICS_MODE[features])
    if method == "physics":
        return physics
    residual = entry("rf").cls(features=features, random_state=seed, **HYBRID_RESIDUAL)
    return entry("hybrid").cls(physics=physics, residual=residual)


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
    base = dataclasses.replace(config, trajectory=dataclasses.replace(config.trajectory, kind=kind,
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
    return dict(zip(feature_names(features, col.N_JOINTS), map(float, values), strict=True))


def _quiet(*args, **kwargs):
    pass
