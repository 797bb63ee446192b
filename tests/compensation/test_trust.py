"""The trust analysis of predictions (compensation/evaluation/trust.py), counted by hand."""

import numpy as np

from ftdrake.compensation.evaluation.trust import assess_trust, trust_references


class _Model:
    std_includes_noise = True
    residual_rms_ = np.array([0.2, 1.0])


def test_rows_are_flagged_per_target_and_cause_as_counted_by_hand():
    names = ["a", "b"]
    outside = np.array([True, False, False, False, False])
    std = np.array([[0.1, 1.0], [0.5, 1.0], [0.1, 3.0], [0.1, 1.0], [0.1, 1.0]])
    prediction = np.array([[0.0, 5.0], [1.0, 5.0], [11.5, 5.0], [-1.5, 5.0], [5.0, 5.0]])
    residual, target_range = trust_references(
        _Model(), names, std, {"a": [0.0, 10.0], "b": [0.0, 10.0], "c": [0.0, 1.0]})
    np.testing.assert_array_equal(residual, [0.2, 1.0])
    dut = assess_trust(names, prediction, std, outside, residual, target_range)

    # factor 2 × residual: a flags 0.5 (> 0.4, row 1); b flags 3.0 (> 2, row 2).
    # range [0, 10] widened by 1: a's 11.5 (row 2) and -1.5 (row 3) are outside.
    assert dut["by_cause"] == {
        "inputs_outside_range": {"a": 0.2, "b": 0.2},
        "std_above_factor_x_residual": {"a": 0.2, "b": 0.2},
        "prediction_outside_target_range": {"a": 0.4, "b": 0.0},
    }
    # With a calibrated std the inputs flag nothing on their own (row 0's inputs are
    # outside, but each target's std is within 2× its residual there): a: rows 1-3; b: row 2.
    assert dut["untrusted_fraction"] == {"a": 0.6, "b": 0.2}
    assert dut["flagging_causes"] == ["std_above_factor_x_residual",
                                      "prediction_outside_target_range"]
    assert "flag nothing on their own" in dut["explanation"]
    assert dut["residual_rms"] == {"a": 0.2, "b": 1.0}
    assert dut["warnings"] == [
        ("warning: inputs outside the training range on 20 % of rows; each target's "
         "predictive std decides whether its predictions there are trusted"),
        ("warning: predictive std > 2× the RMS error on its training rows (the model lacks "
         "data there) on "
         "a 20 %, b 20 % of rows"),
        "warning: predictions beyond the training range of the target (±10 %) on a 40 % of rows",
        ("warning: predictions on flagged rows cannot be trusted; see 'trust' in --json (share "
         "of rows flagged per target and cause)"),
    ]


def test_without_a_calibrated_std_or_target_ranges_only_the_inputs_count():
    names = ["a"]
    residual, target_range = trust_references(object(), names, None, {"b": [0, 1]})
    assert residual is None and target_range is None
    dut = assess_trust(names, np.zeros((4, 1)), None, np.array([False] * 4))
    assert list(dut["by_cause"]) == ["inputs_outside_range"]
    assert dut["untrusted_fraction"] == {"a": 0.0} and dut["warnings"] == []
    assert dut["uncertain_std_factor"] is None
    # Without a calibrated std, a row with an input outside flags every target.
    dut = assess_trust(["a", "b"], np.zeros((4, 2)), None, np.array([True, False, False, False]))
    assert dut["untrusted_fraction"] == {"a": 0.25, "b": 0.25}
    assert dut["flagging_causes"] == ["inputs_outside_range"]
