"""`ftdrake replay --calibrate-detector`: the detector's thresholds for the budget from a
user's contact-free log, written into a scenario the live station and replay take."""

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2

import ftdrake
from ftdrake import PhysicsPayloadCompensator, ScenarioConfig, save_model
from ftdrake.cli.main import main
from ftdrake.conventions import WRENCH_AXES, WRENCH_UNITS, wrench_columns
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.sim.collection import collect

RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def physics_and_free_log(tmp_path_factory):
    """A physics model trained on one Fourier run, and a held-out one of another seed."""
    folder = tmp_path_factory.mktemp("calibrate_detector")
    config = ScenarioConfig()
    train = collect(config, 1, kind="fourier", seed=11, duration=8.0, n_jobs=1, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # one short run excites the payload only in part
        model = PhysicsPayloadCompensator().fit(joint_state_layout(train), wrench_targets(train))
    save_model(model, folder / "m.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    free = collect(config, 1, kind="fourier", seed=12, duration=8.0, n_jobs=1, progress=False)
    free.to_parquet(folder / "free.parquet")
    return folder


def replay_cli(folder, *extra):
    return main(["replay", "--model", str(folder / "m.ftd"), "--log",
                 str(folder / "free.parquet"), "--out", str(folder / "out.parquet"),
                 "--pairing", "simulated", "--quiet", *extra])


def test_a_contact_free_log_calibrates_the_chi2_test_that_then_stays_quiet_on_it(
        physics_and_free_log, capsys):
    folder = physics_and_free_log
    assert replay_cli(folder, "--calibrate-detector", str(folder / "tuned.yaml")) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    tuned = ftdrake.load_chain_config(folder / "tuned.yaml")  # a chain config
    # auto, calibrating, a physics model: the χ² test.
    assert tuned.detector.test == report["detector"]["test"] == "chi2"
    # Independent: the largest whitened statistic on the judged rows, and the budget's
    # quantile (1 per hour at 1 kHz).
    out = pd.read_parquet(folder / "out.parquet")
    judged = (out["t"] - out["t"].iloc[0]).to_numpy() >= tuned.detector.arm_after_s
    w = out[wrench_columns("wrench_contact")].to_numpy()[judged]
    s = out[wrench_columns("wrench_std")].to_numpy()[judged]
    expected = max(chi2.isf(1.0 / 3600.0 / RATE_HZ, 6), 1.05 * np.max(np.sum((w / s) ** 2, 1)))
    assert tuned.detector.chi2_on == pytest.approx(expected, rel=1e-9)
    # The rest of the scenario and the detector's debounce are the ones replay ran.
    assert tuned.sensor == ftdrake.ChainConfig().sensor  # the log carries no scenario
    assert tuned.detector.debounce_on == ScenarioConfig().chain.detector.debounce_on
    # Replayed with the calibrated chain config, the same motion raises no contact.
    assert replay_cli(folder, "--config", str(folder / "tuned.yaml")) == 0
    again = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert again["contact_samples"] == 0


def test_hand_set_norm_thresholds_are_recalibrated_as_the_norm_test(physics_and_free_log,
                                                                    capsys):
    folder = physics_and_free_log
    hand = ftdrake.ChainConfig()
    hand.detector.force_on = 4.0  # set by hand: "auto" keeps the norm test
    ftdrake.save_config(hand, folder / "hand.yaml")
    assert replay_cli(folder, "--config", str(folder / "hand.yaml"),
                      "--calibrate-detector", str(folder / "norm.yaml")) == 0
    capsys.readouterr()
    tuned = ftdrake.load_chain_config(folder / "norm.yaml").detector
    out = pd.read_parquet(folder / "out.parquet")
    judged = (out["t"] - out["t"].iloc[0]).to_numpy() >= tuned.arm_after_s
    r = out[wrench_columns("wrench_contact")].to_numpy()[judged]
    assert tuned.test == "norm"
    # Independent: per block, max(the largest axis RMS · √(χ²₃ quantile at 1 − p/2), 1.05 ×
    # the largest norm on the log), p = 1 per hour at 1 kHz.
    k = np.sqrt(chi2.isf(1.0 / 3600.0 / RATE_HZ / 2.0, 3))
    rms = np.sqrt(np.mean(r**2, axis=0))
    for block, value in ((slice(0, 3), tuned.force_on), (slice(3, 6), tuned.torque_on)):
        expected = max(k * rms[block].max(), 1.05 * np.linalg.norm(r[:, block], axis=1).max())
        assert value == pytest.approx(expected, rel=1e-9)


def test_a_delay_corrected_only_in_the_replay_is_refused_naming_the_fix(physics_and_free_log,
                                                                         capsys):
    folder = physics_and_free_log
    assert replay_cli(folder, "--delay", "0.01",
                      "--calibrate-detector", str(folder / "delayed.yaml")) != 0
    assert "train with --delay/--align" in capsys.readouterr().err
    assert not (folder / "delayed.yaml").exists()
