"""The two-part model in one file, applied to a new path, and its correction exported as CSV
giving the in-memory correction's reference offsets."""

import dataclasses as dc

import numpy as np
import pandas as pd
import pytest
from pydrake.trajectories import PiecewisePolynomial

from ftdrake.config import ScenarioConfig
from ftdrake.config.contour import HoleConfig
from ftdrake.errors import LogError, ModelFileError
from ftdrake.experiments.contour import ContourPlan, HoleRunner, Learner, contour_scenario
from ftdrake.experiments.reference_correction import corrected_reference, desired_states
from ftdrake.experiments.two_part_model import (
    TwoPartModel,
    export_reference_csv,
    offset_from_csv,
    read_joint_path,
)
from ftdrake.systems.learned_feedforward import fit_feedforward_gp


@pytest.fixture(scope="module")
def learned():
    """A small hole's task and a two-part learner whose GPs are fitted on its desired states
    (a gravity- and inertia-like twist for part two, a torque for part one)."""
    runner = HoleRunner(contour_scenario(ScenarioConfig()))
    task = runner.task(HoleConfig(diameter_m=0.01, speed_m_s=0.03, rest_s=0.1))
    t = np.arange(0.0, task.path.duration, 2e-3)
    X = desired_states(task.trajectory, t)
    q, _, qdd = np.split(X, 3, axis=1)
    plan = dc.replace(ContourPlan(), max_points=60, optimize_points=100)
    learner = Learner("timed", runner, task, plan)
    learner.reference_model = fit_feedforward_gp(X, 1e-4 * np.cos(q) + 2e-5 * qdd,
                                                 max_points=60, optimize_points=100)
    learner.torque_model = fit_feedforward_gp(X, 2 * np.sin(q) + 0.2 * qdd, max_points=60,
                                              optimize_points=100)
    return runner, task, learner


def test_saved_model_loads_and_gives_the_same_corrections(learned, tmp_path):
    runner, _task, learner = learned
    model = TwoPartModel.from_learner(learner, info={"note": "test"})
    loaded = TwoPartModel.load(model.save(tmp_path / "two_part.ftd"))
    assert loaded.info == {"method": "timed", "note": "test"}
    other = runner.task(HoleConfig(diameter_m=0.012, offset_m=[0.002, 0.0, 0.0], rest_s=0.1))
    t = np.linspace(0.0, other.path.duration, 200)
    np.testing.assert_array_equal(loaded.reference(other.trajectory).vector_values(t),
                                  model.reference(other.trajectory).vector_values(t))
    x = desired_states(other.trajectory, t[50:51])[0]
    np.testing.assert_array_equal(loaded.feedforward().evaluate_one(x),
                                  model.feedforward().evaluate_one(x))
    # The model applied to the new hole is the experiment's own correction for it.
    np.testing.assert_allclose(loaded.reference(other.trajectory).vector_values(t),
                               learner.reference(other).vector_values(t), rtol=0, atol=1e-15)


def test_exported_csv_gives_the_in_memory_reference_offsets(learned, tmp_path):
    _, task, learner = learned
    model = TwoPartModel.from_learner(learner)
    csv = tmp_path / "correction.csv"
    table = export_reference_csv(model, task.trajectory, 1000.0, csv)
    t = table["time"].to_numpy()
    np.testing.assert_allclose(np.diff(t), 1e-3, atol=1e-12)
    in_memory = learner.reference(task)
    expected = (in_memory.vector_values(t) - task.trajectory.vector_values(t)).T
    assert np.abs(expected).max() > 1e-5  # rad: a correction worth exporting
    written = pd.read_csv(csv)
    n = model.n
    np.testing.assert_allclose(written[[f"offset_{j}" for j in range(n)]].to_numpy(), expected,
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(written[[f"q_ref_{j}" for j in range(n)]].to_numpy(),
                               in_memory.vector_values(t).T, rtol=0, atol=1e-15)
    # The CSV replayed as a controller would (its offsets added to the path, splined): the
    # reference the in-memory correction runs, to 1e-9 rad.
    replayed = corrected_reference(task.trajectory, offset_from_csv(csv, n))
    np.testing.assert_allclose(replayed.vector_values(t), in_memory.vector_values(t),
                               rtol=0, atol=1e-9)


def test_exported_std_is_the_confidence_times_the_gps_std(learned, tmp_path):
    """Along a path that drifts out of the data (0.4 rad on every joint by its end) the
    confidence falls from 1 to 0; the std column is ``confidence · σ`` throughout."""
    _, task, learner = learned
    model = TwoPartModel.from_learner(learner)
    knots = np.arange(0.0, task.path.duration, 0.01)
    drift = np.linspace(0.0, 0.4, len(knots))
    zero = np.zeros((7, 1))
    away = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        knots, task.trajectory.vector_values(knots) + drift, zero, zero)
    written = export_reference_csv(model, away, 500.0, tmp_path / "away.csv")
    t = written["time"].to_numpy()
    _, std, confidence = model.correction.evaluate(desired_states(away, t))
    assert confidence.max() == 1.0 and confidence.min() == 0.0
    np.testing.assert_allclose(written[[f"offset_std_{j}" for j in range(7)]].to_numpy(),
                               confidence * std, rtol=1e-12)
    np.testing.assert_allclose(written[[f"confidence_{j}" for j in range(7)]].to_numpy(),
                               confidence, rtol=1e-12)


def test_bad_model_files_are_named(learned, tmp_path):
    _, _, learner = learned
    path = TwoPartModel.from_learner(learner).save(tmp_path / "m.ftd")
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    broken = tmp_path / "broken.ftd"
    broken.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match=r"broken\.ftd: checksum mismatch"):
        TwoPartModel.load(broken)
    other = tmp_path / "other.ftd"
    other.write_bytes(b"FTDRAKE-MODEL\n{}\n")
    with pytest.raises(ModelFileError, match="not a two-part model file"):
        TwoPartModel.load(other)
    with pytest.raises(ModelFileError, match="no such two-part model file"):
        TwoPartModel.load(tmp_path / "absent.ftd")
    learner_without = Learner("torque", learner.runner, learner.task, learner.plan)
    with pytest.raises(ModelFileError, match="learned no reference correction"):
        TwoPartModel.from_learner(learner_without)


def test_joint_path_csv(learned, tmp_path):
    _, task, _ = learned
    t = np.arange(0.0, task.path.duration, 0.01)
    q = task.trajectory.vector_values(t).T
    good = tmp_path / "path.csv"
    pd.DataFrame({"time": t, **{f"q_{j}": q[:, j] for j in range(7)}}).to_csv(good, index=False)
    path = read_joint_path(good, 7)
    np.testing.assert_allclose(path.vector_values(t).T, q, atol=1e-12)
    with pytest.raises(LogError, match=r"lacks column\(s\) \['q_6'\]"):
        bad = tmp_path / "bad.csv"
        pd.DataFrame({"time": t, **{f"q_{j}": q[:, j] for j in range(6)}}).to_csv(bad)
        read_joint_path(bad, 7)
    with pytest.raises(LogError, match=r"time must increase strictly \(row 3\)"):
        back = tmp_path / "back.csv"
        pd.DataFrame({"time": [0, 1, 0.5, 2], **{f"q_{j}": 0.0 for j in range(7)}}).to_csv(back)
        read_joint_path(back, 7)


def test_per_step_calls_equal_the_gps_mean_and_std_with_the_rule(learned, tmp_path):
    """What a loop runs each step (both parts' compiled one-row calls, from the loaded file)
    against the GPs' own batch predictions and the confidence rule, to 1e-9, on rows on and
    off the data (the confidence between 0 and 1)."""
    _, task, learner = learned
    model = TwoPartModel.load(TwoPartModel.from_learner(learner).save(tmp_path / "m.ftd"))
    t = np.linspace(0.0, task.path.duration, 60)
    X = desired_states(task.trajectory, t)
    rows = np.vstack([X, X + np.linspace(0.0, 0.5, len(X))[:, None]])
    for gp, dut in ((model.feedforward_model, model.feedforward()),
                    (model.reference_model, model.correction)):
        mean, std = gp.predict(rows), gp.predict_std(rows)
        confidence = np.clip((0.9 - std / dut.prior_std) / (0.9 - 0.5), 0.0, 1.0)
        assert 0 < confidence.mean() < 1
        got = np.array([dut.evaluate_one(x).copy() for x in rows])
        np.testing.assert_allclose(got, np.hstack([confidence * mean, std, confidence]),
                                   rtol=0, atol=1e-9)
