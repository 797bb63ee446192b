"""LearnedFeedforward: the GP's correction, its confidence rule, bad input, and learning."""

import logging

import numpy as np
import pytest

from ftdrake.errors import FtdrakeError
from ftdrake.systems.learned_feedforward import (
    MIN_SAMPLES,
    FeedforwardDataError,
    LearnedFeedforward,
    fit_feedforward_gp,
    prior_std,
)

N = 3  # joints


def _data(rows=600, seed=0):
    t = np.linspace(0.0, 6.0, rows)[:, None]
    w = np.array([1.0, 1.7, 2.3])
    q, qd, qdd = np.sin(w * t), w * np.cos(w * t), -(w**2) * np.sin(w * t)
    X = np.hstack([q, qd, qdd])
    tau = 2 * np.sin(q) + 0.5 * np.tanh(qd / 0.3) + 0.1 * qdd
    return X, tau + 1e-3 * np.random.default_rng(seed).normal(size=tau.shape)


@pytest.fixture(scope="module")
def model():
    X, tau = _data()
    return fit_feedforward_gp(X, tau, max_points=120, optimize_points=100)


def _status(dut, x, control):
    context = dut.CreateDefaultContext()
    dut.get_input_port_control().FixValue(context, control)
    dut.get_input_port_desired_state().FixValue(context, x[: 2 * N])
    dut.get_input_port_desired_acceleration().FixValue(context, x[2 * N:])
    return {name: dut.GetOutputPort(name).Eval(context)
            for name in ("control", "correction", "correction_std", "confidence", "status")}


def test_on_the_data_the_correction_is_the_gps_mean(model):
    dut = LearnedFeedforward(model, n_joints=N)
    X, tau = _data(seed=1)
    control = np.array([1.0, 2.0, -3.0])
    for x in X[::97]:
        out = _status(dut, x, control)
        mean = model.predict(x[None])[0]
        std = model.predict_std(x[None])[0]
        np.testing.assert_allclose(out["correction_std"], std, rtol=1e-6, atol=1e-9)
        np.testing.assert_array_equal(out["confidence"], np.ones(N))  # σ ≪ σ₀ on the data
        np.testing.assert_allclose(out["correction"], mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out["control"], control + mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out["status"], np.concatenate(
            [out["correction"], out["correction_std"], out["confidence"]]))
    # The learned function, not only the data: within 2 % of the torque's range.
    correction, _, _ = dut.evaluate(X)
    assert np.abs(correction - tau).max() < 0.02 * np.ptp(tau)


def test_confidence_rule_scales_down_then_zeroes_away_from_the_data(model, caplog):
    dut = LearnedFeedforward(model, n_joints=N, trust_ratio=0.5, reject_ratio=0.9)
    x0 = _data()[0][100]
    sigma0 = prior_std(model)
    ratios, confidences = [], []
    for shift in np.linspace(0.0, 6.0, 25):  # walk off the data in q
        x = x0.copy()
        x[:N] += shift
        _, std, confidence = (a[0] for a in dut.evaluate(x[None]))
        ratios.append(std / sigma0)
        confidences.append(confidence)
    ratios, confidences = np.array(ratios), np.array(confidences)
    expected = np.clip((0.9 - ratios) / 0.4, 0.0, 1.0)  # the documented rule
    np.testing.assert_allclose(confidences, expected, atol=1e-12)
    assert confidences[0].min() == 1.0 and confidences[-1].max() == 0.0
    assert np.any((confidences > 0) & (confidences < 1))  # the linear band is used
    with caplog.at_level(logging.WARNING, logger="ftdrake.systems.learned_feedforward"):
        far = x0.copy()
        far[:N] += 6.0
        out = _status(dut, far, np.zeros(N))
    np.testing.assert_array_equal(out["correction"], np.zeros(N))
    assert "scaled to zero" in caplog.text and "outside the data" in caplog.text


def test_bad_input_is_a_clear_error(model):
    X, tau = _data()
    with pytest.raises(FeedforwardDataError, match=f"need >= {MIN_SAMPLES}"):
        fit_feedforward_gp(X[: MIN_SAMPLES - 1], tau[: MIN_SAMPLES - 1])
    with pytest.raises(FtdrakeError, match="N × 3n"):
        fit_feedforward_gp(X[:, :-1], tau)
    bad = tau.copy()
    bad[5, 1] = np.nan
    with pytest.raises(FeedforwardDataError, match="NaN"):
        fit_feedforward_gp(X, bad)
    with pytest.raises(FeedforwardDataError, match="3 joints; the arm has 7"):
        LearnedFeedforward(model, n_joints=7)


def test_latency_path_equals_batch_path(model):
    dut = LearnedFeedforward(model)
    X = _data(seed=2)[0][::50] + 0.3
    correction, std, confidence = dut.evaluate(X)
    for i, x in enumerate(X):
        row = dut.evaluate_one(x)
        np.testing.assert_allclose(row, np.concatenate([correction[i], std[i], confidence[i]]),
                                   rtol=1e-9, atol=1e-12)
    row = dut.evaluate_one(np.full(3 * N, np.nan))  # a non-finite input: no correction
    np.testing.assert_array_equal(row[:N], 0.0)
    np.testing.assert_array_equal(row[2 * N:], 0.0)


@pytest.mark.slow
def test_learning_in_the_loop_beats_ilc_on_a_new_trajectory(tmp_path):
    from ftdrake.compensation.files.persistence import load_model
    from ftdrake.experiments.feedforward import FeedforwardPlan, run_feedforward_experiment

    # 6 s: a 3 s Fourier run fades in so fast that its first run's tracking error takes the
    # arm's states far from the desired ones, and the GP (fitted on the states the arm was
    # in) then has no data where the desired trajectory goes (see the report's limits).
    plan = FeedforwardPlan(iterations=1, trajectory="fourier", duration_s=6.0, seed=3,
                           max_points=150, optimize_points=120)
    summary = run_feedforward_experiment(plan=plan, out_dir=tmp_path, progress=False)
    gp, ilc = summary["task"]["gp"], summary["task"]["ilc"]
    assert gp["improvement"] > 5  # one iteration of the GP
    assert gp["tip_rms_mm"][-1] < ilc["tip_rms_mm"][-1]
    general = summary["generalisation"]
    assert general["gp"]["improvement"] > 3 > general["ilc"]["improvement"]
    for name in ("summary.json", "iterations.csv", "tracking.png"):
        assert (tmp_path / name).stat().st_size > 0
    model = load_model(tmp_path / "feedforward_model.ftd", expect_n_joints=7)
    LearnedFeedforward(model, n_joints=7)
