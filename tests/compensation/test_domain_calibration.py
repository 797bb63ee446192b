"""Where the support term gets its calibration: runs of the training data held out because
they lie farthest from the others (compensation.domain.farthest_groups,
DomainCalibratedHybrid(holdout=share))."""

import warnings

import numpy as np
import pytest

from ftdrake.compensation.estimators import domain
from ftdrake.compensation.estimators.domain_calibrated import DomainCalibratedHybrid
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.evaluation.metrics import coverage
from tests.helpers import poses, static_readings


def runs(rng, regions, n=300):
    """Static poses, `n` per run, run k's joint offsets in regions[k]; (X, run label)."""
    X = np.vstack([poses(rng, n, lo, hi) for lo, hi in regions])
    return X, np.repeat(np.arange(len(regions)), n)


def test_the_runs_that_go_where_no_other_went_are_held_out():
    rng = np.random.default_rng(1)
    # Eight runs over [−0.8, 0]; runs 3 and 9 also reach [0, 1] — far from every other run.
    regions = [(-0.8, 0.0)] * 10
    regions[3], regions[9] = (-0.8, 1.0), (-0.2, 1.0)
    X, groups = runs(rng, regions)
    held, chosen = domain.farthest_groups(X[:, :7], groups, share=0.2)
    assert sorted(chosen) == [3, 9]
    np.testing.assert_array_equal(held, np.isin(groups, [3, 9]))
    # A share under one run's rows still holds out one whole run: one of the two.
    held, chosen = domain.farthest_groups(X[:, :7], groups, share=0.05)
    assert len(chosen) == 1 and chosen[0] in (3, 9) and held.sum() == 300
    # One run alone: its time blocks; the block that goes to [0, 1] is the one held out.
    X1 = np.vstack([poses(rng, 900, -0.8, 0.0), poses(rng, 100, 0.3, 1.0)])
    held, chosen = domain.farthest_groups(X1[:, :7], None, share=0.1)
    assert chosen == [9] and held[900:].all() and not held[:900].any()


@pytest.mark.parametrize(("share", "message"), [(0.0, "share must be in"),
                                                (0.6, "share must be in")])
def test_a_share_that_leaves_too_little_to_train_on_is_refused(share, message):
    X, groups = runs(np.random.default_rng(0), [(-0.8, 0.0)] * 10, n=30)
    with pytest.raises(ValueError, match=message):
        domain.farthest_groups(X[:, :7], groups, share=share)


def test_held_out_calibration_covers_poses_in_and_out_of_the_training_region():
    rng = np.random.default_rng(0)
    regions = [(-0.8, 0.0)] * 8 + [(-0.8, 1.0)] * 2
    X, groups = runs(rng, regions, n=250)
    Y = static_readings(X, rng)
    physics = PhysicsPayloadCompensator(mode="static", features="q")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation warnings are tested elsewhere
        hybrid = HybridCompensator(physics=physics, identification="consistent")
        model = DomainCalibratedHybrid(hybrid, holdout=0.2, refit=False).fit(X, Y, groups)
        refitted = DomainCalibratedHybrid(hybrid, holdout=0.2, refit=True).fit(X, Y, groups)
    record = model.domain_calibration_
    assert sorted(record["held_out_groups"]) == [8, 9] and record["held_out_rows"] == 500
    assert np.any(model.domain_growth_[:3] > 0)
    assert record["growth"] == model.domain_growth_.tolist()
    sets = {"in": poses(rng, 1000, -0.8, 0.0), "out": poses(rng, 1000, 0.2, 1.0)}
    c95 = {k: coverage(static_readings(v, rng), model.predict(v), model.predict_std(v))
           for k, v in sets.items()}
    print("coverage_95", {k: v.round(3) for k, v in c95.items()}, record)
    assert np.all((c95["in"] >= 0.90) & (c95["in"] <= 0.98)), c95["in"]
    assert np.all((c95["out"] >= 0.88) & (c95["out"] <= 0.995)), c95["out"]
    assert min(record["coverage_95_before"]) < 0.6  # g = 0 did not cover the runs that left
    # The refit trains on every run and keeps the calibrated ℓ and g.
    assert refitted.domain_calibration_["refit"] and refitted.domain_length_ == pytest.approx(
        refitted.domain_calibration_["length"] or np.inf)
    np.testing.assert_allclose(refitted.domain_growth_, refitted.domain_calibration_["growth"])
    assert refitted.domain_distance(X[groups == 9]).max() < 1e-9  # on its data now


def test_a_shared_growth_scales_with_each_axis_training_error():
    rng = np.random.default_rng(2)
    X, groups = runs(rng, [(-0.8, 0.0)] * 8 + [(-0.8, 1.0)] * 2, n=200)
    Y = static_readings(X, rng)
    physics = PhysicsPayloadCompensator(mode="static", features="q")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = DomainCalibratedHybrid(
            HybridCompensator(physics=physics, identification="consistent"), holdout=0.2,
            refit=False, shared_growth=True).fit(X, Y, groups)
        per_axis = domain.calibrate(*calibration_rows(model, X[groups >= 8], Y[groups >= 8]))
    ratio = model.domain_growth_ ** 2 / model.domain_far_var_
    assert ratio.min() > 0 and np.ptp(ratio) < 1e-9 * ratio.max()  # one κ for all axes
    assert model.domain_calibration_["shared_growth"]
    # Per axis (the default) the growths are not in that proportion.
    assert np.ptp(per_axis[2] ** 2 / model.domain_far_var_) > 0.1 * ratio.max()


def calibration_rows(model, X, Y):
    """domain.calibrate's arguments for held-out rows X, Y of a fitted hybrid."""
    Z = model._validated_features(X)
    parameter_var = model.physics_._variance(model.physics_._select(Z), include_noise=False)
    return (model.domain_distance(X), Y - model._physics(Z), model.residual_.predict(Z),
            model._noise_var(), model.domain_far_var_, parameter_var)


def test_a_shared_in_domain_level_scales_with_each_axis_training_error():
    """With in_domain="held_out" and `shared`, σ²_in is one multiple of each axis' floor (the
    residual's training error): errors generated with σ²_in = 1.5 × floor on axes whose floors
    differ ninefold give back that one ratio."""
    rng = np.random.default_rng(3)
    n, floor, far = 20000, np.array([1.0, 4.0, 9.0]), np.array([10.0, 20.0, 30.0])
    d = rng.uniform(0.0, 3.0, n)
    w = domain.weight(d, 1.5)[:, None]
    error = rng.normal(size=(n, 3)) * np.sqrt(w * 1.5 * floor + (1 - w) * far)
    args = (d, error, np.zeros((n, 3)), floor, far, np.zeros((n, 3)))
    _, in_var, growth, _ = domain.calibrate(*args, shared=True, in_domain="held_out")
    ratio = in_var / floor
    assert np.ptp(ratio) < 1e-9 and ratio[0] == pytest.approx(1.5, abs=0.1)
    assert np.all(growth < 0.2 * np.sqrt(far))  # no growth was generated
    _, per_axis, _, _ = domain.calibrate(*args, shared=False, in_domain="held_out")
    assert np.ptp(per_axis / floor) > 1e-3  # per axis, each its own
