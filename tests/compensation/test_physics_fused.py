"""The physics payload model's fused loop update (input checks, q̈ estimate, payload row and
compensated wrench in one compiled call), against the row-predictor path it replaced and
against predict / predict_std, in CompensatorSystem, faults included."""

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftdrake.compensation.compiled.loop import compensate_with_payload
from ftdrake.compensation.estimators.physics_rows import PayloadRowKernels
from ftdrake.runtime.compensator import CompensatorSystem
from tests.helpers import CABLE_WEIGHT as WEIGHT
from tests.helpers import PAYLOAD_CASES as CASES
from tests.helpers import PAYLOAD_PHI as PHI
from tests.helpers import compensator_run
from tests.helpers import payload_rows as rows

OUTPUTS = ("wrench_internal", "wrench_compensated", "wrench_std", "fault", "out_of_domain")


def fitted_physics(make, n, temperature=False):
    physics = make()
    X = rows(n, 300, seed=0)
    A = physics.regressor(X)
    phi = PHI if A.shape[-1] == 16 else np.concatenate([PHI, WEIGHT])
    Y = A @ phi + np.random.default_rng(1).normal(0, 0.02, (len(X), 6))
    if temperature:
        T = 25 + 5 * np.sin(np.linspace(0, 3, len(X)))
        X, Y = np.column_stack([X, T]), Y + 0.01 * (T - 25)[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # excitation warnings are tested elsewhere
        return physics.fit(X, Y)


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    make, n = CASES[request.param]
    model = fitted_physics(make, n)
    if "rotated" in request.param:
        # A mounting error, as identify_mounting finds it: the fused update must rotate too.
        model.mounting_rotation_ = Rotation.from_euler("xyz", [2, -3, 1],
                                                       degrees=True).as_matrix()
    return model, n


def test_the_compensator_runs_the_fused_update_and_it_equals_the_row_path(case, monkeypatch):
    """Bit for bit against the row predictor's path (what ran before), and to 1e-12 against
    predict / predict_std (``fast=False``)."""
    model, n = case
    update, _ = model.fused_loop_update()
    assert update is compensate_with_payload
    wrench = np.random.default_rng(5).normal(size=6) * 5
    dut, fused = compensator_run(model, n, wrench, OUTPUTS)
    assert dut._fused is not None and dut._fused[0] is compensate_with_payload
    monkeypatch.setattr(PayloadRowKernels, "fused_loop_update", lambda _self: None)
    row_dut, row_path = compensator_run(model, n, wrench, OUTPUTS)
    assert row_dut._fused is None  # the reference ran the row predictor
    _, reference = compensator_run(model, n, wrench, OUTPUTS, fast=False)
    scale = max(1.0, np.abs(reference["wrench_internal"]).max())
    for name in OUTPUTS:
        np.testing.assert_array_equal(fused[name], row_path[name], err_msg=name)
        np.testing.assert_allclose(fused[name], reference[name], rtol=0,
                                   atol=1e-12 * scale, err_msg=name)
    assert np.ptp(fused["wrench_internal"][2:], axis=0).max() > 1e-3  # it moved
    assert fused["fault"].max() == 0.0


def test_a_nan_reading_faults_the_fused_update_as_the_row_path(case, monkeypatch):
    model, n = case
    wrench = np.array([1.0, np.nan, 0.0, 0.0, 0.0, 0.0])
    _, fused = compensator_run(model, n, wrench, OUTPUTS)
    monkeypatch.setattr(PayloadRowKernels, "fused_loop_update", lambda _self: None)
    _, row_path = compensator_run(model, n, wrench, OUTPUTS)
    for name in OUTPUTS:
        np.testing.assert_array_equal(fused[name], row_path[name], err_msg=name)
    assert fused["fault"][1:].min() == 1.0


def test_a_temperature_model_has_no_fused_update_and_runs_its_row_predictor():
    model = fitted_physics(CASES["ftdrake arm"][0], 7, temperature=True)
    assert model.fused_loop_update() is None
    dut = CompensatorSystem(model, 1e-3)
    assert dut._fused is None and dut._predict is not None
