"""Repeatability of the payload identification across noise seeds (the cheap version of
benchmarks/identification_repeatability.py: the model's own regressor, 3 seeds)."""

import warnings

import numpy as np

from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.testing import (
    COM,
    COM_SPREAD_GOAL_MM,
    MASS,
    MASS_SPREAD_GOAL,
    SIGMA,
    THETA,
    identification_spread,
    sinusoids,
)


def test_three_noise_seeds_give_the_same_mass_and_centre_of_mass():
    X = sinusoids(np.random.default_rng(0), range(7), n=1500)  # one trajectory for all runs
    A = PhysicsPayloadCompensator().regressor(X)
    masses, coms = [], []
    for seed in (1, 2, 3):
        noise = np.random.default_rng(seed).normal(size=(len(X), 6)) * SIGMA
        drift = np.random.default_rng(seed).normal(size=6) * 3 * SIGMA  # a bias per run
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            dut = PhysicsPayloadCompensator(identification="consistent").fit(
                X, A @ THETA + noise + drift)
        masses.append(dut.parameters_[0])
        coms.append(dut.parameters_[1:4] / dut.parameters_[0])
    result = identification_spread(masses, coms)
    assert result["mass_range_rel"] < MASS_SPREAD_GOAL, result
    assert max(result["com_range_mm"]) < COM_SPREAD_GOAL_MM, result
    assert abs(result["mass_mean_kg"] - MASS) < 0.01 * MASS
    np.testing.assert_allclose(np.mean(coms, axis=0), COM, atol=2e-3)
