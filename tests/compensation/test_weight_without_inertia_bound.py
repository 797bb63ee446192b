"""A weight carried without inertia cannot be negative: both identifications keep m_w ≥ 0 and
the summary's verdict is true (it printed ``mw -1.1006 kg`` and ``physically possible body:
yes``)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.compensation.identification.consistent import is_physically_consistent

TRUTH = np.r_[1.2, 1.2 * np.array([0.01, -0.02, 0.06]), 0.004, 0.0, 0.0, 0.005, 0.0, 0.003,
              0.5, -0.3, 1.0, 0.02, -0.01, 0.03, -0.25, 0.0, 0.0, -0.25 * 0.1]


def _data(rows=300, seed=0):
    """Random joint states of ftdrake's arm and the reading of a payload whose 'weight
    without inertia' is negative (an upward pull of 0.25 kg·g): unconstrained least squares
    follows it below zero."""
    rng = np.random.default_rng(seed)
    X = np.hstack([rng.uniform(-2, 2, (rows, 7)), rng.uniform(-1, 1, (rows, 7)),
                   rng.uniform(-3, 3, (rows, 7))])
    model = PhysicsPayloadCompensator(weight_without_inertia=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)  # fitted to noise: its kinematics
        model.fit(X, rng.standard_normal((rows, 6)))
    Y = model.regressor(X) @ TRUTH + 0.05 * rng.standard_normal((rows, 6))
    return X, Y, model.regressor(X)


@pytest.mark.parametrize("identification", ["least_squares", "consistent"])
def test_weight_without_inertia_never_goes_negative(identification):
    X, Y, A = _data()
    # Independent check that the data do pull it below zero: plain least squares.
    unconstrained = np.linalg.lstsq(A.reshape(-1, 20), Y.reshape(-1), rcond=None)[0]
    assert unconstrained[16] < -0.1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        model = PhysicsPayloadCompensator(weight_without_inertia=True,
                                          identification=identification).fit(X, Y)
    mw = model.parameters_[16]
    assert 0.0 <= mw < 1e-6
    assert model.physically_consistent_ == (is_physically_consistent(model.parameters_[:10])
                                            and mw >= 0)
    text = model.summary()
    assert "mw is on its bound 0" in text
    verdict = next(ln for ln in text.splitlines() if "physically possible body" in ln)
    assert ("yes" in verdict.split("(")[0]) == model.physically_consistent_
    assert "weight_without_inertia >= 0" in model.identified()["active_constraints"]
    # The bound costs fit: the residual is above the unconstrained one, not below.
    free_rms = np.sqrt(np.mean((Y - A @ unconstrained) ** 2, axis=0))
    assert np.sum(model.residual_rms_ ** 2) >= np.sum(free_rms ** 2) * (1 - 1e-9)
