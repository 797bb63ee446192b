"""The hybrid's fused row (payload model + forest residual in one compiled call), against its
own predict / predict_std, against the two-call row it replaced, and in CompensatorSystem."""

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftdrake.compensation.compiled.hybrid import CompiledHybrid
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from tests.helpers import CABLE_WEIGHT as WEIGHT
from tests.helpers import PAYLOAD_CASES as CASES
from tests.helpers import PAYLOAD_PHI as PHI
from tests.helpers import compensator_run
from tests.helpers import payload_rows as rows


def fitted_hybrid(physics, n, temperature=False):
    X = rows(n, 300, seed=0)
    rng = np.random.default_rng(1)
    # The payload's reading, a smooth effect it does not model (for the forest) and noise.
    A = physics.regressor(X)
    phi = PHI if A.shape[-1] == 16 else np.concatenate([PHI, WEIGHT])
    Y = (A @ phi + 0.3 * np.sin(2 * X[:, :6])
         + rng.normal(0, 0.02, (len(X), 6)))
    if temperature:
        T = 25 + 5 * np.sin(np.linspace(0, 3, len(X)))
        X, Y = np.column_stack([X, T]), Y + 0.01 * (T - 25)[:, None]
    residual = RandomForestCompensator(features="q", n_estimators=8, per_output=False,
                                       min_samples_leaf=3, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation warnings are tested elsewhere
        return HybridCompensator(physics, residual).fit(X, Y)


def two_call_row(model):
    """The row the fused kernel replaced: the payload row (parameter std), the residual's
    row, combined in numpy with the residual's cross-validated error variance."""
    physics = model.physics_.row_predictor(include_noise=False)
    residual = model.residual_.row_predictor()

    def row(x):
        mean, std = physics(x)
        return mean + residual(x)[0], np.sqrt(std * std + model.residual_noise_var_)

    return row


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    make, n = CASES[request.param]
    model = fitted_hybrid(make(), n)
    if "rotated" in request.param:
        # A mounting error, as identify_mounting finds it: the fused row must rotate too.
        model.physics_.mounting_rotation_ = Rotation.from_euler("xyz", [2, -3, 1],
                                                                degrees=True).as_matrix()
    return model, n


def test_fused_row_equals_predict_predict_std_and_the_two_call_row(case):
    dut, n = case
    X = rows(n, 60, seed=2)
    assert isinstance(dut.compiled_predictor(), CompiledHybrid)
    mean, std = dut.predict(X), dut.predict_std(X)
    tol = 1e-12 * max(1.0, np.abs(mean).max())
    fused = dut.row_predictor()
    got = [fused(x) for x in X]
    np.testing.assert_allclose([m for m, _ in got], mean, rtol=0, atol=tol)
    np.testing.assert_allclose([s for _, s in got], std, rtol=0, atol=1e-12)
    reference = two_call_row(dut)
    expected = [reference(x) for x in X]
    np.testing.assert_allclose([m for m, _ in got], [m for m, _ in expected], rtol=0, atol=tol)
    np.testing.assert_allclose([s for _, s in got], [s for _, s in expected], rtol=0,
                               atol=1e-12)
    # The parts are there: the residual's variance and the parameters' both count.
    assert (std ** 2 > dut.residual_noise_var_ * (1 + 1e-9)).any(axis=0).all()
    batch_mean, batch_std = dut.compiled_predictor().predict_with_std(X)
    np.testing.assert_allclose(batch_mean, mean, rtol=0, atol=tol)
    np.testing.assert_allclose(batch_std, std, rtol=0, atol=1e-12)


def test_compiled_hybrid_refuses_bad_rows(case):
    dut, n = case
    compiled = dut.compiled_predictor()
    with pytest.raises(ValueError, match="columns"):
        compiled.predict_one_with_std(np.zeros(3 * n + 2))
    bad = np.zeros(3 * n)
    bad[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        compiled.predict_one_with_std(bad)


def test_with_a_temperature_column_the_row_runs_unfused_and_still_equals_predict():
    dut = fitted_hybrid(PhysicsPayloadCompensator(), 7, temperature=True)
    assert dut.compiled_predictor() is None
    X = np.column_stack([rows(7, 20, seed=3), np.linspace(20, 30, 20)])
    row = dut.row_predictor()
    np.testing.assert_allclose([row(x)[0] for x in X], dut.predict(X), rtol=0, atol=1e-9)


def test_compensator_system_runs_the_fused_hybrid_as_predict_does(case):
    """The fused update (input checks, q̈ estimate, hybrid row) against ``fast=False``
    (``predict`` / ``predict_std`` on the same rows), sample by sample."""
    model, n = case
    wrench = np.random.default_rng(5).normal(size=6) * 5
    names = ("wrench_internal", "wrench_compensated", "wrench_std")
    logs = {fast: compensator_run(model, n, wrench, names, fast=fast)[1]
            for fast in (True, False)}
    fused, reference = logs[True], logs[False]
    scale = max(1.0, np.abs(reference["wrench_internal"]).max())
    for name in ("wrench_internal", "wrench_compensated"):
        np.testing.assert_allclose(fused[name], reference[name], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(fused["wrench_std"], reference["wrench_std"], rtol=0,
                               atol=1e-12)
    assert np.ptp(fused["wrench_internal"][2:], axis=0).max() > 1e-3  # it moved
