"""A predictive std that grows with the motion: recovered from residuals whose true σ(‖q̇‖,
‖q̈‖) is known, honest per motion bin on fresh rows, and the std the loop publishes.

Generated data: rows [q, q̇, q̈] of 3 joints; residuals normal with
σ = √(σ₀² + (α·‖q̇‖ + β·‖q̈‖)²) per axis (the vibration the simulated sensor adds, on a
resting noise), computed here independently of the model's basis."""

import itertools

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.motion_std import (
    MotionNoiseModel,
    MotionStdCompensator,
    motion_levels,
)
from ftdrake.errors import ConfigError
from ftdrake.runtime.compensator import CompensatorSystem

N = 3
SIGMA0 = np.array([0.025, 0.025, 0.05, 0.00125, 0.00125, 0.00125])
ALPHA = np.array([0.15, 0.2, 0.15, 0.006, 0.006, 0.004])  # per rad/s
BETA = np.array([0.03, 0.03, 0.04, 0.001, 0.001, 0.001])  # per rad/s²


def true_std(s, a):
    return np.sqrt(SIGMA0**2 + (np.multiply.outer(s, ALPHA) + np.multiply.outer(a, BETA)) ** 2)


def rows(count, seed, rest_share=0.3):
    """Rows with a share at rest (q̇ = q̈ = 0) and the rest moving at up to ~1.5 rad/s."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1, 1, (count, N))
    qd = rng.normal(0, 0.6, (count, N))
    qdd = rng.normal(0, 2.0, (count, N))
    still = rng.random(count) < rest_share
    qd[still], qdd[still] = 0.0, 0.0
    return np.hstack([q, qd, qdd])


def residuals(X, seed):
    s, a = motion_levels(X)
    return np.random.default_rng(seed).normal(0.0, 1.0, (len(X), 6)) * true_std(s, a)


def test_motion_levels_are_the_norms_of_the_velocity_and_acceleration_blocks():
    X = np.array([[9, 9, 9, 3, 4, 0, 0, 0, 2.0]])
    s, a = motion_levels(X)
    assert s[0] == 5.0 and a[0] == 2.0


def test_the_std_is_recovered_from_residuals_across_rest_and_motion():
    X = rows(40000, 0)
    model = MotionNoiseModel().fit(X, residuals(X, 1))
    # At rest, and on fresh rows of the same motion (where the fit has data).
    np.testing.assert_allclose(model.std_at(0.0, 0.0), SIGMA0, rtol=0.03)
    X_test = rows(2000, 11)
    error = model.predict_std(X_test) / true_std(*motion_levels(X_test)) - 1
    assert np.median(np.abs(error)) < 0.03 and np.abs(error).max() < 0.1
    assert (model.coef_ >= 0).all()


def bin_coverage(model):
    """{bin: coverage per axis} of ±1.96σ on fresh rows, binned by ‖q̇‖."""
    X_test = rows(40000, 4)
    inside = np.abs(residuals(X_test, 5)) <= 1.96 * model.predict_std(X_test)
    s, _ = motion_levels(X_test)
    edges = [-1, 1e-9, 0.6, 1.2, np.inf]
    return {(lo, hi): inside[(s > lo) & (s <= hi)].mean(axis=0)
            for lo, hi in itertools.pairwise(edges)}


def test_coverage_is_honest_in_every_motion_bin_on_fresh_rows():
    """±1.96σ holds 95 % of fresh residuals at rest, slow, medium and fast (each bin and
    axis within 93.5–96.5 %). Without the re-weighting the rows in motion drown those at
    rest, whose coverage then falls below 90 % on some axis."""
    X = rows(40000, 2)
    r = residuals(X, 3)
    for (lo, hi), coverage in bin_coverage(MotionNoiseModel().fit(X, r)).items():
        print(f"‖q̇‖ in ({lo}, {hi}]: coverage {np.round(coverage, 3)}")
        assert (0.935 <= coverage).all() and (coverage <= 0.965).all()
    unweighted = bin_coverage(MotionNoiseModel(iterations=0).fit(X, r))
    assert unweighted[(-1, 1e-9)].min() < 0.9


def test_a_constant_std_is_not_honest_per_bin():
    """The spread of all residuals (the usual constant std) over-covers at rest and
    under-covers at speed: what the motion model is for."""
    X = rows(20000, 6)
    r = residuals(X, 7)
    inside = np.abs(r) <= 1.96 * r.std(axis=0)
    s, _ = motion_levels(X)
    assert inside[s == 0].mean() > 0.99 and inside[s > 1.2].mean() < 0.9


def test_it_follows_the_estimator_contract():
    model = MotionNoiseModel(iterations=2, min_std=1e-4)
    assert model.get_params() == {"iterations": 2, "min_std": 1e-4}
    assert clone(model).get_params() == model.get_params()
    with pytest.raises(NotFittedError):
        model.predict_std(rows(10, 0))
    with pytest.raises(ConfigError, match="iterations"):
        MotionNoiseModel(iterations=-1).fit(rows(20, 0), np.zeros((20, 6)))
    wrapper = MotionStdCompensator(RandomForestCompensator(), cv=1)
    with pytest.raises(ConfigError, match="cv"):
        wrapper.fit(rows(20, 0), np.zeros((20, 6)))


@pytest.fixture(scope="module")
def wrapped():
    """A forest on a smooth wrench of q, its residual the motion-dependent noise; the std
    fitted from 3-fold out-of-fold residuals (a forest fits its own rows too closely)."""
    X = rows(6000, 8)
    mean = np.column_stack([np.sin(X[:, 0]), np.cos(X[:, 1]), X[:, 2], 0.1 * X[:, 0],
                            0.1 * X[:, 1], 0.05 * X[:, 2]])
    model = MotionStdCompensator(RandomForestCompensator(features="q", n_estimators=20,
                                                         min_samples_leaf=20), cv=3)
    return model.fit(X, mean + residuals(X, 9))


def test_the_wrapper_keeps_the_mean_and_gives_the_motion_std(wrapped):
    X = rows(200, 10)
    np.testing.assert_array_equal(wrapped.predict(X), wrapped.estimator_.predict(X))
    s, a = motion_levels(X)
    std = wrapped.predict_std(X)
    np.testing.assert_array_equal(std, wrapped.noise_.predict_std(X))
    # In motion the noise dominates; at rest the forest's own error adds to it.
    moving = s > 0.6
    np.testing.assert_allclose(std[moving], true_std(s, a)[moving], rtol=0.25)
    assert (std[s == 0] >= 0.9 * SIGMA0).all() and (std[s == 0] < 3 * SIGMA0).all()
    predict = wrapped.row_predictor()
    for row in X[:5]:
        mean, std = predict(row)
        np.testing.assert_allclose(mean, wrapped.predict(row[None])[0], rtol=1e-12)
        np.testing.assert_allclose(std, wrapped.predict_std(row[None])[0], rtol=1e-12)


def test_the_loop_publishes_the_motion_std(wrapped):
    """CompensatorSystem's wrench_std: the motion model's σ at the sample's ‖q̇‖, ‖q̈‖."""
    system = CompensatorSystem(wrapped, 0.001)
    context = system.CreateDefaultContext()
    state = np.r_[0.2, -0.1, 0.3, 0.5, -0.4, 0.3]
    acceleration = np.array([1.0, 2.0, -2.0])
    system.get_input_port_wrench_measured().FixValue(context, np.zeros(6))
    system.get_input_port_joint_state().FixValue(context, state)
    system.get_input_port_joint_acceleration().FixValue(context, acceleration)
    updated = system.EvalUniquePeriodicDiscreteUpdate(context)
    context.SetDiscreteState(updated)
    expected = wrapped.noise_.std_at(np.linalg.norm(state[3:]), np.linalg.norm(acceleration))
    np.testing.assert_allclose(system.get_output_port_wrench_std().Eval(context), expected,
                               rtol=1e-12)


def test_the_chi2_detector_whitens_by_the_motion_std(wrapped):
    """The chain's χ² test with the motion std: a steady force that is far above the std at
    rest, and well within it at speed, is contact at rest and not while moving."""
    from ftdrake.config import ChainConfig
    from ftdrake.runtime.chain import CompensationChain
    from ftdrake.runtime.detector import chi2_threshold
    from ftdrake.runtime.step import ChainStep

    config = ChainConfig()
    config.bias_tracker.enabled = False
    config.detector.test = "chi2"
    chain = CompensationChain(wrapped, config)
    threshold = chi2_threshold(chain.config.detector, chain.period)
    q = np.array([0.2, -0.1, 0.3])
    speeds = {"rest": np.zeros(N), "moving": np.full(N, 0.9)}  # ‖q̇‖ 1.56 rad/s
    sigma = {k: wrapped.noise_.std_at(np.linalg.norm(v), 0.0)[0] for k, v in speeds.items()}
    force = np.sqrt(threshold * sigma["rest"] * sigma["moving"])  # between the two
    contact = {}
    for name, v in speeds.items():
        step = ChainStep(chain)
        internal = wrapped.predict(np.r_[q, v, np.zeros(N)][None])[0]
        for k in range(200):
            out = step.update(k * chain.period, internal + np.r_[force, 0, 0, 0, 0, 0],
                              np.r_[q, v])
        np.testing.assert_allclose(out["wrench_std"], wrapped.noise_.std_at(
            np.linalg.norm(v), 0.0), rtol=1e-9, atol=1e-12)
        contact[name] = out["contact"][0]
    assert sigma["moving"] > 3 * sigma["rest"]
    assert contact == {"rest": 1.0, "moving": 0.0}
