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


def test_a_start_transient_is_left_out_of_the_threshold_and_reported(physics_and_free_log,
                                                                      capsys):
    """Issue 42 item 13: a start transient set the χ² threshold 15× too high (the worst case
    over the log). The robust term gives the log with a transient nearly the threshold of the
    log without it, and the transient is reported (times, size)."""
    folder = physics_and_free_log
    free = pd.read_parquet(folder / "free.parquet")
    t = free["t"].to_numpy() - free["t"].iloc[0]
    start = ftdrake.ChainConfig().detector.arm_after_s
    kick = np.where(t >= start, 8.0 * np.exp(-(t - start) / 0.03), 0.0)  # N, decays in ~0.1 s
    free.assign(meas_Fx=free["meas_Fx"] + kick, meas_Ty=free["meas_Ty"] - 0.1 * kick
                ).to_parquet(folder / "kicked.parquet")
    chi2_on, norm_on = {}, {}
    for name in ("free", "kicked"):
        assert main(["replay", "--model", str(folder / "m.ftd"), "--log",
                     str(folder / f"{name}.parquet"), "--out", str(folder / f"{name}.csv"),
                     "--pairing", "simulated", "--calibrate-detector",
                     str(folder / f"{name}.yaml")]) == 0
        captured = capsys.readouterr()
        report = json.loads(captured.out.strip().splitlines()[-1])["detector"]
        chi2_on[name] = report["chi2_on"]
        norm_on[name] = np.array([report["force_on"], report["torque_on"]])
        if name == "free":
            assert report["ignored_outliers"] == []
            continue
        # Independent: the worst case over the judged rows, which the old rule took.
        out = pd.read_csv(folder / "kicked.csv")
        judged = (out["t"] - out["t"].iloc[0]).to_numpy() >= start
        w = out[wrench_columns("wrench_contact")].to_numpy()[judged]
        s = out[wrench_columns("wrench_std")].to_numpy()[judged]
        worst = np.sum((w / s) ** 2, 1)
        assert 1.05 * worst.max() > 5 * chi2_on["free"]  # the transient would have set it
        [outlier] = report["ignored_outliers"]
        assert outlier["statistic"] == "chi2"
        assert outlier["peak"] == pytest.approx(worst.max(), rel=1e-9)
        assert start <= outlier["t_first"] - out["t"].iloc[0] <= outlier["t_peak"] - out[
            "t"].iloc[0] <= outlier["t_last"] - out["t"].iloc[0] < start + 1.0
        assert ("warning: --calibrate-detector: 1 stretch(es) of the log were left out of the "
                "threshold" in captured.err and "chi2 above its threshold" in captured.err)
    assert chi2_on["kicked"] == pytest.approx(chi2_on["free"], rel=0.1)
    # The norm test's thresholds (kept for a switch back) leave the transient out too.
    np.testing.assert_allclose(norm_on["kicked"], norm_on["free"], rtol=0.1)


def test_replay_and_evaluate_take_a_time_window(physics_and_free_log, capsys):
    """Issue 42 item 13: --t-start/--t-end (s, the log's time) choose the rows replayed and
    evaluated."""
    folder = physics_and_free_log
    t = pd.read_parquet(folder / "free.parquet")["t"].to_numpy()
    inside = int(((t >= 2.0) & (t <= 3.5)).sum())
    assert 0 < inside < len(t)
    assert replay_cli(folder, "--t-start", "2", "--t-end", "3.5") == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    out = pd.read_parquet(folder / "out.parquet")
    assert report["rows"] == len(out) == inside == report["time_window"]["rows"]
    assert out["t"].min() >= 2.0 and out["t"].max() <= 3.5
    assert main(["evaluate", "--model", str(folder / "m.ftd"), "--data",
                 str(folder / "free.parquet"), "--t-start", "2", "--t-end", "3.5",
                 "--json", str(folder / "eval.json"), "--quiet"]) == 0
    capsys.readouterr()
    assert json.loads((folder / "eval.json").read_text())["rows"]["used"] == inside
    assert replay_cli(folder, "--t-start", "100") != 0
    assert "--t-start/--t-end keep 0 rows of the log" in capsys.readouterr().err
