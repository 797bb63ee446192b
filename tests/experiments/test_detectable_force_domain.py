"""The detectable force against the distance to the training data (experiments.
detection_domain), and the replayed detection evaluation that reports it for both tests."""

import warnings

import numpy as np
import pytest

import ftdrake
from ftdrake.config import DetectorConfig
from ftdrake.experiments.detection import (
    DetectionPlan,
    markdown,
    run_detection_evaluation,
    with_tests,
)
from ftdrake.experiments.detection_domain import (
    detectable_force_vs_domain,
    plot_detectable_force_vs_domain,
)
from ftdrake.experiments.detection_replay import run_plan_by_replay
from ftdrake.runtime.detector import chi2_threshold

PERIOD = 0.001


def test_the_chi2_tests_force_follows_the_std_and_the_norm_tests_does_not(tmp_path):
    rng = np.random.default_rng(0)
    d = rng.uniform(0.0, 4.0, 20000)
    # A std that grows with d, as the hybrid's: σ² = σ²_in + g² d.
    sigma_f = np.sqrt(0.05 ** 2 + 0.1 ** 2 * d)
    std = np.column_stack([sigma_f, 0.8 * sigma_f, 0.5 * sigma_f] + [0.004 * np.ones_like(d)] * 3)
    detectors = {"chi2": DetectorConfig(test="chi2", chi2_on=40.0),
                 "norm": DetectorConfig(force_on=1.3, torque_on=0.1)}
    samples = [{"d": d[:5000], "std": std[:5000]}, {"d": d[5000:], "std": std[5000:]}]
    dut = detectable_force_vs_domain(samples, detectors, PERIOD)
    assert dut["samples"] == 20000
    chi2, norm = dut["chi2"]["bins"], dut["norm"]["bins"]
    # Independent: √chi2_on · σ_Fx at the bin's samples (Fx has the largest std here).
    for bin_, (lo, hi) in zip(chi2.values(), [(0, 1), (1, 2), (2, np.inf)], strict=True):
        rows = (d >= lo) & (d < hi)
        assert bin_["samples"] == rows.sum()
        assert bin_["median_n"] == pytest.approx(np.sqrt(40.0) * np.median(sigma_f[rows]))
    assert chi2["out_of_domain"]["median_n"] > 1.5 * chi2["in_domain"]["median_n"]
    assert norm["in_domain"]["median_n"] == norm["out_of_domain"]["median_n"] == 1.3
    curve = dut["chi2"]["curve"]
    assert len(curve) == 16 and np.all(np.diff([c["median_n"] for c in curve]) > 0)
    results = {"hybrid": {"detectable_force_vs_domain": dut}, "forest": {}}
    assert plot_detectable_force_vs_domain(results, tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000
    assert not plot_detectable_force_vs_domain({"forest": {}}, tmp_path / "g.png")


@pytest.mark.slow
def test_replayed_evaluation_reports_both_tests_and_the_force_out_of_domain(tmp_path):
    data = ftdrake.collect(ftdrake.ScenarioConfig(), 1, kind="rehearsal", seed=100,
                           duration=14.0, progress=False, n_jobs=1)
    X, Y = ftdrake.joint_state_layout(data)[::8], ftdrake.wrench_targets(data)[::8]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one rehearsal excites the payload poorly
        hybrid = ftdrake.DomainCalibratedHybrid(ftdrake.HybridCompensator(),
                                                holdout=0.2).fit(X, Y)
    plan = DetectionPlan(free_minutes=0.1, kinds=("fourier",), depths_mm=(12.0,),
                         surfaces=("table",), rehearsals=1, calibration_runs_per_kind=0,
                         events=None, tests=("norm", "chi2"))
    results = run_detection_evaluation(tmp_path / "det", {"hybrid": hybrid}, plan=plan,
                                       n_jobs=1, progress=False, run=run_plan_by_replay)
    assert set(results) == {"hybrid (norm)", "hybrid (chi2)"}
    assert results["hybrid (chi2)"]["detector"]["test"] == "chi2"
    assert results["hybrid (norm)"]["detector"]["test"] == "norm"
    for r in results.values():
        assert r["press_count"] == 1 and r["presses"][0]["detected"]
        entry = r["detectable_force_vs_domain"]
        assert entry["samples"] == pytest.approx(6.0 * 1000 / 10, abs=10)
        # The norm test's force is its threshold everywhere (std_gain 0) ...
        force_on = results["hybrid (norm)"]["detector"]["force_on"]
        assert all(b["median_n"] == pytest.approx(force_on)
                   for b in entry["norm"]["bins"].values() if b["samples"])
    # ... the χ² test's is √chi2_on · the largest force std, which the chain gave.
    chi2 = results["hybrid (chi2)"]["detector"]
    curve = results["hybrid (chi2)"]["detectable_force_vs_domain"]["chi2"]["curve"]
    assert min(c["p5_n"] for c in curve) >= np.sqrt(chi2_threshold(
        DetectorConfig(**chi2), PERIOD)) * 0.9 * np.sqrt(hybrid._noise_var()[:3].max())
    text = markdown(results, plan)
    assert "Detectable force in free motion" in text and "χ² >" in text
    # Both results carry the same entry; the table shows it once, under the model's name.
    assert "| hybrid | chi2 |" in text and "| hybrid | norm |" in text
    assert "| hybrid (chi2) | chi2 |" not in text
    for name in ("detection.json", "detection.md", "detectable_force_vs_domain.png"):
        assert (tmp_path / "det" / name).is_file()


def test_compared_tests_skip_the_chi2_test_for_a_model_without_a_reading_std():
    forest = ftdrake.RandomForestCompensator()
    hybrid = ftdrake.HybridCompensator()
    plan = DetectionPlan.quick(tests=("norm", "chi2"))
    assert list(with_tests({"forest": forest, "hybrid": hybrid}, plan)) == [
        "forest (norm)", "hybrid (norm)", "hybrid (chi2)"]
    assert list(with_tests({"forest": forest}, DetectionPlan())) == ["forest"]
    with pytest.raises(ValueError, match="'max' is not 'norm' or 'chi2'"):
        with_tests({"forest": forest}, DetectionPlan(tests=("max",)))
    assert plan.events is None and plan.free_minutes == 2.0 and len(plan.depths_mm) == 5
