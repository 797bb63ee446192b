"""`replay` on a log with time gaps (issue 42 item 11): the gaps are found, reported, and the
chain restarts after each, so nothing integrates or differentiates across one."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from ftdrake import replay, save_model
from ftdrake.cli.main import main
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.conventions import WRENCH_AXES, WRENCH_UNITS, wrench_columns
from ftdrake.offline.replay import find_gaps

TRUTH = np.r_[1.2, 1.2 * np.array([0.01, -0.02, 0.06]), 0.004, 0.0, 0.0, 0.005, 0.0, 0.003,
              0.5, -0.3, 1.0, 0.02, -0.01, 0.03]
RATE_HZ = 200.0


def _motion(t, phase):
    """q, q̇, q̈ (rad, rad/s, rad/s²) of a smooth motion of 7 joints: sines."""
    w = 1.0 + 0.3 * np.arange(7)
    arg = np.outer(t, w) + phase + np.arange(7)
    return 0.8 * np.sin(arg), 0.8 * w * np.cos(arg), -0.8 * w**2 * np.sin(arg)


@pytest.fixture(scope="module")
def model_and_segments():
    """A dynamic physics model (q, q̇, q̈) fitted on the truth, and two 2-s stretches of
    motion 15 s apart whose joint states do not join (another phase after the gap)."""
    rng = np.random.default_rng(0)
    X = np.hstack([rng.uniform(-1.5, 1.5, (600, 7)), rng.uniform(-2, 2, (600, 7)),
                   rng.uniform(-4, 4, (600, 7))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        kin = PhysicsPayloadCompensator().fit(X, rng.standard_normal((600, 6)))
        model = PhysicsPayloadCompensator().fit(X, kin.regressor(X) @ TRUTH)
    segments = []
    for t0, phase in ((0.0, 0.0), (17.0, 1.3)):
        t = t0 + np.arange(int(2 * RATE_HZ)) / RATE_HZ
        q, qd, qdd = _motion(t - t0, phase)
        wrench = kin.regressor(np.hstack([q, qd, qdd])) @ TRUTH
        segments.append(pd.DataFrame({"t": t, **{f"q_{i}": q[:, i] for i in range(7)},
                                      **{f"qd_{i}": qd[:, i] for i in range(7)},
                                      **dict(zip(wrench_columns("meas"), wrench.T,
                                                 strict=True))}))
    return model, segments


def test_a_gap_restarts_the_chain_as_if_the_stretches_were_replayed_apart(model_and_segments):
    model, (a, b) = model_and_segments
    log = pd.concat([a, b], ignore_index=True)
    whole = replay(model, log)
    apart = pd.concat([replay(model, a), replay(model, b)], ignore_index=True)
    np.testing.assert_allclose(whole.to_numpy(), apart.to_numpy(), rtol=0, atol=1e-12)
    gaps = whole.attrs["gaps"]
    assert gaps["count"] == 1 and gaps["gaps"][0]["row"] == len(a)
    assert gaps["gaps"][0]["length_s"] == pytest.approx(15.0 + 1 / RATE_HZ)
    assert gaps["median_step_s"] == pytest.approx(1 / RATE_HZ)
    # Read as one 5 ms step (the gap not seen: the old behaviour), the gap made a q̈ spike and
    # a spurious wrench many times the restart's (the loop's q̈ estimate starting afresh).
    after = slice(len(a), len(a) + 20)
    restarted = np.abs(whole[wrench_columns("wrench_compensated")].to_numpy()[after]).max()
    joined = replay(model, log, gap_factor=1e9)
    spurious = np.abs(joined[wrench_columns("wrench_compensated")].to_numpy()[after]).max()
    assert spurious > 10 * restarted


def test_the_command_reports_the_gaps(model_and_segments, tmp_path, capsys):
    model, (a, b) = model_and_segments
    save_model(model, tmp_path / "m.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    pd.concat([a, b], ignore_index=True).to_csv(tmp_path / "gappy.csv", index=False)
    assert main(["replay", "--model", str(tmp_path / "m.ftd"), "--log",
                 str(tmp_path / "gappy.csv"), "--out", str(tmp_path / "out.csv")]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out.strip().splitlines()[-1])
    assert report["gaps"]["count"] == 1
    assert report["gaps"]["gaps"][0]["t_before"] == pytest.approx(a["t"].iloc[-1])
    assert report["gaps"]["gaps"][0]["t_after"] == pytest.approx(17.0)
    assert ("warning: replay: 1 gap(s) in the log (a step longer than 3 × the median step 5 ms):"
            " 15 s after t = 1.995 s. The chain restarted after each (bias tracker, "
            "payload-change monitor, q̇/q̈ estimates, delay line, detector): each stretch "
            "replays as a log of its own (--gap-factor X sets the rule)") in err


def test_find_gaps_counts_steps_beyond_the_factor():
    t = np.r_[0.0, 1, 2, 5, 6, 7, 20, 21]  # steps 3 (3 × the median, not more) and 13
    found = find_gaps(t)
    assert found["count"] == 1 and found["gaps"][0]["row"] == 6
    assert found["gaps"][0]["length_s"] == 13.0 and found["gaps"][0]["t_before"] == 7.0
    assert find_gaps(t, 2.5)["count"] == 2
