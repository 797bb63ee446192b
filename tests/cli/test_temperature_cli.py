"""`train/evaluate --temperature COL`: the sensor temperature as the models' last input, kept in
the manifest; `evaluate` names the column and the flag when a log lacks it, and reads a table
of static poses (no time column) as `calibrate` does."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest

from ftdrake.cli.main import main
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.compensation.files.persistence import load_model, read_manifest, save_model
from ftdrake.conventions import WRENCH_AXES
from ftdrake.data.training import ReadOptions, load_training_data
from ftdrake.errors import LogError
from ftdrake.testing import SIGMA, THETA, pose_tables, sinusoids

K = np.array([0.04, -0.03, 0.12, 0.003, -0.0025, 0.002])  # N/K, N·m/K
WRENCH = [f"meas_{a}" for a in WRENCH_AXES]


def motion_log(seed, n=1200):
    """A 20-s motion of all joints while the sensor warms from 22 to 30 °C."""
    rng = np.random.default_rng(seed)
    X = sinusoids(rng, range(7), n=n, duration=20.0)
    t = np.linspace(0, 20, n)
    T = 22 + 8 * (1 - np.exp(-t / 8))
    Y = (PhysicsPayloadCompensator().regressor(X) @ THETA + np.outer(T - 22, K)
         + rng.normal(size=(n, 6)) * SIGMA)
    frame = pd.DataFrame({"t": t, **{f"{p}_{j}": X[:, 7 * b + j] for b, p in
                                     enumerate(("q", "qd", "qdd")) for j in range(7)},
                          **dict(zip(WRENCH, Y.T, strict=True)), "temp_c": T})
    return frame, X, T, Y


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_train_and_evaluate_read_the_temperature_column(tmp_path, capsys):
    train, _, _, _ = motion_log(0)
    held, *_ = motion_log(1)
    train.to_csv(tmp_path / "train.csv", index=False)
    held.to_csv(tmp_path / "held.csv", index=False)
    held.drop(columns="temp_c").to_csv(tmp_path / "no_temp.csv", index=False)
    flags = ["--velocities", "qd_*", "--accelerations", "qdd_*"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        code, out, err = run(capsys, "train", "--data", tmp_path / "train.csv", "--kind",
                             "physics", "--robot", "ftdrake", "--preset", "none",
                             "--temperature", "temp_c", *flags, "--out", tmp_path / "m.ftd")
    assert code == 0, err
    assert "zero drift per K" in out  # the identified coefficients are printed
    manifest = read_manifest(tmp_path / "m.ftd")
    assert manifest["extra"]["data"]["options"]["temperature"] == "temp_c"
    assert manifest["extra"]["columns"]["temperature"] == "temp_c"
    assert "temperature" in manifest["input_range"]
    model = load_model(tmp_path / "m.ftd")
    assert model.temperature_in_
    np.testing.assert_allclose(model.temperature_coefficients_, K, rtol=0.05, atol=1e-3)
    # evaluate reads the column the manifest names: held-out error at the noise level.
    code, out, err = run(capsys, "evaluate", "--model", tmp_path / "m.ftd", "--data",
                         tmp_path / "held.csv", "--json", tmp_path / "e.json")
    assert code == 0, err
    mse = [m["mse"] for m in json.loads((tmp_path / "e.json").read_text())
           ["metrics"]["all"].values()]
    assert np.all(np.sqrt(mse) < 1.5 * SIGMA), np.sqrt(mse) / SIGMA  # measured 0.98–1.02 σ
    # A log without that column: one line naming the column and the flag.
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "m.ftd", "--data",
                       tmp_path / "no_temp.csv", "--quiet")
    assert code == 2
    assert "no temperature column 'temp_c'" in err and "--temperature COLUMN" in err
    assert len(err.strip().splitlines()) == 1
    # A bag has no temperature column: said, not a traceback.
    with pytest.raises(LogError, match="bag has no temperature column"):
        load_training_data("tests/data/ur3/ur3_2019-11-27-11-55-35.bag",
                           ReadOptions(temperature="temp_c"))


def test_evaluate_names_the_flag_for_a_temperature_model_without_read_options(tmp_path,
                                                                              capsys):
    # A model fitted in Python keeps no read options: evaluate cannot guess the column.
    _, X, T, Y = motion_log(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        model = PhysicsPayloadCompensator().fit(np.c_[X, T], Y)
    save_model(model, tmp_path / "m.ftd", target_names=WRENCH, target_units=["N"] * 3
               + ["N*m"] * 3, sensor_frame="S")
    held, *_ = motion_log(1)
    held.to_csv(tmp_path / "held.csv", index=False)
    flags = ["--velocities", "qd_*", "--accelerations", "qdd_*"]
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "m.ftd", "--data",
                       tmp_path / "held.csv", *flags)
    assert code == 2 and "trained with the sensor temperature" in err
    assert "--temperature COL" in err
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "m.ftd", "--data",
                       tmp_path / "held.csv", *flags, "--temperature", "temp_c")
    assert code == 0, err


def test_evaluate_reads_a_static_pose_table_as_calibrate_does(tmp_path, capsys):
    joints, _, _ = pose_tables(0, 40, temperature=True)
    held, _, _ = pose_tables(1, 100, temperature=True)
    joints.to_csv(tmp_path / "poses.csv", index=False)
    held.to_csv(tmp_path / "held.csv", index=False)  # no time column
    code, _, err = run(capsys, "calibrate", "--data", tmp_path / "poses.csv", "--robot",
                       "ftdrake", "--out", tmp_path / "cal")
    assert code == 0, err
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "cal" / "model.ftd",
                       "--data", tmp_path / "held.csv", "--json", tmp_path / "e.json")
    assert code == 0, err
    result = json.loads((tmp_path / "e.json").read_text())
    assert result["rows"]["used"] == 100 and "static poses" in result["source"]
    rms = np.sqrt([m["mse"] for m in result["metrics"]["all"].values()])
    # Measured: 0.96–1.14 σ per axis (the held-out noise itself is 1 σ).
    assert np.all(rms < 1.5 * SIGMA), rms / SIGMA
    # The calibration had a temperature: the static table without it is refused by name.
    held.drop(columns="temperature").to_csv(tmp_path / "no_temp.csv", index=False)
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "cal" / "model.ftd",
                       "--data", tmp_path / "no_temp.csv")
    assert code == 2 and "no temperature column 'temperature'" in err, err
    # A time window means nothing on static poses.
    code, _, err = run(capsys, "evaluate", "--model", tmp_path / "cal" / "model.ftd",
                       "--data", tmp_path / "held.csv", "--t-start", "1")
    assert code == 2 and "no time axis" in err
