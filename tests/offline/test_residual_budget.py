"""The residual budget recovers a drift, a stream delay and a sensor filter injected into a
log, and each one's share; on a replayed simulated log with the sensor's stream delay on it
finds that delay."""

import json

import numpy as np
import pandas as pd
import pytest

import ftdrake
from ftdrake.cli.main import main
from ftdrake.experiments.residual_budget import SHARES, decompose, residual_budget

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
    from ftdrake.experiments.residual_budget import _resting_noise
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
