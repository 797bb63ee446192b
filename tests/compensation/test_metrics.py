"""Per-axis metrics against hand computation, and refusal of bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ftdrake.compensation.evaluation import metrics

# Two axes, three rows; every value below is worked out by hand.
Y_TRUE = np.array([[1.0, 10.0], [2.0, 10.0], [3.0, 40.0]])
Y_PRED = np.array([[1.0, 13.0], [3.0, 10.0], [2.0, 40.0]])
# errors: axis 0 [0, 1, -1], axis 1 [3, 0, 0]
# var(y): axis 0 = 2/3; axis 1: mean 20, deviations [-10, -10, 20] → (100+100+400)/3 = 200


def test_mse_by_hand():
    np.testing.assert_allclose(metrics.mse(Y_TRUE, Y_PRED), [2 / 3, 3.0])


def test_nmse_by_hand():
    np.testing.assert_allclose(metrics.nmse(Y_TRUE, Y_PRED), [(2 / 3) / (2 / 3), 3.0 / 200])


def test_variance_score_by_hand():
    # var of errors: axis 0 mean 0 → 2/3; axis 1 mean 1, deviations [2,-1,-1] → 6/3 = 2
    np.testing.assert_allclose(metrics.variance_score(Y_TRUE, Y_PRED), [0.0, 1 - 2 / 200])


def test_variance_score_ignores_offset_but_nmse_does_not():
    y = np.linspace(0, 1, 50)
    assert metrics.variance_score(y, y + 0.5)[0] == pytest.approx(1.0)
    assert metrics.nmse(y, y + 0.5)[0] == pytest.approx(0.25 / np.var(y))


def test_residual_rms_and_noise_ratio_by_hand():
    truth = np.zeros((4, 2))
    estimate = np.array([[1.0, 2.0], [-1.0, 2.0], [1.0, -2.0], [-1.0, -2.0]])
    np.testing.assert_allclose(metrics.residual_rms(truth, estimate), [1.0, 2.0])
    np.testing.assert_allclose(metrics.rms_over_noise(truth, estimate, [0.5, 4.0]), [2.0, 0.5])
    np.testing.assert_allclose(metrics.rms_over_noise(truth, estimate, 2.0), [0.5, 1.0])


def test_noise_ratio_is_one_for_pure_sensor_noise():
    sigma = np.array([0.05, 0.05, 0.05, 0.003, 0.003, 0.003])
    truth = np.zeros((20000, 6))
    noisy = np.random.default_rng(0).normal(0, sigma, truth.shape)
    np.testing.assert_allclose(metrics.rms_over_noise(truth, noisy, sigma), 1.0, atol=0.02)


def test_report_is_json_ready_and_keyed_by_axis():
    rng = np.random.default_rng(1)
    truth = rng.normal(size=(100, 6))
    measured = truth + rng.normal(0, 0.1, truth.shape)
    predicted = truth + 0.2
    predicted[:, 5] = truth[:, 5]
    measured[:, 5] = 7.0  # a constant axis: nmse/variance_score undefined → None
    out = metrics.report(measured, predicted, truth=truth, noise_std=0.1)
    assert list(out) == ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]
    assert set(out["Fx"]) == {"mse", "nmse", "variance_score", "rms_vs_truth", "rms_over_noise"}
    assert out["Fx"]["rms_vs_truth"] == pytest.approx(0.2)
    assert out["Fx"]["rms_over_noise"] == pytest.approx(2.0)
    assert out["Tz"]["nmse"] is None and out["Tz"]["variance_score"] is None
    json.dumps(out, allow_nan=False)


def test_report_names_and_one_dimensional_input():
    out = metrics.report(Y_TRUE, Y_PRED, target_names=["tau_1", "tau_2"])
    assert out["tau_2"]["mse"] == pytest.approx(3.0)
    assert list(metrics.report(Y_TRUE[:, 0], Y_PRED[:, 0])) == ["y0"]
    assert "rms_vs_truth" not in out


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: metrics.mse(Y_TRUE, Y_PRED[:2]), r"shape \(3, 2\) but y_pred has shape \(2, 2\)"),
        (lambda: metrics.mse(Y_TRUE, Y_PRED[:, :1]), "shape"),
        (lambda: metrics.nmse(np.empty((0, 2)), np.empty((0, 2))), "non-empty"),
        (lambda: metrics.rms_over_noise(Y_TRUE, Y_PRED, [1.0, 0.0]), "positive"),
        (lambda: metrics.rms_over_noise(Y_TRUE, Y_PRED, [1.0, 1.0, 1.0]), "2 values"),
        (lambda: metrics.report(Y_TRUE, Y_PRED, noise_std=0.1), "needs truth"),
        (lambda: metrics.report(Y_TRUE, Y_PRED, target_names=["a"]), "2 distinct"),
        (lambda: metrics.report(Y_TRUE, Y_PRED, truth=Y_TRUE[:, :1]), "truth has shape"),
    ],
)
def test_bad_input_is_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@given(
    arrays(np.float64, (6, 3), elements=st.floats(-1e3, 1e3)),
    st.integers(0, 5),
    st.integers(0, 2),
    st.sampled_from([np.nan, np.inf, -np.inf]),
)
def test_any_nonfinite_value_is_refused(values, row, col, bad):
    corrupt = values.copy()
    corrupt[row, col] = bad
    for fn in (metrics.mse, metrics.nmse, metrics.variance_score, metrics.residual_rms):
        with pytest.raises(ValueError, match=f"first at row {row}"):
            fn(values, corrupt)
        with pytest.raises(ValueError, match="before scoring"):
            fn(corrupt, values)
