"""What the identification summaries say about what the data determine: parameters the data
cannot determine printed as such (not ± 0.000), implausible drive gains named with the flag
to drop, one true physical-consistency verdict."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ftdrake.compensation.estimators.arm import ArmDynamicsCompensator, DriveGainWarning
from ftdrake.compensation.identification.consistent import (
    is_physically_consistent,
    physical_violations,
)
from ftdrake.physics.arm_dynamics import ArmDynamics, ArmModel
from tests.helpers import FRICTION, arm_torques
from tests.helpers import UR3_URDF as UR3


@pytest.fixture(scope="module")
def ur3():
    return ArmDynamics(ArmModel(UR3).build_plant())


@pytest.fixture(scope="module")
def torques(ur3):
    """Joint torques (gains 1) of the UR3 at random states, 0.05 N·m noise."""
    return arm_torques(ur3, np.random.default_rng(3), 300, ur3.model_parameters(), FRICTION,
                      np.ones(6), 0.05)


def _identifiable_by_rank(ur3, X):
    """Parameter i is determined by the data alone iff its unit vector lies in the row space
    of the regressor (rigid body, friction, offsets): adding it as a row keeps the rank."""
    n = 6
    q, v, vd = X[:, :n], X[:, n:2 * n], X[:, 2 * n:]
    eye = np.eye(n)
    A = np.concatenate([ur3.regressor(q, v, vd), v[:, :, None] * eye,
                        np.tanh(v / 0.02)[:, :, None] * eye,
                        np.broadcast_to(eye, (len(X), n, n))], axis=2).reshape(-1, 78)
    norms = np.linalg.norm(A, axis=0)
    # A column at round-off level (an axis the kinematics never turn about) is no data.
    A = np.where(norms > 1e-9 * norms.max(), A / np.maximum(norms, 1e-300), 0.0)
    s = np.linalg.svd(A, compute_uv=False)
    tol = 1e-7 * s[0]
    rank = int(np.sum(s > tol))
    out = []
    for i in range(A.shape[1]):
        e = np.zeros(A.shape[1])
        e[i] = 1.0
        s_i = np.linalg.svd(np.vstack([A, e]), compute_uv=False)
        out.append(int(np.sum(s_i > tol)) == rank)
    return np.array(out)


def test_parameters_the_data_cannot_determine_are_printed_as_such(ur3, torques):
    X, Y = torques
    model = ArmDynamicsCompensator(robot=UR3).fit(X, Y)
    expected = _identifiable_by_rank(ur3, X)
    assert 0 < expected.sum() < len(expected)  # some of each: the check can fail both ways
    np.testing.assert_array_equal(model.identifiable_, expected)
    text = model.summary()
    names = model.parameter_names_
    for k, body in enumerate(model.dynamics().bodies):
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"{body.name()}:"))
        if expected[10 * k]:
            assert "± " in line and "not identifiable" not in line, line
        else:
            assert "not identifiable from this data" in line and "±" not in line, line
            assert model.identified()[names[10 * k]]["std_error"] == np.inf
    assert "± 0.000" not in text
    assert f"{int((~expected).sum())} of 78 parameters are not identifiable" in text


def test_implausible_drive_gains_warn_and_name_the_flag(ur3, torques):
    X, _ = torques
    X = X.copy()
    X[:, 12:] *= 0.01  # a slow log: the wrist's rigid-body torque is tiny
    q, v, vd = X[:, :6], X[:, 6:12], X[:, 12:]
    tau = (ur3.regressor(q, v, vd) @ ur3.model_parameters() + FRICTION[0] * v
           + FRICTION[1] * np.tanh(v / 0.02))
    Y = tau + 0.05 * np.random.default_rng(0).standard_normal(tau.shape)  # joint torques
    with pytest.warns(DriveGainWarning) as caught:
        model = ArmDynamicsCompensator(robot=UR3, drive_gains="identify").fit(X, Y)
    far = np.abs(np.log(np.abs(model.gains_))) > np.log(1.5)
    assert far.any()
    message = str(caught[0].message)
    assert "drive_gains identify" in message and "joint torque" in message
    assert "--" not in message  # Python names the parameter, not a command-line flag
    for j in np.flatnonzero(far):
        assert model.dynamics().joint_names[j] in message
    assert "Drop drive_gains identify" in model.summary()
    # Unit gains really fit as well (the warning's claim), by an independent fixed fit.
    fixed = ArmDynamicsCompensator(robot=UR3).fit(X, Y)
    assert np.all(fixed.residual_rms_[far] <= 1.05 * model.residual_rms_[far])


def test_gains_of_a_current_log_do_not_warn(ur3):
    gains = np.array([-0.5, -1.4, -1.35, -1.7, -3.0, -11.0])  # currents: far from 1, real
    X, Y = arm_torques(ur3, np.random.default_rng(4), 300, ur3.model_parameters(), FRICTION,
                      gains, 0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DriveGainWarning)
        model = ArmDynamicsCompensator(robot=UR3, drive_gains="identify").fit(X, Y)
    np.testing.assert_allclose(model.gains_, gains, rtol=0.1)


@pytest.mark.parametrize("identification", ["consistent", "least_squares"])
def test_one_true_physical_consistency_verdict(ur3, torques, identification):
    X, Y = torques
    truth = ur3.model_parameters().copy()
    truth[50:60] *= -0.5  # the wrist's last body as no body can be: least squares follows
    q, v, vd = X[:, :6], X[:, 6:12], X[:, 12:]
    Y = Y + ur3.regressor(q, v, vd) @ (truth - ur3.model_parameters())
    model = ArmDynamicsCompensator(robot=UR3, identification=identification,
                                   prior=None).fit(X, Y)
    text = model.summary()
    bodies = model.dynamics().bodies
    problems = [f"{b.name()}: {p}" for k, b in enumerate(bodies)
                for p in physical_violations(model.parameters_[10 * k:10 * k + 10], tol=1e-7)]
    consistent = all(is_physically_consistent(model.parameters_[10 * k:10 * k + 10], tol=1e-7)
                     for k in range(len(bodies)))
    assert "NOT physically consistent" not in text
    verdicts = [ln for ln in text.splitlines() if "physically possible" in ln]
    assert len(verdicts) == 1
    if identification == "consistent":
        assert consistent and verdicts[0].strip() == "every body physically possible: yes"
    else:
        assert not consistent and "NO" in verdicts[0]
        for p in problems:
            assert text.count(p) == 1


def test_the_solvers_rounding_is_projected_onto_physical_bodies(ur3):
    """A consistent fit a hair outside J ⪰ 0 (the solver's last rounding, which made the
    summary say 'consistent, NOT physically consistent') is moved onto it, by about that
    much."""
    from ftdrake.compensation.estimators.arm import _onto_bodies
    from ftdrake.compensation.identification.consistent import pseudo_inertia

    prior = ur3.model_parameters()
    theta = prior.copy()
    # Body 5 a flat plate (one principal second moment 0), then 1e-6 past it.
    J = pseudo_inertia(theta[50:60])
    lam, V = np.linalg.eigh(J)
    J_out = (V * np.r_[-1e-6, lam[1:]]) @ V.T
    theta[50:60] = [J_out[3, 3], *J_out[:3, 3], *np.trace(J_out[:3, :3]) * np.eye(3)[
        [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]] - J_out[:3, :3][[0, 0, 0, 1, 1, 2],
                                                            [0, 1, 2, 1, 2, 2]]]
    assert not is_physically_consistent(theta[50:60], tol=1e-7)
    projected = _onto_bodies(theta, prior, 6)
    assert all(is_physically_consistent(projected[10 * k:10 * k + 10], tol=1e-7)
               for k in range(6))
    # Clipped in the program's scaled metric (lengths of 0.1 m): a change of the order of
    # the 1e-6 injected (measured 2e-5 on one inertia entry), nothing like a refit.
    assert np.abs(projected - theta).max() < 1e-4
    assert np.abs(projected - theta)[:50].max() == 0.0  # the other bodies are untouched
