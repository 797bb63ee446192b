"""The demo (the main job) end to end on a short run: both models trained on the same data,
the same held-out contact scenario with each in the loop, outputs written."""

import json

import pytest

from ftdrake.config import ScenarioConfig
from ftdrake.experiments.demo import (
    OTHER_KINDS,
    TASK_COVERING_RUNS,
    better_model,
    print_table,
    run_demo,
)
from ftdrake.version import result_provenance


@pytest.mark.slow
def test_demo_compares_forest_and_hybrid_on_the_same_held_out_contact(tmp_path, capsys):
    out = tmp_path / "demo"
    summary = run_demo(out, fourier=1, rehearsals=2, duration=8.0, meshcat_html=False,
                       progress=False)
    assert set(summary["models"]) == {"forest", "hybrid"}
    for name, result in summary["models"].items():
        assert result["true_contacts"] == 1, name
        assert result["missed_contacts"] == 0, name
        assert (out / f"model_{name}.ftd").is_file()
    # The hybrid's physics extrapolates where a forest on little data cannot: its worst
    # free-motion axis is closer to the sensor noise.
    hybrid, forest = summary["models"]["hybrid"], summary["models"]["forest"]
    assert max(hybrid["compensation_error_over_noise"]) < max(
        forest["compensation_error_over_noise"])
    # So the summary names the hybrid: both find the one contact without a miss, the hybrid
    # raises no more false alarms than the forest, and its error is the lower.
    assert hybrid["false_positives"] <= forest["false_positives"]
    assert summary["better"] == "hybrid"
    # The sensor is mounted rotated by the scenario's default (1.5, -2, 1) deg; the hybrid
    # identifies it. The cable and the cross-talk, which the rigid model lacks, pull the fit
    # off by up to ~1.4 deg on this short run (2.28, -3.36, ...), so: within 1.5 deg.
    injected = ScenarioConfig().sensor.mounting_rpy_deg
    assert hybrid["model"]["mounting_rpy_deg"] == pytest.approx(injected, abs=1.5)
    assert summary["training_trajectories"] == (1 + 2 + len(OTHER_KINDS) + TASK_COVERING_RUNS
                                                - 1)  # one held out
    # The hybrid's out-of-domain std was calibrated on a training run held out for it (then
    # refitted on all), and its coverage is reported per distance bin on the held-out runs.
    calibration = hybrid["model"]["domain_calibration"]
    assert calibration["refit"] and len(calibration["held_out_groups"]) >= 1
    # One growth shared by the axes; σ²_in (one multiple of each axis' training error) and
    # the parameters' scale c from the held-out runs too.
    assert calibration["shared_growth"] and min(calibration["growth"]) >= 0
    assert calibration["in_domain"] == "held_out"
    assert calibration["parameter_variance_scale"] >= 0.0
    bins = hybrid["domain_coverage"]
    assert sum(b["rows"] for b in bins.values()) > 1000
    assert all(len(b["coverage_95"]) == 6 for b in bins.values() if b["rows"])
    written = json.loads((out / "summary.json").read_text())
    assert written["better"] == summary["better"]
    assert written["provenance"] == result_provenance(written["provenance"]["command"])
    assert (out / "contact.png").stat().st_size > 10_000
    print_table(summary)
    table = capsys.readouterr().out
    assert "forest" in table and "hybrid" in table and "(better)" in table


def test_better_model_prefers_fewer_errors_then_lower_free_motion_error():
    results = {
        "a": {"false_positives": 0, "missed_contacts": 0, "compensation_error_over_noise": [9]},
        "b": {"false_positives": 0, "missed_contacts": 0, "compensation_error_over_noise": [2]},
        "c": {"false_positives": 1, "missed_contacts": 0, "compensation_error_over_noise": [1]},
    }
    assert better_model(results) == "b"
    results["b"]["missed_contacts"] = 2
    assert better_model(results) == "a"
