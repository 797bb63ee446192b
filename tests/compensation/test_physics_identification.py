"""PhysicsPayloadCompensator's identification options on the arm: physically consistent fit,
prior, and warnings that name what the data cannot determine."""

import warnings

import numpy as np
import pytest

from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.compensation.estimators.registry import entry
from ftdrake.compensation.identification.consistent import PayloadPrior, is_physically_consistent
from ftdrake.errors import ConfigError
from ftdrake.testing import MASS, SIGMA, THETA, TRUE_PAYLOAD, readings, sinusoids


def fit(X, Y, **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return PhysicsPayloadCompensator(**params).fit(X, Y)


def held_out_error(model, seed):
    """Worst axis's RMS error, in noise σ, on a trajectory of all 7 joints (noise-free truth)."""
    X = sinusoids(np.random.default_rng(seed), range(7))
    truth = PhysicsPayloadCompensator().regressor(X) @ THETA
    return float(np.max(np.sqrt(np.mean(((model.predict(X) - truth) / SIGMA) ** 2, axis=0))))


@pytest.mark.parametrize("seed", [0, 3])
def test_two_joint_motion_least_squares_is_no_body_the_consistent_fit_is_and_predicts_better(seed):
    rng = np.random.default_rng(seed)
    X = sinusoids(rng, joints=(3, 5))  # elbow and wrist pitch only
    Y = readings(X, rng)
    ls = fit(X, Y, identification="least_squares")
    dut = fit(X, Y, identification="consistent")
    assert not ls.physically_consistent_
    assert not is_physically_consistent(ls.parameters_[:10])
    assert dut.physically_consistent_ and is_physically_consistent(dut.parameters_[:10])
    e_ls, e_dut = held_out_error(ls, 100 + seed), held_out_error(dut, 100 + seed)
    assert e_dut < 0.5 * e_ls, (e_ls, e_dut)  # measured: 14.5σ vs 3.7σ (seed 0)
    # The mass, which gravity excites, is right either way.
    assert dut.parameters_[0] == pytest.approx(MASS, rel=0.01)
    table = dut.identified()
    assert table["least_squares"]["physically_consistent"] is False
    assert {"Ixx", "Izz"} <= set(table["not_determined"])


def test_the_warning_names_the_undetermined_parameters_and_the_prior_decides_them():
    rng = np.random.default_rng(1)
    X = sinusoids(rng, joints=(3, 5))
    Y = readings(X, rng)
    with pytest.warns(ExcitationWarning, match=r"not determined by the data.*Ixx.*Izz"):
        PhysicsPayloadCompensator(identification="consistent").fit(X, Y)
    with pytest.warns(ExcitationWarning, match=r"the prior decided .*Ixx \d+%"):
        dut = PhysicsPayloadCompensator(identification="consistent", prior=TRUE_PAYLOAD).fit(X, Y)
    table = dut.identified()
    assert table["Ixx"]["prior_share"] > 0.5  # unexcited: the prior's value
    assert table["m"]["prior_share"] < 0.05  # excited: the data's
    assert held_out_error(dut, 101) < 1.0


def test_static_poses_with_the_dynamic_model_name_the_inertia():
    """The user's report: condition number 3e17 and no parameter named."""
    rng = np.random.default_rng(2)
    X = sinusoids(rng, joints=range(7), n=40)
    X[:, 7:] = 0.0  # static poses: q̇ = q̈ = 0
    with pytest.warns(ExcitationWarning) as record:
        dut = PhysicsPayloadCompensator().fit(X, readings(X, rng))
    message = str(record[0].message)
    for name in ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"):
        assert name in message
    assert "'none'" not in message and ": none" not in message.split(";")[1]
    assert np.all(np.isinf(dut.standard_errors_[4:10]))  # not the pseudo-inverse's 0
    assert dut.parameters_[0] == pytest.approx(MASS, rel=0.01)


def test_prior_with_negative_mass_is_refused_by_name():
    with pytest.raises(ConfigError, match=r"prior\.mass: -1\.0 kg is not a positive mass"):
        PayloadPrior(mass=-1.0)
    X = sinusoids(np.random.default_rng(0), (3, 5), n=50)
    with pytest.raises(ConfigError, match=r"prior\.mass"):
        PhysicsPayloadCompensator(identification="consistent",
                                  prior={"mass": -0.5, "com": [0, 0, 0.1]}).fit(X, np.ones((50, 6)))
    with pytest.raises(ConfigError, match="triangle inequality"):
        PayloadPrior(1.0, inertia=(0.01, 0, 0, 0.001, 0, 0.001))


def test_hybrid_and_registry_pass_the_identification_on():
    rng = np.random.default_rng(0)
    X = sinusoids(rng, joints=(3, 5), n=600)
    Y = readings(X, rng)
    assert entry("physics").build().identification == "consistent"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        dut = entry("hybrid").build().fit(X, Y)
    assert isinstance(dut, HybridCompensator)
    assert dut.physics_.identification == "consistent" and dut.physics_.physically_consistent_
    summary = dut.summary()
    assert "physically possible bodies" in summary and "std error" in summary and "Izz" in summary
