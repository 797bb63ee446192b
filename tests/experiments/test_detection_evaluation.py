"""Detection evaluated like a safety function (experiments.detection)."""

import json

import numpy as np
import pytest

import ftdrake
from ftdrake.experiments.detection import (
    DetectionPlan,
    markdown,
    run_detection_evaluation,
    summarise,
)
from ftdrake.version import result_provenance


def press(force, detected, delay=0.004):
    return {"kind": "contact", "surface": "table", "depth_mm": 1.0, "force_n": force,
            "detected": detected, "delay_s": delay if detected else None, "true_contacts": 1,
            "false_positives": 0, "duration_s": 14.0}


def test_summary_counts_false_positives_per_hour_and_the_smallest_reliable_force():
    free = [{"kind": "fourier", "duration_s": 1800.0, "false_positives": 1},
            {"kind": "random", "duration_s": 1800.0, "false_positives": 0}]
    presses = [press(0.2, False), press(0.6, True), press(0.4, False), press(1.0, True),
               press(8.0, True, 0.003), press(30.0, True, 0.005)]
    dut = summarise(free, presses)
    assert dut["free_motion_s"] == 3600.0
    assert dut["false_positives_per_hour"] == pytest.approx(1.0)
    assert dut["missed"] == 2 and dut["press_count"] == 6
    # 0.6 N is detected but 0.4 N is not; every press from 0.6 N on is.
    assert dut["smallest_reliably_detected_force_n"] == 0.6
    assert dut["max_delay_s_presses_from_5n"] == 0.005
    detector = {"force_on": 1.0, "torque_on": 0.1, "false_positives_per_hour": 2.0}
    text = markdown({"m": {**dut, "detector": detector, "presses": presses}}, DetectionPlan())
    assert "| 2 of 6 |" in text
    assert "(budget 2 false positive per hour)" in text


@pytest.mark.slow
def test_a_short_plan_runs_end_to_end_and_writes_its_report(tmp_path):
    data = ftdrake.collect(ftdrake.ScenarioConfig(), 1, kind="rehearsal", seed=100,
                           progress=False, n_jobs=1)
    X, Y = ftdrake.joint_state_layout(data)[::4], ftdrake.wrench_targets(data)[::4]
    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=10, per_output=False,
                                             random_state=0).fit(X, Y)
    plan = DetectionPlan(free_minutes=0.1, kinds=("fourier",), depths_mm=(12.0,),
                         surfaces=("table",), rehearsals=1)
    results = run_detection_evaluation(tmp_path / "det", {"forest": forest}, plan=plan,
                                       n_jobs=2, progress=False)
    r = results["forest"]
    assert r["press_count"] == 1 and r["presses"][0]["force_n"] > 10.0  # a 12 mm press
    assert r["free_motion_s"] == pytest.approx(6.0, abs=0.01)
    assert np.isfinite(r["detector"]["force_on"])
    for name in ("detection.json", "detection.md", "detection_rate.png"):
        assert (tmp_path / "det" / name).is_file()
    written = json.loads((tmp_path / "det" / "detection.json").read_text())
    assert written["provenance"] == result_provenance(written["provenance"]["command"])
    assert written["provenance"]["command"].startswith("python ")  # run by pytest, not the CLI


def test_a_run_that_could_not_be_made_is_counted_in_the_results_table():
    """A run the planner refused is a cell of the model's row, not only a line below it
    (issue 42 item 24)."""
    from ftdrake.config import DetectorConfig
    from ftdrake.experiments.detection import model_result

    rows = [{"kind": "fourier", "seed": 1, "duration_s": 60.0, "false_positives": 0},
            press(8.0, True),
            {"kind": "contact", "surface": "wall", "depth_mm": 20.0, "seed": 6110,
             "skipped": "trajectory exceeds the acceleration limit of joint_r"}]
    result = model_result(DetectorConfig(), rows)
    assert result["runs_not_made"] == 1 and result["press_count"] == 1
    text = markdown({"m": result}, DetectionPlan())
    header = next(x for x in text.splitlines() if x.startswith("| model | thresholds"))
    row = next(x for x in text.splitlines() if x.startswith("| m |"))
    assert header.rstrip(" |").endswith("runs not made")
    assert row.rstrip(" |").endswith("**1** (contact wall)")
    assert "m: run not made (contact, wall 20.0 mm, seed 6110)" in text
    made = markdown({"m": model_result(DetectorConfig(), rows[:2])}, DetectionPlan())
    assert next(x for x in made.splitlines() if x.startswith("| m |")).endswith("| 0 |")
