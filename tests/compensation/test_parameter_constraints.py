"""Every compensator declares its parameters the scikit-learn way (``_parameter_constraints``)
and ``fit`` refuses a value they do not allow before any work, naming the parameter."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.utils._param_validation import InvalidParameterError
from sklearn.utils.estimator_checks import check_param_validation

from ftdrake.compensation.calibration.orientation_model import OrientationPayloadCompensator
from ftdrake.compensation.estimators.base import ParameterError
from ftdrake.compensation.estimators.registry import REGISTRY
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.estimators.tuning import PerOutputCompensator
from ftdrake.errors import ConfigError

# A valid [q, q̇, q̈] layout of 7 joints and a wrench: any refusal is the parameter's.
X = np.random.default_rng(0).uniform(-1, 1, (40, 21))
Y = np.random.default_rng(1).normal(size=(40, 6))


class BadType:
    """A value no constraint allows."""


def constrained(entry):
    return [name for name, rule in entry.cls._parameter_constraints.items()
            if rule != "no_validation"]


CASES = [(name, param) for name, entry in REGISTRY.items() for param in constrained(entry)]


@pytest.mark.parametrize("kind, param", CASES, ids=[f"{k}-{p}" for k, p in CASES])
def test_a_bad_value_is_refused_at_fit_naming_the_parameter(kind, param):
    entry = REGISTRY[kind]
    model = entry.build(**{param: BadType()})  # constructing stores it as given
    assert isinstance(model.get_params()[param], BadType)
    with pytest.raises(ParameterError, match=rf"The '{param}' parameter of "
                                             rf"{entry.cls.__name__} must be") as refused:
        model.fit(X, Y)
    assert isinstance(refused.value, InvalidParameterError)  # scikit-learn's, a ValueError
    assert isinstance(refused.value, ConfigError)  # and ftdrake's, for the command line
    assert not hasattr(model, "n_features_in_")  # refused before any fitting


@pytest.mark.parametrize("kind", list(REGISTRY))
def test_every_parameter_has_a_constraint_and_the_defaults_pass(kind):
    model = REGISTRY[kind].build()
    assert set(model._parameter_constraints) == set(model.get_params(deep=False))
    model._validate_params()


@pytest.mark.parametrize("model", [
    *(entry.build() for entry in REGISTRY.values()),
    PerOutputCompensator([SVRCompensator() for _ in range(6)]),
    OrientationPayloadCompensator(),
], ids=[*REGISTRY, "per_output", "orientation"])
def test_scikit_learns_parameter_validation_check(model):
    """scikit-learn's own check: a constraint for each parameter, and for each a value of no
    allowed type and a value outside each constraint refused by ``fit`` with its message."""
    check_param_validation(type(model).__name__, model)


@pytest.mark.parametrize("make, param, value, allowed", [
    (lambda **kw: REGISTRY["rf"].build(**kw), "n_estimators", 0, "in the range"),
    (lambda **kw: REGISTRY["rf"].build(**kw), "features", "q,qdd", "among"),
    (lambda **kw: REGISTRY["svr"].build(**kw), "C", -1.0, "in the range"),
    (lambda **kw: REGISTRY["gpr"].build(**kw), "subset", "nearest", "among"),
    (lambda **kw: REGISTRY["physics"].build(**kw), "mode", "quasi", "among"),
    (lambda **kw: REGISTRY["arm"].build(**kw), "drive_gains", "guess", "among"),
    (lambda **kw: REGISTRY["hybrid"].build(**kw), "features", "q", "among"),
])
def test_the_message_says_what_the_parameter_may_be(make, param, value, allowed):
    with pytest.raises(ParameterError, match=rf"'{param}' parameter .* {allowed}.* Got "
                                             rf"{value!r} instead"):
        make(**{param: value}).fit(X, Y)
