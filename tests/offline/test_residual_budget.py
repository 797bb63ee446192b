"""The residual budget recovers a drift, a stream delay and a sensor filter injected into a
log, and each one's share; on a replayed simulated log with the sensor's stream delay on it
finds that delay."""

import json
import re

import numpy as np
import pandas as pd
import pytest

import ftdrake
from ftdrake.cli.main import main
from ftdrake.data.robot_log import resample_uniform
from ftdrake.offline.residual_budget import SHARES, decompose, residual_budget

PERIOD = 1e-3  # s
NOISE = np.array([0.03, 0.03, 0.05, 1e-3, 1e-3, 1e-3])  # N, N·m


def predicted_wrench(t, seed=0):
    """A model's predicted reading in motion: sums of sines from 0.3 to 6 Hz (N, N·m)."""
    rng = np.random.default_rng(seed)
    scale = np.array([3.0, 3.0, 5.0, 0.3, 0.3, 0.2])
    freqs = np.array([0.3, 0.8, 1.7, 3.1, 6.0])
    amp = rng.uniform(0.3, 1.0, (len(freqs), 6)) / freqs[:, None] ** 0.5
    phase = rng.uniform(0, 2 * np.pi, (len(freqs), 6))
    return 2.0 + scale * np.einsum("fa,tfa->ta", amp,
                                   np.sin(2 * np.pi * freqs[None, :, None] * t[:, None, None]
                                          + phase[None]))


def low_pass(x, fc):
    """First-order low-pass, written out sample by sample (independent of the library's)."""
    alpha = 1.0 - np.exp(-2 * np.pi * fc * PERIOD)
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, len(x)):
        y[k] = y[k - 1] + alpha * (x[k] - y[k - 1])
    return y


def lag(x, samples):
    """x delayed by whole samples (the first value held)."""
    return np.vstack([np.repeat(x[:1], samples, axis=0), x[:-samples]]) if samples else x


def injected(delay_samples=0, fc=None, slope=None, seconds=20.0, seed=1):
    t = np.arange(0, seconds, PERIOD)
    P = predicted_wrench(t)
    reading = lag(P, delay_samples)
    if fc is not None:
        reading = low_pass(reading, fc)
    drift = np.zeros_like(P) if slope is None else 0.05 + np.outer(t, slope)
    noise = np.random.default_rng(seed).standard_normal(P.shape) * NOISE
    return t, P, reading + drift + noise - P, {"drift": drift, "noise": noise}


def oracle_shares(t, P, r, drift, delay_s, fc):
    """The shares by their definition with the true effects: the drift's mean's and the
    rest of the drift's gains, then the
    Shapley split of the true delay's and filter's gains (own shift and filter)."""
    def ms(x):
        return np.mean(x[100:-100] ** 2, axis=0)
    m = r - drift + P
    drift_mean = drift[100:-100].mean(axis=0)
    k = round(delay_s / PERIOD)
    e0, ed = ms(m - P), ms(m - lag(P, k))
    ef = ms(m - low_pass(P, fc)) if fc else e0
    edf = ms(m - low_pass(lag(P, k), fc)) if fc else ed
    total = ms(r)
    offset = ms(r - drift_mean)
    return {"offset": (total - offset) / total, "drift": (offset - e0) / total,
            "delay": 0.5 * (e0 - ed + ef - edf) / total,
            "filter": 0.5 * (e0 - ef + ed - edf) / total, "remainder": edf / total}


@pytest.mark.parametrize(("delay", "fc", "slope"), [
    (15, None, None),                            # a stream delay alone
    (0, 4.0, None),                              # the sensor's filter alone
    (0, None, [0.01, -0.01, 0.02, 4e-4, 0, -4e-4]),  # drift alone (N/s, N·m/s)
    (12, 3.0, [0.01, -0.01, 0.02, 4e-4, 0, -4e-4]),  # all three
])
def test_the_budget_recovers_injected_effects_and_their_shares(delay, fc, slope):
    t, P, r, truth = injected(delay, fc, slope)
    budget = decompose(r, P, t, np.ones(len(t), bool), NOISE)
    assert budget.delay_s == pytest.approx(delay * PERIOD, abs=PERIOD)  # within one sample
    if fc is None:
        assert not np.isfinite(budget.filter_cutoff_hz) or budget.filter_cutoff_hz > 40 * 4.0
    else:
        assert budget.filter_cutoff_hz == pytest.approx(fc, rel=0.15)
    np.testing.assert_allclose(budget.drift_per_s, slope or np.zeros(6),
                               atol=0.1 * np.max(np.abs(slope or [0.01])))
    oracle = oracle_shares(t, P, r, truth["drift"], delay * PERIOD, fc)
    for name in SHARES:
        np.testing.assert_allclose(budget.shares[name], oracle[name], atol=0.03, err_msg=name)
    np.testing.assert_allclose(sum(budget.shares.values()), 1.0, atol=1e-9)
    # What is left is the noise.
    np.testing.assert_allclose(budget.remainder_rms, NOISE, rtol=0.1)


def test_a_model_that_explains_the_log_leaves_only_noise():
    t, P, r, _ = injected()
    budget = decompose(r, P, t, np.ones(len(t), bool), NOISE)
    assert max(abs(budget.shares[name]).max() for name in ("drift", "delay", "filter")) < 0.01
    np.testing.assert_allclose(budget.motion_over_noise, 1.0, atol=0.05)


def test_a_non_uniform_log_is_refused():
    t, P, r, _ = injected(seconds=2.0)
    t = t.copy()
    t[500:] += 0.05  # a gap
    with pytest.raises(ftdrake.LogError, match="uniformly"):
        decompose(r, P, t, np.ones(len(t), bool), NOISE)


@pytest.fixture(scope="module")
def delayed_logs():
    """Short demo-arm runs: a training log with the streams in step (a model trained on
    aligned streams) and a held-out one whose wrench stream lags by 8 ms."""
    config = ftdrake.ScenarioConfig()
    # Two runs: a payload model fitted on one 10 s run is poorly excited, and its error, which
    # follows the wrench's rate, reads as 3 ms less delay.
    train = ftdrake.collect(config, 2, kind="fourier", duration=10.0, progress=False, n_jobs=1)
    config.sensor.stream_delay_s = 0.008
    held_out = ftdrake.collect(config, 1, kind="fourier", duration=8.0, seed=7,
                               progress=False, n_jobs=1)
    return train, held_out


@pytest.fixture(scope="module")
def delayed_replay(delayed_logs):
    """A payload model trained on the aligned runs and the held-out log with the delay."""
    train, held_out = delayed_logs
    model = ftdrake.PhysicsPayloadCompensator(identify_mounting=True,
                                              weight_without_inertia=True)
    model.fit(ftdrake.joint_state_layout(train)[::4], ftdrake.wrench_targets(train)[::4])
    log = held_out.drop(columns="trajectory")
    log.attrs = held_out.attrs
    return model, log


def test_the_budget_of_a_replayed_log_finds_the_sensors_stream_delay(delayed_replay):
    model, log = delayed_replay
    budget = residual_budget(model, log)
    # The sensor's 8 ms, and its 400 Hz first-order filter, which delays motion this slow by
    # 1/(2π·400 Hz) = 0.4 ms (too slow to tell the filter from a delay).
    assert budget.delay_s == pytest.approx(0.008 + 1 / (2 * np.pi * 400), abs=PERIOD)
    assert budget.noise_source == "sensor config"
    assert budget.shares["delay"].sum() > budget.shares["filter"].sum()
    report = budget.as_dict()
    assert set(report["shares"]) == set(SHARES)
    assert isinstance(pd.Series(report["motion_over_noise"]).max(), float)


def test_replay_budget_prints_the_functions_budget(delayed_replay, tmp_path, capsys):
    model, log = delayed_replay
    log.to_parquet(tmp_path / "log.parquet")
    ftdrake.save_model(model, tmp_path / "m.ftd", target_names=ftdrake.WRENCH_AXES,
                       target_units=ftdrake.WRENCH_UNITS)
    assert main(["replay", "--model", str(tmp_path / "m.ftd"), "--log",
                 str(tmp_path / "log.parquet"), "--out", str(tmp_path / "out.csv"),
                 "--budget"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    expected = residual_budget(model, log).as_dict()
    assert report["residual_budget"] == json.loads(json.dumps(expected))


def test_the_resting_noise_is_measured_on_each_still_stretch_about_its_own_mean():
    from ftdrake.offline.residual_budget import _resting_noise
    rng = np.random.default_rng(3)
    n = 3000
    still = np.zeros(n, bool)
    still[200:1200] = still[1800:2800] = True  # two stops at different poses
    reading = np.where(still[:, None], 0.0, 5.0) + rng.standard_normal((n, 6)) * NOISE
    reading[1800:2800] += [2.0, -1.0, 4.0, 0.1, 0.2, -0.1]  # the second pose's load
    frame = pd.DataFrame(reading, columns=[f"meas_{a}" for a in ftdrake.WRENCH_AXES])
    noise, source = _resting_noise(frame, still, None, None)
    assert source == "rest rows"
    np.testing.assert_allclose(noise, NOISE, rtol=0.05)
    few = np.zeros(n, bool)
    few[:50] = True  # too few rows at rest: the configured sensor's σ
    noise, source = _resting_noise(frame, few, None, ftdrake.ScenarioConfig())
    assert source == "sensor config" and noise[2] == pytest.approx(np.hypot(1 / 20, 1 / 20
                                                                             / np.sqrt(12)))


# -- a log whose time steps jitter (issue 42 item 3) --------------------------------------------
def jittering_log(rows=1500, seed=4):
    """A 7-joint log at 100 Hz whose steps jitter 7.7–12.1 ms (a real robot's driver), arm
    moving, with one re-tare event."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.0077, 0.0121, rows))
    frame = pd.DataFrame({"t": t})
    for i in range(7):
        frame[f"q_{i}"] = 0.4 * np.sin(0.8 * t + i)
        frame[f"qd_{i}"] = 0.32 * np.cos(0.8 * t + i)
    for c in [f"meas_{a}" for a in ftdrake.WRENCH_AXES]:
        frame[c] = rng.normal(0, 0.05, rows)
    frame["tared"] = 0
    frame.loc[700, "tared"] = 1
    return frame


def small_model(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (200, 21))
    model = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(X, X[:, :6] * 0.1)
    ftdrake.save_model(model, tmp_path / "m.ftd", target_names=ftdrake.WRENCH_AXES,
                       target_units=ftdrake.WRENCH_UNITS)
    return model, str(tmp_path / "m.ftd")


def test_a_jittering_log_is_refused_before_the_replay_with_the_tolerance_and_the_fix(
        tmp_path, capsys, monkeypatch):
    import ftdrake.offline.replay as replay_module
    import ftdrake.offline.residual_budget as budget_module

    def never(*_, **__):
        raise AssertionError("replayed a log the budget refuses")

    monkeypatch.setattr(budget_module, "replay", never)
    monkeypatch.setattr(replay_module, "replay", never)  # the command imports it when it runs
    frame = jittering_log()
    model, path = small_model(tmp_path)
    message = (r"residual_budget: the log is not sampled uniformly: \d+ of 1499 time steps are "
               r"more than 5% off the median 9\.\d+ ms \(steps 7\.\d+–12\.\d+ ms\); the delay and "
               r"filter are fitted in samples of one period\. Resample it onto a uniform grid at "
               r"the median period: ")
    with pytest.raises(ftdrake.LogError, match=message + r"residual_budget\(\.\.\., "
                                                         r"resample=True\)"):
        residual_budget(model, frame)
    frame.to_csv(tmp_path / "log.csv", index=False)
    assert main(["replay", "--model", path, "--log", str(tmp_path / "log.csv"), "--out",
                 str(tmp_path / "out.csv"), "--budget"]) == 2
    err = capsys.readouterr().err
    assert re.search(message + r"--resample$", err.strip()), err


def test_resample_puts_a_jittering_log_on_a_uniform_grid_and_keeps_its_events(tmp_path, capsys):
    frame = jittering_log()
    frame["line"] = 3.0 * frame["t"] - 1.0  # linear in t: interpolated exactly
    grid = resample_uniform(frame)
    steps = np.diff(grid["t"])
    period = np.median(np.diff(frame["t"]))
    np.testing.assert_allclose(steps, period, rtol=1e-9)
    assert grid["t"].iloc[0] == frame["t"].iloc[0] and grid["t"].iloc[-1] <= frame["t"].iloc[-1]
    np.testing.assert_allclose(grid["line"], 3.0 * grid["t"] - 1.0, atol=1e-12)
    event = frame["t"][frame["tared"] == 1].iloc[0]
    assert grid["tared"].sum() == 1
    assert abs(grid["t"][grid["tared"] == 1].iloc[0] - event) <= period / 2 + 1e-12
    # The command's --resample: the budget runs on the resampled log.
    _, path = small_model(tmp_path)
    frame.drop(columns="line").to_csv(tmp_path / "log.csv", index=False)
    assert main(["replay", "--model", path, "--log", str(tmp_path / "log.csv"), "--out",
                 str(tmp_path / "out.csv"), "--budget", "--resample"]) == 0
    captured = capsys.readouterr()
    assert f"note: --resample: 1500 rows onto a uniform grid of {len(grid)} at" in captured.err
    report = json.loads(captured.out.strip().splitlines()[-1])
    assert report["rows"] == len(grid) and report["residual_budget"]["rows"]["motion"] > 1000


def test_replay_budget_says_which_noise_it_judges_against(tmp_path, capsys):
    """Without rest in the log the budget's σ is the chain config sensor's: a warning says so
    and names --noise-std, which then sets σ (issue 42 item 4)."""
    frame = resample_uniform(jittering_log())
    frame.to_csv(tmp_path / "log.csv", index=False)
    _, path = small_model(tmp_path)
    command = ["replay", "--model", path, "--log", str(tmp_path / "log.csv"), "--out",
               str(tmp_path / "out.csv"), "--budget"]
    assert main(command) == 0
    captured = capsys.readouterr()
    spec = ftdrake.ChainConfig().sensor.spec()
    sigma = np.sqrt(np.asarray(spec.noise_std) ** 2 + np.asarray(spec.resolution) ** 2 / 12)
    assert ("warning: --budget: the log has 0 rows at rest, too few to measure the noise on "
            f"(200 needed): its σ ({', '.join(f'{v:.3g}' for v in sigma)}, N and N·m) is the "
            "chain config sensor's, not necessarily yours; give yours with --noise-std S[,S...]"
            ) in captured.err
    assert json.loads(captured.out.splitlines()[-1])["residual_budget"]["noise_source"] == \
        "sensor config"
    assert main([*command, "--noise-std", "0.05"]) == 0
    captured = capsys.readouterr()
    assert ("note: --budget: in units of the resting noise σ of --noise-std (0.05, 0.05, 0.05, "
            "0.05, 0.05, 0.05)") in captured.err
    budget = json.loads(captured.out.splitlines()[-1])["residual_budget"]
    assert budget["noise_source"] == "given"
    assert set(budget["noise_std"].values()) == {0.05}
    assert main([*command, "--noise-std", "0.05,0.1"]) == 2
    assert "--noise-std gives 2 values: give one, or six" in capsys.readouterr().err


def test_negative_shares_and_a_negative_delay_are_explained():
    """A wrench stream leading the joint states by 10 samples on five axes, Tz in step: the
    shared delay comes out negative and costs Tz; the budget says what both mean (issue 42
    item 5) and prints no −0.0."""
    t = np.arange(0, 20, PERIOD)
    P = predicted_wrench(t)
    reading = P.copy()
    reading[:-10, :5] = P[10:, :5]
    reading[-10:, :5] = P[-1, :5]
    r = reading - P + np.random.default_rng(1).standard_normal(P.shape) * NOISE
    budget = decompose(r, P, t, np.ones(len(t), bool), NOISE)
    assert budget.delay_s < -5 * PERIOD
    negative = [(name, axis) for name in SHARES
                for axis, v in zip(ftdrake.WRENCH_AXES, budget.shares[name], strict=True)
                if round(float(v), 3) < 0]
    assert ("delay", "Tz") in negative
    report = budget.as_dict()
    shares_note, delay_note = report["notes"]
    assert shares_note.startswith("negative shares (" + ", ".join(
        f"{n} {a} {round(float(budget.shares[n][ftdrake.WRENCH_AXES.index(a)]), 3):g}"
        for n, a in negative) + "): correcting that part made that axis's in-motion residual "
        "larger, not smaller")
    assert delay_note == (f"delay_s {budget.delay_s * 1e3:.3g} ms is negative: the wrench "
                          "stream leads the joint states (delay_s > 0 when the wrench lags), "
                          "or the model's error follows the motion's rate and reads as a lead")
    assert "-0.0," not in json.dumps(report) and "-0.0}" not in json.dumps(report)
    in_step = decompose(*[injected(15)[i] for i in (2, 1, 0)], np.ones(20000, bool), NOISE)
    assert in_step.as_dict()["notes"] == []
