"""Detector thresholds from a false-positive budget (offline.thresholds)."""

import numpy as np
import pytest
from scipy.stats import chi2

from ftdrake.config import DetectorConfig, parse_config
from ftdrake.errors import ConfigError
from ftdrake.offline.thresholds import (
    armed,
    thresholds_for_false_positive_rate,
    thresholds_from_quantile,
)

SIGMA = np.array([0.03, 0.03, 0.03, 0.002, 0.002, 0.002])  # N, N·m


def test_gaussian_residuals_exceed_the_thresholds_at_the_budgeted_rate():
    rng = np.random.default_rng(0)
    rate_hz, budget = 1000.0, 720.0  # false positives per hour: 1e-4 per sample each F, T
    held_out = rng.normal(0, SIGMA, (1000, 6))
    dut = thresholds_for_false_positive_rate(held_out, sample_rate_hz=rate_hz,
                                             false_positives_per_hour=budget)
    fresh = rng.normal(0, SIGMA, (2_000_000, 6))
    over = ((np.linalg.norm(fresh[:, :3], axis=1) > dut.force_on)
            | (np.linalg.norm(fresh[:, 3:], axis=1) > dut.torque_on))
    expected = budget / 3600 / rate_hz * len(fresh)  # 400 samples
    # The scale comes from 1000 held-out samples (RMS to ~2 %), which moves a 4.8 σ tail by
    # ~20 % (this seed: 325 of 400). Not splitting the budget between force and torque
    # gives 635, a χ with 1 or 6 degrees of freedom 5707 or 12: all fail.
    assert 0.6 * expected < over.sum() < 1.5 * expected


def test_the_gaussian_term_is_the_chi_quantile_of_the_largest_axis_rms():
    residual = np.random.default_rng(1).normal(0, SIGMA, (1000, 6))
    dut = thresholds_for_false_positive_rate(residual, sample_rate_hz=1000.0)
    p = 1.0 / 3600 / 1000 / 2  # one per hour, split between force and torque
    rms = np.sqrt(np.mean(residual**2, axis=0))
    assert dut.force_on == pytest.approx(np.sqrt(chi2.isf(p, 3)) * rms[:3].max(), rel=1e-12)
    assert dut.torque_on == pytest.approx(np.sqrt(chi2.isf(p, 3)) * rms[3:].max(), rel=1e-12)


def test_heavy_tails_never_fire_on_the_data_that_set_the_thresholds():
    rng = np.random.default_rng(2)
    residual = rng.normal(0, SIGMA, (5000, 6))
    residual[2500:2510, 0] += 2.0  # a burst where the motion left the training data
    dut = thresholds_for_false_positive_rate(residual, sample_rate_hz=1000.0)
    assert np.linalg.norm(residual[:, :3], axis=1).max() < dut.force_on
    assert dut.force_on == pytest.approx(1.05 * np.linalg.norm(residual[:, :3], axis=1).max())


@pytest.mark.parametrize("residual, kwargs, match", [
    (np.zeros((50, 6)), {}, "N >= 100"),
    (np.zeros((200, 5)), {}, "N × 6"),
    (np.full((200, 6), np.nan), {}, "NaN"),
    (np.ones((200, 6)), {"false_positives_per_hour": 0.0}, "must be positive"),
])
def test_bad_input_is_refused(residual, kwargs, match):
    with pytest.raises(ValueError, match=match):
        thresholds_for_false_positive_rate(residual, sample_rate_hz=1000.0, **kwargs)


def test_the_unarmed_start_up_does_not_set_the_thresholds():
    # A simulated run starts with a controller transient the detector does not judge (it arms
    # after arm_after_s): a spike there must not raise the thresholds.
    rng = np.random.default_rng(3)
    t = np.arange(20_000) / 1000.0
    residual = rng.normal(0, [0.025, 0.025, 0.05, 1e-3, 1e-3, 1e-3], (len(t), 6))
    residual[:3] += [0.5, 0, 0, 0.03, 0, 0]  # the first 3 ms
    judged = armed(t, DetectorConfig().arm_after_s)
    assert judged.sum() == len(t) - 50 and not judged[:50].any()
    with_start = thresholds_for_false_positive_rate(residual, sample_rate_hz=1000)
    armed_only = thresholds_for_false_positive_rate(residual[judged], sample_rate_hz=1000)
    assert with_start.force_on > 0.5 and with_start.torque_on > 0.03
    assert armed_only.force_on < 0.4 and armed_only.torque_on < 0.01


def test_the_budget_is_the_scenarios_and_the_thresholds_record_it():
    residual = np.random.default_rng(4).normal(0, SIGMA, (1000, 6))
    scenario = parse_config("detector: {false_positives_per_hour: 10.0}")
    dut = thresholds_for_false_positive_rate(
        residual, sample_rate_hz=1000.0,
        false_positives_per_hour=scenario.chain.detector.false_positives_per_hour)
    p = 10.0 / 3600 / 1000 / 2
    rms = np.sqrt(np.mean(residual**2, axis=0))
    assert dut.force_on == pytest.approx(np.sqrt(chi2.isf(p, 3)) * rms[:3].max(), rel=1e-12)
    assert dut.false_positives_per_hour == 10.0
    # Without a budget: the config tree's default (one per hour), recorded as well.
    default = thresholds_for_false_positive_rate(residual, sample_rate_hz=1000.0)
    assert default.false_positives_per_hour == DetectorConfig().false_positives_per_hour == 1.0
    assert default.force_on > dut.force_on
    with pytest.raises(ConfigError, match=r"detector\.false_positives_per_hour"):
        parse_config("detector: {false_positives_per_hour: 0.0}")


def test_quantile_thresholds_are_the_margin_times_the_norms_quantile_floored():
    rng = np.random.default_rng(5)
    residual = rng.normal(0, [0.5, 0.5, 0.5, 1e-3, 1e-3, 1e-3], (2000, 6))
    dut = thresholds_from_quantile(residual, margin=2.0, quantile=0.99, debounce_on=5)
    force = np.sort(np.linalg.norm(residual[:, :3], axis=1))
    assert force[1979] <= dut.force_on / 2.0 <= force[1980]  # the 0.99 quantile of 2000
    assert dut.torque_on == 0.02  # the floor: the torque residual is far below it
    assert dut.debounce_on == 5
