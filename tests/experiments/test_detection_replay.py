"""The detection evaluation by replay gives the in-loop evaluation's results."""

import pytest

import ftdrake
from ftdrake.experiments.detection import DetectionPlan, run_plan
from ftdrake.experiments.detection_replay import replay_differs_from_loop, run_plan_by_replay

SHORT_PLAN = DetectionPlan(free_minutes=0.1, kinds=("fourier",), depths_mm=(12.0,),
                           surfaces=("table",), rehearsals=1, calibration_runs_per_kind=0,
                           events=None)


def two_models():
    data = ftdrake.collect(ftdrake.ScenarioConfig(), 1, kind="rehearsal", seed=100,
                           duration=14.0, progress=False, n_jobs=1)
    X, Y = ftdrake.joint_state_layout(data)[::4], ftdrake.wrench_targets(data)[::4]
    return {f"forest{k}": ftdrake.RandomForestCompensator(
        features=features, n_estimators=5, random_state=k).fit(X, Y)
        for k, features in enumerate(("q", "q,qd,qdd"))}


@pytest.mark.slow
def test_replayed_evaluation_counts_what_the_loop_counts():
    models = two_models()
    config = ftdrake.ScenarioConfig()
    dut = run_plan_by_replay(models, config, SHORT_PLAN, n_jobs=1, progress=False)
    loop = run_plan(models, config, SHORT_PLAN, n_jobs=1, progress=False)
    for name in models:
        assert dut[name].pop("replayed_runs") == 2 and dut[name].pop("closed_loop_runs") == 0
        assert dut[name] == loop[name]
    press = dut["forest0"]["presses"][0]
    assert press["detected"] and press["force_n"] > 10.0  # a real press, detected


def test_only_the_payload_tracker_needs_the_loop():
    config = ftdrake.ScenarioConfig()
    assert replay_differs_from_loop(config) is None
    config.chain.bias_tracker.track_payload = True
    assert "track_payload" in replay_differs_from_loop(config)
