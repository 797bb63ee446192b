"""Datasets: collect → save → load keeps rows, columns, units and the scenario."""

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from ftdrake import ConfigError, ScenarioConfig
from ftdrake.data.dataset import load_dataset, save_dataset
from ftdrake.sim.collection import collect


@pytest.fixture(scope="module")
def small():
    config = ScenarioConfig()
    config.sensor.preset = "robotiq_ft300"  # 100 Hz: a small frame
    return collect(config, 2, kind="fourier", duration=1.0, n_jobs=1, progress=False)


def test_round_trip_keeps_rows_units_and_scenario(small, tmp_path):
    path = tmp_path / "d.parquet"
    save_dataset(small, path)
    frame, scenario = load_dataset(path)
    pd.testing.assert_frame_equal(frame, small)
    assert scenario.sensor.preset == "robotiq_ft300" and scenario.trajectory.kind == "fourier"
    units = json.loads(pq.read_schema(path).metadata[b"ftdrake.units"])
    assert units["t"] == "s" and units["q_3"] == "rad" and units["qdd_est_0"] == "rad/s^2"
    assert units["meas_Fz"] == "N" and units["external_true_Tx"] == "N*m"
    assert sorted(frame["trajectory"].unique()) == [0, 1]
    # Runs differ (their own seeds) but share the sensor's calibration.
    a, b = (frame[frame["trajectory"] == i]["meas_Fx"].to_numpy() for i in (0, 1))
    assert not np.array_equal(a, b)


def test_collect_refuses_contact_kinds_and_bad_counts():
    with pytest.raises(ConfigError, match="collect needs free motion"):
        collect(ScenarioConfig(), 1, kind="contact", progress=False)
    with pytest.raises(ValueError, match="trajectories must be >= 1"):
        collect(ScenarioConfig(), 0, progress=False)


def test_unreadable_dataset_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"PAR1 not really")
    with pytest.raises(ValueError, match="not a readable Parquet dataset"):
        load_dataset(bad)
    with pytest.raises(FileNotFoundError, match="no dataset"):
        load_dataset(tmp_path / "missing.parquet")


def test_imu_columns_keep_their_units_and_give_the_imu_layout(tmp_path):
    from ftdrake import conventions as col
    from ftdrake.data.dataset import imu_layout, joint_state_layout
    from ftdrake.errors import LogError

    config = ScenarioConfig()
    config.sensor.preset = "robotiq_ft300"
    config.imu.enabled = True
    frame = collect(config, 1, kind="fourier", duration=0.5, n_jobs=1, progress=False)
    path = tmp_path / "imu.parquet"
    save_dataset(frame, path)
    loaded, scenario = load_dataset(path)
    assert scenario.imu.enabled
    units = json.loads(pq.read_schema(path).metadata[b"ftdrake.units"])
    assert (units["imu_acc_z"], units["imu_gyro_x"], units["imu_alpha_y"]) == (
        "m/s^2", "rad/s", "rad/s^2")
    X = imu_layout(loaded)
    np.testing.assert_array_equal(X[:, :21], joint_state_layout(loaded))
    np.testing.assert_array_equal(X[:, 21:], loaded[list(col.IMU_INPUTS)].to_numpy())
    with pytest.raises(LogError, match=r"scenario\.imu\.enabled"):
        imu_layout(loaded.drop(columns=["imu_gyro_y"]))
