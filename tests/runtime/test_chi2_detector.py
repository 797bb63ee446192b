"""The detector's χ² test (DetectorConfig.test = "chi2"): the whitened 6-D wrench against the
χ²₆ quantile of the false-positive budget."""

import dataclasses as dc
import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from scipy.stats import chi2

from ftdrake.config import (
    ChainConfig,
    DetectorConfig,
    default_scenario_path,
    load_config,
    parse_config,
)
from ftdrake.errors import ConfigError
from ftdrake.offline.thresholds import (
    chi2_on_for_false_positive_rate,
    detectable_force,
    thresholds_for_false_positive_rate,
)
from ftdrake.runtime.detector import ContactDetector, chi2_threshold, detect_chi2

RATE_HZ = 1000.0
# 3600 per hour at 1 kHz: p = 1e-3 per sample, 1000 expected in 10⁶ samples (Poisson σ 32).
BUDGET = 3600.0
ONE_SAMPLE = {"debounce_on": 1, "debounce_off": 1, "release_ratio": 1.0}


def flagged_fraction(w, std, config):
    """The share of samples the compiled χ²-test kernel flags, with no debounce and no
    hysteresis (each sample judged alone)."""
    constants = np.array([chi2_threshold(config, 1.0 / RATE_HZ), config.release_ratio,
                          config.debounce_on, config.debounce_off])
    flag, counter, force = np.zeros(1), np.zeros(1), np.zeros(1)
    hits = 0
    for i in range(len(w)):
        detect_chi2(w[i], std[i], constants, flag, counter, force)
        hits += flag[0] > 0.5
    return hits / len(w)


def test_false_positive_rate_on_gaussian_data_is_the_budgets():
    rng = np.random.default_rng(0)
    n = 1_000_000
    # A std that changes from sample to sample and axis to axis (in and out of domain): the
    # whitened test holds the same rate everywhere.
    std = np.array([0.03, 0.03, 0.05, 0.002, 0.002, 0.002]) * rng.uniform(0.5, 20.0, (n, 1))
    std *= rng.uniform(0.8, 1.2, (n, 6))
    w = rng.normal(size=(n, 6)) * std
    config = DetectorConfig(test="chi2", false_positives_per_hour=BUDGET, **ONE_SAMPLE)
    p = BUDGET / 3600 / RATE_HZ
    assert chi2_threshold(config, 1 / RATE_HZ) == pytest.approx(chi2.isf(p, 6), rel=1e-12)
    got = flagged_fraction(w, std, config)
    print("false-positive fraction", got, "expected", p)
    # Within 4 Poisson σ of 1000 (measured 0.00100). A wrong tail fails: χ²₃'s quantile
    # would give 0.012, 1 − p/2 0.0005, the norm's p/2 split 0.0005.
    assert abs(got - p) < 4 * np.sqrt(p / n)
    high = chi2.isf(p / 2, 6)
    assert abs(np.mean(np.sum((w / std) ** 2, axis=1) > high) - p) > 4 * np.sqrt(p / n)


def run(wrench, std, seconds=0.2, tracker_std=None):
    """The χ² detector on constant inputs for `seconds`: (detector, its contact flag)."""
    config = DetectorConfig(test="chi2", debounce_on=3, arm_after_s=0.0)
    builder = DiagramBuilder()
    dut = builder.AddSystem(ContactDetector(config, 0.001))
    inputs = {dut.get_input_port_wrench_contact(): wrench, dut.get_input_port_wrench_std(): std}
    if tracker_std is not None:
        inputs[dut.get_input_port_wrench_std_tracker()] = tracker_std
    for port, value in inputs.items():
        source = builder.AddSystem(ConstantVectorSource(np.asarray(value, float)))
        builder.Connect(source.get_output_port(), port)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(seconds)
    context = dut.GetMyContextFromRoot(simulator.get_context())
    return dut, dut.get_output_port_contact().Eval(context)[0]


def test_detector_in_a_diagram_fires_on_a_whitened_excess_and_keeps_debounce():
    dut, _ = run(np.zeros(6), np.ones(6))
    k = np.sqrt(dut.chi2_on)  # ≈ 6.5 σ at 1 per hour and 1 kHz
    sigma = np.array([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])
    assert run([1.1 * k * 0.1, 0, 0, 0, 0, 0], sigma)[1] == 1.0
    assert run([0.9 * k * 0.1, 0, 0, 0, 0, 0], sigma)[1] == 0.0
    # The same force out of domain, where the model's std is 3× larger: no contact.
    assert run([1.1 * k * 0.1, 0, 0, 0, 0, 0], 3 * sigma)[1] == 0.0


def test_the_trackers_std_is_added_in_quadrature():
    """The model's std 0.6 σ and the tracker's 0.8 σ whiten as σ (√(0.36 + 0.64)): a force
    just over the threshold at σ is contact, just under it is not. Summed stds (1.4 σ) or
    the tracker's left out (0.6 σ) would turn one of the two answers round."""
    dut, _ = run(np.zeros(6), np.ones(6))
    k = np.sqrt(dut.chi2_on)
    sigma = np.array([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])
    assert run([1.1 * k * 0.1, 0, 0, 0, 0, 0], 0.6 * sigma, tracker_std=0.8 * sigma)[1] == 1.0
    assert run([0.9 * k * 0.1, 0, 0, 0, 0, 0], 0.6 * sigma, tracker_std=0.8 * sigma)[1] == 0.0


def test_thresholds_for_the_chi2_test_from_held_out_data():
    rng = np.random.default_rng(1)
    std = np.array([0.03, 0.03, 0.05, 0.002, 0.002, 0.002]) * rng.uniform(1, 5, (5000, 1))
    residual = rng.normal(size=(5000, 6)) * std
    dut = thresholds_for_false_positive_rate(residual, sample_rate_hz=RATE_HZ, std=std,
                                             test="chi2")
    assert dut.test == "chi2"
    assert dut.chi2_on == pytest.approx(chi2.isf(1 / 3600 / RATE_HZ, 6), rel=1e-12)
    residual[100] = 40 * std[100]  # where the model is unsure and does not say so
    burst = chi2_on_for_false_positive_rate(residual, std, sample_rate_hz=RATE_HZ,
                                            false_positives_per_hour=1.0)
    assert burst == pytest.approx(1.05 * 6 * 40 ** 2)
    with pytest.raises(ValueError, match="std"):
        thresholds_for_false_positive_rate(residual, sample_rate_hz=RATE_HZ, test="chi2")
    # The detectable force grows with the std (χ²) and does not (norm).
    forces = detectable_force(dut, np.vstack([std[0], 4 * std[0]]), 1 / RATE_HZ)
    assert forces[1] == pytest.approx(4 * forces[0])
    assert np.ptp(detectable_force(DetectorConfig(test="norm"),
                                   np.vstack([std[0], 4 * std[0]]), 1e-3)) == 0
    with pytest.raises(ConfigError, match="for_model"):
        detectable_force(DetectorConfig(chi2_on=45.0), std[:2], 1e-3)
    # "auto" on held-out data: the χ² test when the model's std is given, else the norm test.
    assert thresholds_for_false_positive_rate(residual, sample_rate_hz=RATE_HZ, std=std,
                                              test="auto").test == "chi2"
    assert thresholds_for_false_positive_rate(residual, sample_rate_hz=RATE_HZ,
                                              test="auto").test == "norm"


def test_config_names_bad_tests_and_the_chain_refuses_a_model_without_std():
    with pytest.raises(ConfigError, match=r"detector\.test"):
        parse_config("chain: {detector: {test: chi3}}")
    with pytest.raises(ConfigError, match=r"detector\.chi2_on"):
        parse_config("chain: {detector: {chi2_on: -1.0}}")
    assert parse_config("chain: {detector: {test: chi2}}").chain.detector.test == "chi2"
    from ftdrake.compensation.estimators.forest import RandomForestCompensator
    from ftdrake.config import ScenarioConfig
    from ftdrake.runtime.chain import CompensationChain

    X = np.random.default_rng(2).uniform(-1, 1, (200, 21))
    forest = RandomForestCompensator(features="q", n_estimators=2).fit(X, np.zeros((200, 6)))
    scenario = ScenarioConfig()
    scenario = scenario.with_chain(detector=dc.replace(scenario.chain.detector, test="chi2"))
    with pytest.raises(ConfigError, match="forest's spread"):
        CompensationChain(forest, scenario.chain_config())


def fitted_physics():
    """A physics model of the scenario's arm on generated rows (only its kind matters)."""
    from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
    rng = np.random.default_rng(3)
    X = np.hstack([rng.uniform(-1, 1, (300, 7)), rng.normal(0, 0.3, (300, 14))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # generated rows do not excite the payload
        return PhysicsPayloadCompensator().fit(X, rng.normal(0, 0.05, (300, 6)))


def test_auto_is_the_calibrated_chi2_test_for_a_model_with_a_reading_std_else_norm():
    from ftdrake.compensation.estimators.forest import RandomForestCompensator
    from ftdrake.config import ScenarioConfig
    from ftdrake.runtime.chain import CompensationChain

    assert DetectorConfig().test == "auto"
    assert load_config(default_scenario_path()).chain.detector.test == "auto"  # the shipped YAML
    physics = fitted_physics()
    X = np.random.default_rng(2).uniform(-1, 1, (200, 21))
    forest = RandomForestCompensator(features="q", n_estimators=2).fit(X, np.zeros((200, 6)))
    # Thresholds about to be set from held-out motion: χ² for a std of a reading only.
    assert DetectorConfig().for_model(physics, calibrating=True).test == "chi2"
    assert DetectorConfig().for_model(forest, calibrating=True).test == "norm"
    # In a chain: a χ² threshold given makes it the χ² test, for a model that can run it.
    given = ScenarioConfig().with_chain(detector=DetectorConfig(chi2_on=45.0))
    chain = CompensationChain(physics, given.chain_config())
    assert chain.config.detector.test == "chi2" and chain.detector.config.test == "chi2"
    assert chain.detector.chi2_on == 45.0
    assert CompensationChain(forest, given.chain_config()).detector.config.test == "norm"
    # Uncalibrated (the budget's quantile would trust a std never checked on held-out
    # motion): the norm test's defaults.
    assert CompensationChain(physics, ChainConfig()).detector.config.test == "norm"
    # Norm thresholds set by hand are meant to be used.
    hand = DetectorConfig(force_on=4.0, chi2_on=45.0)
    assert hand.for_model(physics).test == hand.for_model(physics, calibrating=True).test \
        == "norm"
    assert DetectorConfig(std_gain=2.0).for_model(physics, calibrating=True).test == "norm"
    # A concrete test is kept, whatever the model.
    assert DetectorConfig(test="norm").for_model(physics, calibrating=True).test == "norm"
    assert DetectorConfig(test="chi2").for_model(physics).test == "chi2"


def test_a_detector_built_alone_resolves_auto_without_a_model_where_it_can():
    assert ContactDetector(DetectorConfig(), 0.001).config.test == "norm"
    assert ContactDetector(DetectorConfig(force_on=3.0), 0.001).config.test == "norm"
    assert ContactDetector(DetectorConfig(test="chi2"), 0.001).config.test == "chi2"
    with pytest.raises(ConfigError, match=r"for_model\(model\)"):
        ContactDetector(DetectorConfig(chi2_on=45.0), 0.001)
