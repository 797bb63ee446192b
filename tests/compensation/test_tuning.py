"""Grid presets, time-respecting folds, and the tuning loop."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.estimators.tuning import (
    PerOutputCompensator,
    cv_splits,
    grid_size,
    param_grid,
    segment_groups,
    tune,
)

N_JOINTS = 7


def smooth_log(n_trajectories=3, rows=200, seed=0):
    """(X, Y, trajectory ids): smooth random joint motions, targets smooth in q (+ noise).

    Consecutive rows are nearly identical, as in a 100 Hz log: the case grouped folds are for.
    """
    rng = np.random.default_rng(seed)
    X, ids = [], []
    for k in range(n_trajectories):
        t = np.linspace(0, 10, rows)[:, None]
        w, ph = rng.uniform(0.2, 0.8, N_JOINTS), rng.uniform(0, 6.3, N_JOINTS)
        q = np.sin(w * t + ph)
        X.append(np.hstack([q, w * np.cos(w * t + ph), -(w**2) * q]))
        ids.append(np.full(rows, k))
    X = np.vstack(X)
    q = X[:, :N_JOINTS]
    Y = np.column_stack(
        [
            9.8 * np.cos(q[:, 1] + q[:, 3]),
            9.8 * np.sin(q[:, 1] + q[:, 3]) * np.cos(q[:, 5]),
            0.8 * np.sin(q[:, 5] - q[:, 6]),
        ]
    )
    return X, Y + rng.normal(0, 0.05, Y.shape), np.concatenate(ids)


# -- grids -----------------------------------------------------------------------------------
def test_paper_grid_sizes():
    # RF: 20 tree counts × 20 max_features (2..21) × 6 leaf sizes (2, 12, ..., 52).
    assert grid_size("paper", "RandomForestCompensator") == 2400
    # With q only (7 features) max_features 2..7 remains: 20 × 6 × 6.
    assert grid_size("paper", "RandomForestCompensator", n_features=7) == 720
    # SVR: linear × 6 C, plus rbf/poly/sigmoid × 6 C × 6 gamma.
    assert grid_size("paper", SVRCompensator()) == 6 + 3 * 36


def test_paper_grid_values_match_the_study():
    (rf,) = param_grid("paper", "RandomForestCompensator")
    assert rf["n_estimators"][0] == 100 and rf["n_estimators"][-1] == 2000
    assert rf["max_features"] == list(range(2, 22))
    assert rf["min_samples_leaf"] == [2, 12, 22, 32, 42, 52]
    svr = param_grid("paper", "SVRCompensator")
    assert {k for g in svr for k in g["kernel"]} == {"rbf", "linear", "poly", "sigmoid"}
    assert svr[1]["C"] == [1, 10, 100, 1e3, 1e4, 1e5]
    assert svr[1]["gamma"] == [0.001, 0.01, 0.1, 1, 10, 100]


def test_quick_grids_are_small():
    assert grid_size("quick", "RandomForestCompensator") <= 6
    assert grid_size("quick", "SVRCompensator") <= 6


@pytest.mark.parametrize(
    "preset, estimator, match",
    [
        ("huge", "SVRCompensator", "unknown preset 'huge'"),
        ("paper", "GPRCompensator", r"no grid for gpr; compensators with one: \[.rf., .svr.\]"),
        ({"max_features": [8, 9]}, "RandomForestCompensator", "no max_features candidate"),
    ],
)
def test_bad_grid_requests_are_refused(preset, estimator, match):
    with pytest.raises(ValueError, match=match):
        param_grid(preset, estimator, n_features=7)


# -- folds ----------------------------------------------------------------------------------
def test_segment_groups_are_contiguous_per_trajectory():
    ids = np.repeat([7, 3], [10, 4])
    groups = segment_groups(ids, n_segments=3)
    # trajectory 3 (sorted first) → labels 0..2 over 4 rows; trajectory 7 → 3..5 over 10 rows
    assert groups[10:].tolist() == [0, 0, 1, 2]
    assert groups[:10].tolist() == [3, 3, 3, 3, 4, 4, 4, 5, 5, 5]
    assert len(np.unique(segment_groups(np.zeros(2), n_segments=5))) == 2


def _groups_split(splits, groups):
    return [set(groups[train]) & set(groups[test]) for train, test in splits]


def test_grouped_folds_never_split_a_group_but_shuffled_folds_do():
    groups = segment_groups(np.repeat([0, 1, 2], 100), n_segments=4)
    grouped = cv_splits(300, cv="grouped", groups=groups, n_splits=5)
    shuffled = cv_splits(300, cv="shuffled", n_splits=5)
    assert all(not shared for shared in _groups_split(grouped, groups))
    assert all(shared for shared in _groups_split(shuffled, groups))
    for splits in (grouped, shuffled):
        assert len(splits) == 5
        tests = np.concatenate([test for _, test in splits])
        assert sorted(tests.tolist()) == list(range(300))  # every row validated exactly once


def test_default_groups_are_contiguous_time_segments():
    splits = cv_splits(1000, n_splits=5)
    for _, test in splits:
        runs = np.count_nonzero(np.diff(test) > 1) + 1
        assert runs <= 4  # SEGMENTS_PER_FOLD contiguous blocks of 50 rows, some adjacent
        assert len(test) == 200


def test_repeats_reshuffle_the_partition():
    splits = cv_splits(400, n_splits=4, n_repeats=3)
    assert len(splits) == 12
    first = {tuple(test) for _, test in splits[:4]}
    second = {tuple(test) for _, test in splits[4:8]}
    assert first != second


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_rows": 300, "groups": np.repeat([0, 1, 2], 100)}, "at least 5 groups.*got 3"),
        ({"n_rows": 4}, "at least 5 rows"),
        ({"n_rows": 100, "n_splits": 1}, "at least 2"),
        ({"n_rows": 100, "cv": "timeseries"}, "unknown cv"),
        ({"n_rows": 100, "groups": np.zeros(99)}, "99 labels for 100 rows"),
    ],
)
def test_impossible_folds_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        cv_splits(kwargs.pop("n_rows"), **kwargs)


# -- the search -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def log():
    return smooth_log()


GRID = {"n_estimators": [8], "min_samples_leaf": [2, 150]}  # 150 rows per leaf is far too coarse


def test_tune_picks_the_better_candidate_and_refits(log):
    X, Y, ids = log
    est = RandomForestCompensator(features="q", random_state=0)
    model, result = tune(est, X, Y, groups=segment_groups(ids, 4), preset=GRID, progress=True)
    assert result.best_params == [{"min_samples_leaf": 2, "n_estimators": 8}]
    assert model.min_samples_leaf == 2 and model.predict(X).shape == Y.shape
    assert result.n_candidates == 2 and result.targets == ["all"]
    json.dumps(result.to_dict(), allow_nan=False)


def test_reported_score_is_the_mean_neg_mse_over_folds(log):
    X, Y, ids = log
    groups = segment_groups(ids, 4)
    est = RandomForestCompensator(features="q", random_state=0)
    _, result = tune(est, X, Y, groups=groups, preset=GRID, n_repeats=2, progress=False)
    scores = []
    for train, test in cv_splits(len(X), groups=groups, n_repeats=2):
        fitted = RandomForestCompensator(
            features="q", random_state=0, n_estimators=8, min_samples_leaf=2
        ).fit(X[train], Y[train])
        scores.append(-np.mean((fitted.predict(X[test]) - Y[test]) ** 2))
    assert result.mean_score[0] == pytest.approx(np.mean(scores), rel=1e-12)
    assert result.std_score[0] == pytest.approx(np.std(scores), rel=1e-12)


def test_shuffled_folds_are_optimistic_on_time_series(log):
    # Shuffled rows put near-copies of every validation row in training; grouped folds don't.
    X, Y, ids = log
    est = RandomForestCompensator(features="q", random_state=0)
    grid = {"n_estimators": [8]}
    _, grouped = tune(est, X, Y, groups=segment_groups(ids, 4), preset=grid, progress=False)
    _, shuffled = tune(est, X, Y, preset=grid, cv="shuffled", progress=False)
    assert -shuffled.mean_score[0] < 0.5 * -grouped.mean_score[0]


def test_per_output_tuning_gives_each_axis_its_own_model(log):
    X, Y, _ = log
    est = SVRCompensator(features="q")
    grid = {"C": [0.01, 10.0], "gamma": [0.3]}
    model, result = tune(
        est,
        X,
        Y,
        preset=grid,
        per_output=True,
        target_names=["Fx", "Fy", "Tz"],
        n_jobs=2,
        progress=False,
    )
    assert isinstance(model, PerOutputCompensator) and len(model.estimators_) == 3
    assert result.targets == ["Fx", "Fy", "Tz"] and len(result.best_params) == 3
    assert all(p["C"] == 10.0 for p in result.best_params)
    for j, member in enumerate(model.estimators_):
        np.testing.assert_array_equal(model.predict(X)[:, j], member.predict(X))


def test_tune_refuses_bad_input(log):
    X, Y, _ = log
    est = RandomForestCompensator(features="q")
    with pytest.raises(ValueError, match="unknown feature set"):
        tune(RandomForestCompensator(features="qd"), X, Y, preset=GRID, progress=False)
    with pytest.raises(ValueError, match="at least 5 rows"):
        tune(est, X[:3], Y[:3], preset=GRID, progress=False)
    bad = X.copy()
    bad[5, 0] = np.nan
    with pytest.raises(ValueError, match="1 of 600 rows"):
        tune(est, bad, Y, preset=GRID, progress=False)
    with pytest.raises(ValueError, match="3 target columns"):
        tune(est, X, Y, preset=GRID, per_output=True, target_names=["a"], progress=False)


def test_per_output_compensator_refuses_wider_members(log):
    X, Y, _ = log
    dut = PerOutputCompensator([RandomForestCompensator()] * 3, features="q")
    with pytest.raises(ValueError, match="wider"):
        dut.fit(X, Y)
    with pytest.raises(ValueError, match="2 estimators for 3"):
        PerOutputCompensator([RandomForestCompensator()] * 2).fit(X, Y)


def test_a_time_budget_of_zero_scores_the_first_candidate_only_and_says_so(log):
    """Issue 42 item 12: the search is bounded in time. A budget of 0 s scores the first
    candidate (here the coarse one), chooses it, and the result says it stopped early; with
    an ample budget the search is the unbounded one, score for score."""
    X, Y, ids = log
    groups = segment_groups(ids, 4)
    est = RandomForestCompensator(features="q", random_state=0)
    grid = {"n_estimators": [8], "min_samples_leaf": [150, 2]}  # the coarse one first
    _, full = tune(est, X, Y, groups=groups, preset=grid, progress=False)
    assert full.best_params == [{"min_samples_leaf": 2, "n_estimators": 8}]
    assert full.scored == [2] and not full.stopped_early and full.time_budget_s is None

    model, cut = tune(est, X, Y, groups=groups, preset=grid, progress=False, time_budget_s=0)
    assert cut.scored == [1] and cut.stopped_early and cut.stopped_after_s >= 0
    assert cut.best_params == [{"min_samples_leaf": 150, "n_estimators": 8}]
    assert model.min_samples_leaf == 150
    assert cut.mean_score == [full.candidates[0]["mean_score"][0]]
    assert cut.candidates[0]["mean_score"][1] is None
    json.dumps(cut.to_dict(), allow_nan=False)

    _, ample = tune(est, X, Y, groups=groups, preset=grid, progress=False, time_budget_s=1e6)
    assert ample.scored == [2] and not ample.stopped_early
    assert ample.candidates == full.candidates and ample.best_params == full.best_params
    with pytest.raises(ValueError, match="time_budget_s must be a non-negative"):
        tune(est, X, Y, groups=groups, preset=grid, progress=False, time_budget_s=-1)


def test_per_output_tuning_under_a_spent_budget_gives_every_axis_its_first_candidate(log):
    X, Y, _ = log
    grid = {"C": [0.01, 10.0], "gamma": [0.3]}
    model, result = tune(SVRCompensator(features="q"), X, Y, preset=grid, per_output=True,
                         target_names=["Fx", "Fy", "Tz"], progress=False, time_budget_s=0)
    assert result.scored == [1, 1, 1] and result.stopped_early
    assert all(p["C"] == 0.01 for p in result.best_params)
    assert len(model.estimators_) == 3
