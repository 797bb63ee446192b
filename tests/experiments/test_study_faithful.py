"""The study repeated faithfully (issue 12): its trajectory, its tool, its protocol."""

import numpy as np
import pandas as pd
import pytest

from ftdrake import conventions as col
from ftdrake.experiments.study import paper
from ftdrake.experiments.study import protocols as dut
from ftdrake.sim import trajectories as traj


def test_study_motion_keeps_table_1_ranges_and_means():
    motion = traj.study_motion(traj.STUDY_DURATION_S, seed=3)
    t = np.arange(0.0, traj.STUDY_DURATION_S, 1.0 / traj.STUDY_SAMPLE_HZ)
    assert len(t) == traj.STUDY_SAMPLES  # 13,745 rows at the study's rate
    q = np.array([traj.model_to_study(motion.value(ti).ravel()) for ti in t[::5]])
    top, bottom, mean = traj.STUDY_JOINTS_DEG
    # Planned STUDY_MARGIN_DEG inside Table 1's ranges, so that tracking stays within them.
    margin = traj.STUDY_MARGIN_DEG
    assert np.all(q <= top - margin + 0.05) and np.all(q >= bottom + margin - 0.05)
    # Whole cycles: the study's ranges are swept and its means met.
    np.testing.assert_allclose(q.max(axis=0), top, atol=0.5)
    np.testing.assert_allclose(q.min(axis=0), bottom, atol=0.5)
    np.testing.assert_allclose(q.mean(axis=0), mean, atol=0.5)
    # Slow, like the study's: under 0.1 rad/s and 0.01 rad/s².
    speed = np.array([motion.derivative(1).value(ti).ravel() for ti in t[::40]])
    accel = np.array([motion.derivative(2).value(ti).ravel() for ti in t[::40]])
    assert np.abs(speed).max() < 0.1 and np.abs(accel).max() < 0.01


def test_mapping_round_trips_and_anchors_the_mean():
    q = np.array([-50.0, -20.0, 100.0, -30.0, -100.0, 80.0, 40.0])
    np.testing.assert_allclose(traj.model_to_study(traj.study_to_model(q)), q)
    np.testing.assert_allclose(traj.study_to_model(traj.STUDY_JOINTS_DEG[2]),
                               traj.STUDY_MODEL_AT_MEAN)


def test_seeds_give_other_trajectories_with_the_same_statistics():
    a, b = (traj.study_motion(100.0, s) for s in (0, 1))
    assert not np.allclose(a.value(50.0), b.value(50.0), atol=1e-3)


def test_table2_comparison_applies_the_stated_tolerance():
    sensor = {a: {"min": lo, "mean": mu, "max": hi, "std": 1.0}
              for a, (lo, mu, hi) in dut.STUDY_TABLE2.items()}
    assert all(r[s]["ok"] for r in dut.table2_comparison(sensor).values() for s in r)
    sensor["Fz"]["max"] += dut.TABLE2_TOLERANCE["force"] + 0.1
    sensor["Tz"]["mean"] -= dut.TABLE2_TOLERANCE["torque"] + 0.01
    bad = {(a, s) for a, r in dut.table2_comparison(sensor).items() for s in r
           if not r[s]["ok"]}
    assert bad == {("Fz", "max"), ("Tz", "mean")}


def _rows(n, tid, rng):
    """Joint states of a slow motion and a wrench that is a function of q, plus noise."""
    t = np.arange(n) / 40.0
    q = np.column_stack([np.sin(0.05 * (j + 1) * t + j + 2 * tid) for j in range(7)])
    w = np.column_stack([3 * q[:, 0] + q[:, 1], 2 * q[:, 2], q[:, 3] ** 2,
                         0.1 * q[:, 4], 0.2 * q[:, 5], 0.1 * q[:, 6]])
    X = np.hstack([q, np.gradient(q, axis=0) * 40.0, np.zeros_like(q)])
    return X, w + 0.01 * rng.standard_normal(w.shape)


def test_protocols_split_rows_for_the_study_and_trajectories_for_ftdrake(monkeypatch):
    rng = np.random.default_rng(0)
    (X0, Y0), (X1, Y1) = _rows(400, 0, rng), _rows(200, 1, rng)
    X, Y = np.vstack([X0, X1]), np.vstack([Y0, Y1])
    frame = pd.DataFrame({col.TRAJECTORY: np.repeat([0, 1], [400, 200]),
                          "row": np.arange(600)})
    monkeypatch.setattr(dut, "joint_state_layout", lambda f, _kind: X[f["row"].to_numpy()])
    monkeypatch.setattr(dut, "wrench_targets", lambda f, _which: Y[f["row"].to_numpy()])
    res = dut.run_protocols(frame, features=("q", "q,qd,qdd"), max_train_rows=200, n_jobs=1)
    assert res["sizes"] == {"study_rows": 400, "train_rows": 200, "test_rows": 120,
                            "heldout_rows": 200, "heldout_trajectories": 1}
    m = res["metrics"]
    # Random rows of the training trajectory are easier than a new trajectory.
    assert m["study"]["rf"]["q"]["Fx"]["nmse"] < m["study_on_new"]["rf"]["q"]["Fx"]["nmse"]
    assert res["cv_mse"]["study"]["svr"]["q"]["Fx"] > 0
    found = dut.protocol_findings(res)
    assert set(found) == {"study", "study_on_new", "heldout"}
    for verdicts in found.values():
        assert set(verdicts) == set("abcd")
        assert verdicts["a"]["cells"] == 12 and 0 <= verdicts["a"]["rf_wins"] <= 12
        assert isinstance(verdicts["b"]["reproduced"], bool)
        assert 0.0 <= verdicts["d"]["q_share"] <= 1.0


def test_findings_need_both_feature_sets_for_b_and_d():
    cell = {a: {"mse": 1.0, "nmse": 0.5, "variance_score": 0.5} for a in col.WRENCH_AXES}
    worse = {a: {"mse": 2.0, "nmse": 0.5 if a not in ("Fz", "Tz") else 0.9,
                 "variance_score": 0.4} for a in col.WRENCH_AXES}
    res = {"metrics": {"study": {"rf": {"q": cell}, "svr": {"q": worse}}}, "importances": {}}
    found = dut.protocol_findings(res)["study"]
    assert found["a"] == {"reproduced": True, "rf_wins": 6, "cells": 6}
    assert found["c"]["reproduced"] and found["c"]["worst_first"][:2] in (["Fz", "Tz"],
                                                                          ["Tz", "Fz"])
    assert found["b"]["reproduced"] is None and found["d"]["reproduced"] is None


@pytest.mark.parametrize("n_splits", [5])
def test_exhaustive_fit_count_is_the_papers_grid(n_splits):
    fits = paper.exhaustive_fits("paper", ("q",), n_splits)
    # 20 tree counts × 6 max_features ≤ 7 (2..7) × 6 leaf sizes = 720 RF candidates on q.
    assert fits["rf"]["q"] == 720 * n_splits * 6
    assert fits["svr"]["q"] == 114 * n_splits * 6  # the study's 114 SVR candidates


def test_study_tool_gives_table_2_sized_readings():
    """The study tool's weight along the study motion, plus the untared bias, has Table 2's
    max / min / mean within the stated tolerance (static: the motion is slow; the full
    simulation's table is in docs/study/study_tool.md)."""
    from ftdrake.sim.station import robot_geometry

    config = dut.study_scenario()
    g = robot_geometry(config)
    plant, context = g.plant, g.plant.CreateDefaultContext()
    tool = plant.GetBodyByName("gripper")  # its body frame is S
    mass, p_SCm = tool.default_mass(), tool.default_com()
    motion = traj.study_motion(traj.STUDY_DURATION_S, seed=0)
    rows = []
    for t in np.arange(0.0, traj.STUDY_DURATION_S, 1.0):
        plant.SetPositions(context, g.arm, motion.value(t).ravel())
        R_WS = tool.EvalPoseInWorld(context).rotation().matrix()
        f_S = mass * R_WS.T @ np.array([0.0, 0.0, -9.81])
        rows.append(np.concatenate([f_S, np.cross(p_SCm, f_S)]) + dut.STUDY_SENSOR_BIAS)
    W = np.array(rows)
    sensor = {a: {"max": W[:, j].max(), "min": W[:, j].min(), "mean": W[:, j].mean(),
                  "std": W[:, j].std()} for j, a in enumerate(col.WRENCH_AXES)}
    bad = {(a, s) for a, r in dut.table2_comparison(sensor).items() for s in r
           if not r[s]["ok"]}
    assert not bad
    # Fz swings across zero as in the study (the tool axis passes through horizontal).
    assert sensor["Fz"]["max"] - sensor["Fz"]["min"] > 12.0


def test_halving_search_runs_the_grid_with_a_growing_budget(monkeypatch):
    """The --paper path: successive halving per axis, RF budgeted in trees, SVR in rows."""
    rng = np.random.default_rng(1)
    (X0, Y0), (X1, Y1) = _rows(400, 0, rng), _rows(100, 1, rng)
    X, Y = np.vstack([X0, X1]), np.vstack([Y0, Y1])
    frame = pd.DataFrame({col.TRAJECTORY: np.repeat([0, 1], [400, 100]),
                          "row": np.arange(500)})
    monkeypatch.setattr(dut, "joint_state_layout", lambda f, _kind: X[f["row"].to_numpy()])
    monkeypatch.setattr(dut, "wrench_targets", lambda f, _which: Y[f["row"].to_numpy()])
    grids = {"rf": {"n_estimators": [5, 15], "max_features": [2, 7],
                    "min_samples_leaf": [2, 30]},
             "svr": [{"kernel": ["linear"], "C": [1.0]},
                     {"kernel": ["rbf"], "C": [10.0, 1e5], "gamma": [0.1, 100.0]}]}
    res = dut.run_protocols(frame, preset=grids, search="halving", features=("q",),
                            protocols=("study", "study_on_new"), max_train_rows=None,
                            n_jobs=1, halving={"svr_max_iter": 2000})
    assert res["settings"]["halving"]["svr_max_iter"] == 2000
    rf, svr = res["best_params"]["study"]["rf"]["q"], res["best_params"]["study"]["svr"]["q"]
    for a in col.WRENCH_AXES:
        # RF: all 4 candidates on 5 trees, the best 2 on 15 (the grid's own tree counts).
        assert rf[a]["resource"] == "n_estimators" and rf[a]["n_resources"] == [5, 15]
        assert rf[a]["n_candidates_fitted"] == 4 + 2 and rf[a]["n_estimators"] == 15
        # SVR: 5 candidates on 60 rows, then the best 2 on 180 (280 training rows).
        assert svr[a]["resource"] == "n_samples" and svr[a]["n_resources"] == [60, 180]
        assert svr[a]["n_candidates_fitted"] == 5 + 2
        assert len(svr[a]["round_fit_s"]) == 2 and svr[a]["last_round_mean_fit_s"] > 0
    m = res["metrics"]
    # The refitted per-axis models learn the wrench (a function of q) on the held-out rows.
    assert m["study"]["rf"]["q"]["Fx"]["nmse"] < 0.2
    assert m["study_on_new"]["svr"]["q"]["Fx"]["mse"] > 0
    assert res["cv_mse"]["study"]["rf"]["q"]["Fy"] > 0
    # The exhaustive estimate scales the last round: RF per tree × every candidate's trees.
    est = paper.exhaustive_seconds(res["best_params"]["study"], train_rows=280, preset=grids)
    per_tree = sum(p["last_round_mean_fit_s"] / 15 for p in rf.values())
    assert est["rf q"] == pytest.approx(per_tree * (5 + 15) * 4 * 5, rel=1e-9)
    assert est["svr q"] > 0
    out = {"results": res, "findings": dut.protocol_findings(res), "cluster": "local",
           "workers": 1, "collect_s": 0.0, "wall_time_s": 1.0,
           "exhaustive_fits": {"rf": {"q": 120}, "svr": {"q": 150}},
           "fitted_candidates": {"rf q": {a: 6 for a in col.WRENCH_AXES}},
           "exhaustive_s_estimate": est}
    text = paper.paper_markdown(out, "")
    assert "factor 3" in text and "2,000 iterations" in text and "rf q Fx:" in text


def test_quick_heldout_reuses_the_study_parameters(monkeypatch):
    rng = np.random.default_rng(2)
    (X0, Y0), (X1, Y1) = _rows(300, 0, rng), _rows(100, 1, rng)
    X, Y = np.vstack([X0, X1]), np.vstack([Y0, Y1])
    frame = pd.DataFrame({col.TRAJECTORY: np.repeat([0, 1], [300, 100]),
                          "row": np.arange(400)})
    monkeypatch.setattr(dut, "joint_state_layout", lambda f, _kind: X[f["row"].to_numpy()])
    monkeypatch.setattr(dut, "wrench_targets", lambda f, _which: Y[f["row"].to_numpy()])
    grids = {"rf": {"n_estimators": [10], "min_samples_leaf": [2, 40]},
             "svr": {"kernel": ["rbf"], "C": [1.0, 100.0], "gamma": [0.1]}}
    res = dut.run_protocols(frame, preset=grids, features=("q",), n_jobs=1,
                            retune_heldout=False)
    assert res["settings"]["retune_heldout"] is False
    assert res["best_params"]["heldout"] == {"rf": {}, "svr": {}}  # no second search
    assert set(res["metrics"]["heldout"]["rf"]) == {"q"}
    assert res["metrics"]["heldout"]["svr"]["q"]["Fx"]["mse"] > 0
    assert set(res["importances"]["heldout"]) == {"q"}


def test_collection_pools_every_run_longest_first(monkeypatch):
    """run_study collects the study trajectories and both datasets in one pool."""
    from ftdrake.config import parse_config
    from ftdrake.experiments.study import run as study_run
    from ftdrake.sim.trajectories import STUDY_DURATION_S

    order = []

    def fake(kind):
        def simulate(config_yaml, index):
            seconds = parse_config(config_yaml).trajectory.duration_s
            order.append(seconds)
            return pd.DataFrame({col.TRAJECTORY: [index], "kind": [kind]})
        return simulate

    monkeypatch.setattr(study_run, "simulate_one", fake("dataset"))
    monkeypatch.setattr(dut, "one_at_rate", fake("study"))
    data = study_run.collect_all(dut.ScenarioConfig(), trajectories=3, duration=5.0, seed=0,
                                 n_jobs=1)
    assert set(data) == {"study", "reference", "z_rich"}
    assert data["reference"][col.TRAJECTORY].tolist() == [0, 1, 2]
    assert data["study"][col.TRAJECTORY].tolist() == [0, 1, 2]
    assert (data["study"]["kind"] == "study").all()
    assert order[0] == pytest.approx(STUDY_DURATION_S) and order == sorted(order, reverse=True)
    assert len(order) == 3 + 2 * 3


def test_quick_estimate_counts_the_study_trajectory_part():
    from ftdrake.experiments.study import estimate_seconds

    with_it, without = estimate_seconds("quick"), estimate_seconds("quick", faithful=False)
    # The long study trajectory alone is STUDY_DURATION_S × 0.2 s of collection.
    assert with_it - without > 0.2 * traj.STUDY_DURATION_S


def test_study_scenario_tracks_with_a_stable_integral_term():
    """The study scenario's controller has integral action (the wrist roll would otherwise
    sag outside Table 1's range), within the stability bound ki < kp·kd."""
    c = dut.study_scenario().controller
    assert c.ki == dut.STUDY_KI > 0 and c.ki < c.kp * c.kd
    assert dut.study_scenario().trajectory.kind == "study"
