"""`--correction` names the entries of C its poses do not determine (and why), prints the others
with finite standard errors, and, where no entry of C is determined on its own, what is: the
reading per unit gravity (it printed all 36 entries as '± ∞')."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ftdrake.compensation.calibration.calibration import KNOWN_COM, KNOWN_MASS, calibrate_table
from ftdrake.compensation.estimators.physics import ExcitationWarning
from tests.helpers import LOADS, WRENCH, sensor_poses


@pytest.fixture(scope="module")
def one_load():
    table, _ = sensor_poses(1, 40, LOADS[0])
    return table.drop(columns=[KNOWN_MASS, *KNOWN_COM])


def _calibrate(table, correction):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return calibrate_table(table, correction=correction)


def test_block_correction_names_the_free_entries_and_bounds_the_others(one_load):
    corr = _calibrate(one_load, "block").correction
    free = corr.free_entries()
    # One load: its torques are ⊥ c, so no torque entry is determined; the force block is.
    assert free[3:, 3:].all() and not free[:3, :3].any()
    # Independently: moving the sensor matrix along the free direction leaves every pose's
    # reading unchanged but moves exactly the entries named free.
    n = corr.free_directions[0]
    M2 = corr.sensor_matrix + 0.01 * np.outer(np.r_[0, 0, 0, 1, 1, 1], n)
    g = one_load[["gx", "gy", "gz"]].to_numpy()
    m, h = corr.payload[0], corr.payload[1:]
    W_S = np.hstack([m * g, np.cross(h, g)])
    np.testing.assert_allclose(W_S @ M2.T, W_S @ corr.sensor_matrix.T, atol=1e-9)
    moved = np.abs(np.linalg.inv(M2) - corr.matrix) > 1e-9
    np.testing.assert_array_equal(moved[3:, 3:], free[3:, 3:])
    text = "\n".join(corr.summary())
    assert "± ∞" not in text and "± inf" not in text
    assert "not determined by these poses (9 of 18 entries)" in text
    assert "perpendicular to its centre of mass" in text and "known_mass" in text
    assert np.all(np.isfinite(corr.std_errors[:3, :3])) and text.count(" ± ") >= 9


def test_full_correction_of_one_load_prints_what_is_determined(one_load):
    corr = _calibrate(one_load, "full").correction
    assert corr.free_entries().all()
    text = "\n".join(corr.summary())
    assert "not determined by these poses (36 of 36 entries)" in text and "± ∞" not in text
    assert "what these poses determine: the reading per unit gravity" in text
    # K is the general linear model of this load: per axis, ordinary least squares of the
    # reading on [g, 1] (computed here independently), with its standard errors.
    g = one_load[["gx", "gy", "gz"]].to_numpy()
    D = np.column_stack([g, np.ones(len(g))])
    Y = one_load[WRENCH].to_numpy()
    coef, *_ = np.linalg.lstsq(D, Y, rcond=None)
    resid = Y - D @ coef
    sigma2 = np.sum(resid ** 2, axis=0) / (len(Y) - 4)
    se = np.sqrt(np.outer(sigma2, np.diag(np.linalg.inv(D.T @ D))[:3]))
    np.testing.assert_allclose(corr.gravity_matrix, coef[:3].T, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(corr.gravity_matrix_std_errors, se, rtol=0.2)


def test_a_chosen_correction_with_free_entries_says_what_the_choice_rests_on(one_load):
    """`auto` picks full on one load while no entry of it is determined: the output says the
    choice rests on what the poses determine (this payload's readings), and the warning no
    longer calls the correction's directions 'uncorrected (standard error ∞)' (issue 42
    item 8)."""
    with pytest.warns(ExcitationWarning) as caught:
        cal = calibrate_table(one_load, correction="auto")
    assert cal.choice["choice"] == "full" and cal.correction.free_entries().all()
    text = cal.summary()
    assert ("  correction chosen from the data: full (cross-validated (5 folds) error of full "
            "is the lowest)") in text
    assert ("    chosen for what these poses determine — the correction's effect on this "
            "payload's readings, which the cross-validation scored — not for its entries one "
            "by one: 36 of 36 are not determined (below, 'free'). It corrects readings of this "
            "payload; for other loads, calibrate with poses of other known loads") in text
    message = "\n".join(str(w.message) for w in caught)
    assert "left uncorrected" not in message and "standard error ∞" not in message
    assert "it still corrects this payload's readings, not necessarily other loads'" in message
    # What the line claims, checked: the correction's reading of this payload's wrench matches
    # the poses as well as the rigid fit cannot.
    assert np.all(cal.correction.residual_rms < 0.2 * cal.correction.rigid_residual_rms)
