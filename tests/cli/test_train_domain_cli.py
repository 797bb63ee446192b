"""`ftdrake train --domain-holdout / --domain-calibration`: the hybrid's out-of-domain std
calibrated where models are trained from the command line."""

import numpy as np
import pytest

from ftdrake.compensation.files.persistence import load_model
from tests.helpers import failure, refused, train


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Three 1 s Fourier runs in one file (three trajectories), and a fourth alone."""
    from ftdrake import ScenarioConfig
    from ftdrake.data.dataset import save_dataset
    from ftdrake.sim.collection import collect

    folder = tmp_path_factory.mktemp("domain")
    frame = collect(ScenarioConfig(), 4, kind="fourier", duration=1.0, n_jobs=2,
                    progress=False)
    save_dataset(frame[frame["trajectory"] < 3], folder / "runs.parquet")
    save_dataset(frame[frame["trajectory"] == 3], folder / "other.parquet")
    return folder


def model_of(path):
    loaded = load_model(path)
    return loaded[0] if isinstance(loaded, tuple) else loaded


def test_holdout_calibrates_on_the_farthest_run_and_refits_on_all(ftdrake, logs, tmp_path):
    path = tmp_path / "h.ftd"
    manifest = train(ftdrake, logs / "runs.parquet", path, "--kind", "hybrid", "--robot",
                     "ftdrake", "--preset", "none", "--domain-holdout", "0.3",
                     "--max-rows", "1200")  # rows covering the runs, kept in their runs
    record = manifest["extra"]["domain_calibration"]
    assert len(record["held_out_groups"]) == 1 and record["held_out_groups"][0] in (0, 1, 2)
    assert record["refit"] and record["training_rows"] + record["held_out_rows"] == 1200
    model = model_of(path)
    assert model.domain_length_ == pytest.approx(record["length"] or np.inf)
    np.testing.assert_allclose(model.domain_growth_, record["growth"])
    # Calibrated on a run another seed of the same kind: the runs leave each other's data.
    assert record["median_distance_held_out"] > 0.5 and max(record["growth"]) > 0


def test_calibration_on_another_log_and_the_refusals(ftdrake, logs, tmp_path):
    path = tmp_path / "c.ftd"
    manifest = train(ftdrake, logs / "runs.parquet", path, "--kind", "hybrid", "--robot",
                     "ftdrake", "--preset", "none", "--domain-calibration",
                     logs / "other.parquet", "--max-rows", "1200", "--domain-shared-growth")
    record = manifest["extra"]["domain_calibration"]
    assert record["rows"] == 1000 and record["file"].endswith("other.parquet")
    model = model_of(path)
    np.testing.assert_allclose(model.domain_growth_, record["growth"])
    ratio = model.domain_growth_ ** 2 / model.domain_far_var_  # one growth for all axes
    assert record["shared_growth"] and np.ptp(ratio) <= 1e-9 * ratio.max()
    # The calibration makes the std cover the other run no worse than before, on every axis.
    assert np.all(np.array(record["coverage_95_after"])
                  >= np.array(record["coverage_95_before"]) - 0.02), record
    line = failure(ftdrake, "train", "--data", logs / "runs.parquet", "--kind", "physics",
                   "--robot", "ftdrake", "--domain-holdout", "0.2", "--out", tmp_path / "p.ftd")
    assert "--domain-holdout is for --kind hybrid" in line
    line = failure(ftdrake, "train", "--data", logs / "runs.parquet", "--kind", "hybrid",
                   "--robot", "ftdrake", "--domain-shared-growth", "--max-rows", "300",
                   "--out", tmp_path / "s.ftd")
    assert "--domain-shared-growth needs --domain-holdout or --domain-calibration" in line
    line = failure(ftdrake, "train", "--data", logs / "runs.parquet", "--kind", "hybrid",
                   "--robot", "ftdrake", "--domain-level", "held_out", "--max-rows", "300",
                   "--out", tmp_path / "l.ftd")
    assert "--domain-level needs --domain-holdout or --domain-calibration" in line


def test_the_demos_calibration_from_the_command_line(ftdrake, logs, tmp_path):
    """--domain-shared-growth --domain-level held_out: the level next to the data from the
    held-out runs too, never below the residual's training error (as the demo calibrates;
    the shared level's arithmetic: tests/compensation/test_domain_calibration.py)."""
    path = tmp_path / "d.ftd"
    manifest = train(ftdrake, logs / "runs.parquet", path, "--kind", "hybrid", "--robot",
                     "ftdrake", "--preset", "none", "--domain-holdout", "0.3",
                     "--domain-shared-growth", "--domain-level", "held_out",
                     "--max-rows", "1200")
    record = manifest["extra"]["domain_calibration"]
    assert record["in_domain"] == "held_out"
    model = model_of(path)
    assert np.all(model.residual_noise_var_ >= model.residual_training_var_ * (1 - 1e-9))
    assert model.domain_parameter_scale_ == pytest.approx(record["parameter_variance_scale"])
    assert record["parameter_variance_scale"] != 1.0  # fitted; "cross_fit" keeps c = 1



def test_a_share_out_of_range_is_refused_before_running(capsys, tmp_path):
    message = refused(capsys, "train", "--data", tmp_path, "--domain-holdout", "0.7",
                      "--out", tmp_path / "x.ftd")
    assert "--domain-holdout: must be a share of the rows in (0, 0.5)" in message
