"""`evaluate` in sensor-σ units when the noise is known, trust flags per output and explained,
and no in-domain score on a handful of rows."""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest

from ftdrake.cli.evaluate import print_evaluation
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.compensation.evaluation.evaluation import (
    MIN_SUBSET_ROWS,
    evaluate_model,
    noise_from_resting_rows,
    target_ranges,
)
from ftdrake.conventions import WRENCH_AXES

TRUTH = np.r_[1.2, 1.2 * np.array([0.01, -0.02, 0.06]), 0.004, 0.0, 0.0, 0.005, 0.0, 0.003,
              0.5, -0.3, 1.0, 0.02, -0.01, 0.03]
SIGMA = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])


def _states(rng, rows, scale=1.0):
    return np.hstack([scale * rng.uniform(-1.5, 1.5, (rows, 7)),
                      scale * rng.uniform(-1, 1, (rows, 7)),
                      scale * rng.uniform(-2, 2, (rows, 7))])


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(0)
    X = _states(rng, 600)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        kin = PhysicsPayloadCompensator().fit(X, rng.standard_normal((600, 6)))
        Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((600, 6))
        model = PhysicsPayloadCompensator().fit(X, Y)
    return model, kin, X, Y


def _report(result, model, X):
    out = io.StringIO()
    print_evaluation({"model": "m.ftd", "model_class": type(model).__name__, "data": "log",
                      "rows": {"used": len(X)}, "target_units": dict.fromkeys(WRENCH_AXES, "N"),
                      **result}, file=out)
    return out.getvalue()


def test_a_model_at_the_noise_floor_scores_one_sigma(fitted):
    model, kin, _, _ = fitted
    rng = np.random.default_rng(1)
    X = _states(rng, 400, scale=0.05)  # small motions: little signal beside the noise
    Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((400, 6))
    result = evaluate_model(model, X, Y, target_names=WRENCH_AXES, noise_std=SIGMA)
    ratio = np.array([result["metrics"]["all"][a]["rms_over_sigma"] for a in WRENCH_AXES])
    nmse = np.array([result["metrics"]["all"][a]["nmse"] for a in WRENCH_AXES])
    assert np.all((ratio > 0.9) & (ratio < 1.15)), ratio
    assert nmse.max() > 0.3  # NMSE alone makes the noise floor look like a poor model
    text = _report(result, model, X)
    assert "rms/σ" in text and "≈1 at the noise floor" in text and "from given" in text


def test_noise_is_estimated_from_resting_rows():
    rng = np.random.default_rng(2)
    X = np.zeros((300, 21))
    X[:, :7] = rng.uniform(-1, 1, 7)  # one pose
    X[100:200, 7:14] = 0.5  # moving in between: not resting
    Y = SIGMA * rng.standard_normal((300, 6)) + np.linspace(0, 5, 300)[:, None] * (
        X[:, 7:8] > 0)
    sigma = noise_from_resting_rows(X, Y, 7)
    np.testing.assert_allclose(sigma, SIGMA, rtol=0.15)
    assert noise_from_resting_rows(X[:, :], Y, 7) is not None
    static = np.zeros_like(X)  # a table of static poses: every row "rests"; no noise from it
    assert noise_from_resting_rows(static, Y, 7) is None


def test_trust_is_per_output_for_a_model_with_a_calibrated_std(fitted):
    model, kin, X_train, Y_train = fitted
    rng = np.random.default_rng(3)
    X = _states(rng, 300)
    X[:, 0] = X_train[:, 0].max() + 0.05  # joint 0 just outside its range on every row
    Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((300, 6))
    result = evaluate_model(model, X, Y, target_names=WRENCH_AXES,
                            training_ranges=target_ranges(Y_train, WRENCH_AXES))
    trust = result["trust"]
    assert result["out_of_domain_fraction"] == 1.0
    assert set(trust["by_cause"]["inputs_outside_range"].values()) == {1.0}
    # Physics extrapolates: its per-target std, not the inputs, decides.
    assert max(trust["untrusted_fraction"].values()) < 0.2, trust["untrusted_fraction"]
    text = _report(result, model, X)
    assert "flag nothing on their own" in text
    # A black box cannot tell: every target of every row outside is flagged.
    forest = RandomForestCompensator(n_estimators=5, random_state=0).fit(X_train, Y_train)
    boxed = evaluate_model(forest, X, Y, target_names=WRENCH_AXES)["trust"]
    assert set(boxed["untrusted_fraction"].values()) == {1.0}


def test_no_in_domain_score_on_a_handful_of_rows(fitted):
    model, kin, _, _ = fitted
    rng = np.random.default_rng(4)
    X = _states(rng, 200, scale=1.14)  # mostly outside the training range
    Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((200, 6))
    result = evaluate_model(model, X, Y, target_names=WRENCH_AXES)
    assert 2 <= result["in_domain_rows"] < MIN_SUBSET_ROWS
    assert result["metrics"]["in_domain"] is None
    text = _report(result, model, X)
    assert f"not given on fewer than {MIN_SUBSET_ROWS} rows" in text


def test_without_sigma_the_table_says_why_and_names_the_flag(fitted):
    """A log with no rest and no --noise-std: no rms/σ column, and the output says so
    (issue 42 item 4; it was dropped without a word)."""
    model, kin, _, _ = fitted
    rng = np.random.default_rng(5)
    X = _states(rng, 300)  # always moving
    Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((300, 6))
    result = evaluate_model(model, X, Y, target_names=WRENCH_AXES)
    assert result["noise"] is None
    text = _report(result, model, X)
    assert "rms/σ" not in text.split("no rms/σ column")[0]
    assert ("no rms/σ column: the log holds no stretch at rest to measure the sensor's noise σ "
            "on (≥ 40 rows in runs of ≥ 20 with every |q̇| < 0.001 rad/s; a table of static "
            "poses has none); give σ with --noise-std S[,S...]") in text


def test_untrusted_means_the_same_for_a_physics_and_a_hybrid_model(fitted):
    """Issue 42 item 7: on the same held-out rows, with the same errors, a hybrid said 100 %
    untrusted (every input outside the range flagged it) where its physics part said 0 %.
    One meaning now: a model with a calibrated std is judged by its std against its own
    in-domain std, whatever its kind; the output says what untrusted means."""
    from ftdrake.compensation.estimators.hybrid import HybridCompensator
    from ftdrake.compensation.evaluation.trust import MEANING

    physics, kin, X_train, Y_train = fitted
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        hybrid = HybridCompensator().fit(X_train, Y_train)
    rng = np.random.default_rng(6)
    X = _states(rng, 300)
    X[:, 0] = X_train[:, 0].max() + 0.05  # joint 0 just outside its range on every row
    Y = kin.regressor(X) @ TRUTH + SIGMA * rng.standard_normal((300, 6))
    ranges = target_ranges(Y_train, WRENCH_AXES)
    results = {name: evaluate_model(m, X, Y, target_names=WRENCH_AXES, training_ranges=ranges)
               for name, m in (("physics", physics), ("hybrid", hybrid))}
    nmse = {name: np.array([r["metrics"]["all"][a]["nmse"] for a in WRENCH_AXES])
            for name, r in results.items()}
    np.testing.assert_allclose(nmse["hybrid"], nmse["physics"], rtol=0.5, atol=0.02)
    for name, result in results.items():
        trust = result["trust"]
        assert set(trust["by_cause"]["inputs_outside_range"].values()) == {1.0}
        assert "inputs_outside_range" not in trust["flagging_causes"], name
        assert max(trust["untrusted_fraction"].values()) < 0.2, (name, trust)
        assert trust["meaning"] == MEANING
        text = _report(result, physics, X)
        assert MEANING in text and "inputs 100 % not flagging" in text
    # The hybrid's in-domain std is its residual's cross-fitted error (σ_in), near the noise.
    np.testing.assert_allclose(results["hybrid"]["trust"]["residual_rms"]["Fx"], SIGMA[0],
                               rtol=0.5)
