"""The grasp's judged-window figures of the tracker experiment on generated runs: what the
tracker left from the settle window on, and what the best constant payload in hindsight
leaves (ftdrake.experiments.tracking.constant_payload_floor).

The runs are built from S's motion along brisk arm motion (Drake's Jacobians), the grasped
payload's wrench by Newton's law for a particle (independent of the regressor the floor
fits), the same noise in both runs, as the experiment's runs have.
"""

import numpy as np
import pandas as pd
import pytest

from ftdrake import ScenarioConfig
from ftdrake import conventions as col
from ftdrake.compensation.identification.payload_identification import payload_regressor
from ftdrake.experiments.tracking import (
    EventPlan,
    constant_payload_floor,
    markdown,
    run_events,
    settled_metrics,
)
from tests.helpers import SENSOR_SIGMA as SIGMA
from tests.helpers import brisk_arm_motion, noise, point_mass_wrench

GRASP_AT, JUDGED_FROM = 1.0, 3.0
MASS, P = 0.5, np.array([0.0, 0.02, 0.12])


@pytest.fixture(scope="module")
def arm_motion():
    return brisk_arm_motion()


def log(t, compensated, estimated=None):
    data = {col.TIME: t}
    for name, values in ((col.WRENCH_COMPENSATED, compensated),
                         (col.WRENCH_CONTACT, compensated if estimated is None else estimated)):
        data.update(dict(zip(col.wrench_columns(name), values.T, strict=True)))
    return pd.DataFrame(data)


def regressor(kin):
    return payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S)


def runs(t, kin, model_error):
    """(event run, reference run): the grasp's wrench from GRASP_AT on, on top of the same
    bias, noise and compensator error in both."""
    held = (t >= GRASP_AT)[:, None]
    common = np.array([0.3, -0.2, 0.5, 0.01, 0.0, -0.01]) + noise(len(t), 3) + model_error
    event = common + np.where(held, point_mass_wrench(MASS, P, kin), 0.0)
    return log(t, event), log(t, common)


def floor(t, kin, model_error, K=None):
    event, reference = runs(t, kin, model_error)
    return constant_payload_floor(event, reference, regressor(kin), K, SIGMA, GRASP_AT,
                                  JUDGED_FROM, 2.0)


def test_without_model_error_the_floor_is_the_payload_and_nothing_is_left(arm_motion):
    t, kin = arm_motion
    row = floor(t, kin, 0.0)
    assert row["payload"][0] == pytest.approx(MASS, rel=1e-3)
    np.testing.assert_allclose(np.asarray(row["payload"][1:]) / row["payload"][0], P, atol=1e-4)
    # What is left is the fitted payload's own noise (its estimate from noisy samples).
    assert row["max_error_sigmas"] < 0.2 and row["within_tolerance"] == 1.0


def test_a_model_error_the_payload_can_express_is_taken_up_and_left_where_it_is_not(
        arm_motion):
    """A compensator error shaped like a second particle's wrench (in both runs): the
    constant payload fitted on the event's run takes it up, so what is left after the
    reference is subtracted is that wrench itself, from the judged window on — the
    particle's Newton–Euler wrench, computed apart from the fit's regressor."""
    t, kin = arm_motion
    error = point_mass_wrench(0.004, np.array([0.05, -0.03, 0.02]), kin)
    row = floor(t, kin, error)
    judged = t >= JUDGED_FROM
    expected = np.abs(error[judged] - error[t > GRASP_AT].mean(axis=0)) / SIGMA
    # The reference's constant bias is its mean over the fitted samples; the event's bias
    # column takes the error's mean too, so only its pose-dependent part is left.
    assert row["max_error_sigmas"] == pytest.approx(expected.max(), rel=0.05)
    assert row["payload"][0] == pytest.approx(MASS + 0.004, rel=1e-3)
    assert row["max_error_sigmas"] > 2.0  # large enough to be seen beyond the noise


def test_the_payload_is_read_through_the_models_map(arm_motion):
    """A payload read by the sensor through K (cross-talk) is recovered when the floor is
    given K, and leaves K's error when it is not."""
    t, kin = arm_motion
    K = np.eye(6)
    K[1, 3], K[3, 1] = 0.3, 0.02
    held = (t >= GRASP_AT)[:, None]
    common = noise(len(t), 4)
    event = log(t, common + np.where(held, point_mass_wrench(MASS, P, kin) @ K.T, 0.0))
    reference = log(t, common)
    args = (regressor(kin),)
    right = constant_payload_floor(event, reference, *args, K, SIGMA, GRASP_AT, JUDGED_FROM, 2.0)
    wrong = constant_payload_floor(event, reference, *args, None, SIGMA, GRASP_AT, JUDGED_FROM,
                                   2.0)
    assert right["max_error_sigmas"] < 0.2
    assert right["payload"][0] == pytest.approx(MASS, rel=1e-3)
    assert wrong["max_error_sigmas"] > 2.0


def test_settled_metrics_judge_only_the_samples_from_the_judged_start(arm_motion):
    t, _ = arm_motion
    d = np.zeros((len(t), 6))
    d[(t > GRASP_AT) & (t < JUDGED_FROM), 3] = 10 * SIGMA[3]  # before the window: not judged
    later = np.flatnonzero(t >= JUDGED_FROM)[:30]
    d[later, 1] = 3 * SIGMA[1]
    event, reference = log(t, d), log(t, np.zeros_like(d))
    row = settled_metrics(event, reference, SIGMA, JUDGED_FROM, 2.0)
    assert row["max_error_sigmas"] == pytest.approx(3.0)
    assert row["within_tolerance"] == pytest.approx(1 - 30 / (t >= JUDGED_FROM).sum())


def test_the_events_table_shows_the_tracker_beside_the_best_constant_payload():
    judged = {"max_error_sigmas": 3.14, "within_tolerance": 0.8234}
    best = {"max_error_sigmas": 1.87, "within_tolerance": 1.0,
            "payload": [0.5, 0.0, 0.01, 0.06]}
    row = {"event": "grasp", "seed": 7, "settled": judged, "best_constant_payload": best,
           "tracked": {"recovered_after_s": None, "false_contact_s": 0.0},
           "untracked": {"recovered_after_s": None, "false_contact_s": 15.0}}
    text = markdown({"hybrid": [row]}, EventPlan(events=("grasp",)))
    line = next(line for line in text.splitlines() if "3.1 σ" in line)
    assert "| 3.1 σ, 82.3 % | 1.9 σ, 100.0 % | 0.5000 kg at (0.0 20.0 120.0) mm |" in line
    assert "slow push" not in text  # no push was run: no empty table


def test_an_unknown_event_is_refused_by_name():
    with pytest.raises(ValueError, match="grab"):
        run_events({}, ScenarioConfig(), EventPlan(events=("grasp", "grab")))


def test_with_no_sample_the_tracker_learns_from_there_are_no_figures(arm_motion):
    """Every sample out of the compensator's domain: nothing to fit, no figures (not a fit
    of nothing), and the table says so."""
    t, kin = arm_motion
    event, reference = runs(t, kin, 0.0)
    for log_ in (event, reference):
        log_[col.OUT_OF_DOMAIN] = 1.0
    row = constant_payload_floor(event, reference, regressor(kin), None, SIGMA, GRASP_AT,
                                 JUDGED_FROM, 2.0)
    assert row == {"max_error_sigmas": None, "within_tolerance": None, "payload": None}
    event[col.OUT_OF_DOMAIN] = np.where(t < 2.0, 1.0, 0.0)  # only the first second after it
    reference[col.OUT_OF_DOMAIN] = 0.0
    row = constant_payload_floor(event, reference, regressor(kin), None, SIGMA, GRASP_AT,
                                 JUDGED_FROM, 2.0)
    assert row["payload"][0] == pytest.approx(MASS, rel=1e-3)
