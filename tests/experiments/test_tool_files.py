"""Reading a tracker's log and an inspected contour from CSV, registering them, and the
simulated measurements' mis-registration undone by the same registration."""

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ftdrake.config.contour import ContourScanConfig, HoleConfig, TrackerConfig
from ftdrake.errors import ConfigError, LogError
from ftdrake.experiments.hole_path import HolePath
from ftdrake.experiments.tool_files import (
    read_contour_points,
    read_tracker_log,
    register_contour_file,
    register_simulated_scan,
    register_simulated_timed,
    register_tracker_log,
)
from ftdrake.sim.tool_measurement import measure_contour, measure_timed

P_HOME = np.array([0.4, 0.0, 0.9])
MISREGISTERED = {"frame_rotation_rad": [0.003, -0.002, 0.4], "frame_offset_m": [1.5, -0.4, 0.2],
                 "clock_offset_s": 0.021, "clock_skew": 5e-5}


@pytest.fixture(scope="module")
def hole():
    path = HolePath.from_config(HoleConfig(diameter_m=0.02), P_HOME)
    t = np.arange(0.0, path.duration, 1e-3)
    return path, t, path.position_W(t)


def _write(path, **columns):
    pd.DataFrame(columns).to_csv(path, index=False)
    return path


def test_tracker_log_in_mm_with_orientation_is_read_and_registered(hole, tmp_path):
    path, t, p = hole
    config = TrackerConfig(**MISREGISTERED, noise_std_m=5e-6)
    stamp, measured = measure_timed(t, p, config)
    R_tool = Rotation.from_rotvec([np.pi, 0, 0])  # the tool points down in W
    R_T = Rotation.from_rotvec(config.frame_rotation_rad).inv() * R_tool  # seen by the tracker
    x, y, z, w = np.tile(R_T.as_quat(), (len(stamp), 1)).T
    file = _write(tmp_path / "tracker.csv", time=stamp, x=1e3 * measured[:, 0],
                  y=1e3 * measured[:, 1], z=1e3 * measured[:, 2], qw=w, qx=x, qy=y, qz=z,
                  status=1)
    log = read_tracker_log(file, unit="mm")
    np.testing.assert_allclose(log.p, measured, atol=1e-12)
    registration, out = register_tracker_log(log, t, p)
    np.testing.assert_allclose(out["R"][0], R_tool.as_matrix(), atol=1e-3)
    assert abs(registration.offset_s - 0.021) < 2e-4
    assert abs(registration.skew - 5e-5) < 3e-5
    np.testing.assert_allclose(out["p"], path.position_W(out["t"]), atol=5e-5)
    report = registration.report()
    assert set(report) >= {"clock_offset_s", "clock_offset_se_s", "offset_se_m",
                           "rotation_se_rad"}


@pytest.mark.parametrize(("columns", "message"), [
    ({"time": np.arange(20.0), "x": 0.0, "y": 0.0}, r"lacks column\(s\) \['z'\]"),
    ({"time": np.arange(5.0), "x": 0.0, "y": 0.0, "z": 0.0}, "5 rows are too few"),
    ({"time": np.r_[0, 1, 2, 2, 4:20], "x": 0.0, "y": 0.0, "z": 0.0},
     "time must increase strictly; row 4 has t = 2.0 after 2.0"),
    ({"time": np.arange(20.0), "x": 0.0, "y": 0.0, "z": 0.0, "qw": 1.0, "qx": 0.0},
     r"needs all of \['qw', 'qx', 'qy', 'qz'\]"),
    ({"time": np.arange(20.0), "x": 0.0, "y": 0.0, "z": 0.0, "qw": 1.0, "qx": 0.5, "qy": 0.0,
      "qz": 0.0},
     "quaternion has norm 1.118"),
    ({"time": np.arange(20.0), "x": np.r_[0.0, np.nan, np.zeros(18)], "y": 0.0, "z": 0.0},
     "row 2 column 'x' is empty"),
])
def test_bad_tracker_logs_are_named(tmp_path, columns, message):
    file = _write(tmp_path / "bad.csv", **columns)
    with pytest.raises(LogError, match=message) as error:
        read_tracker_log(file)
    assert "bad.csv" in str(error.value)


def test_missing_files_and_units_are_named(tmp_path):
    with pytest.raises(LogError, match="no such tracker log file"):
        read_tracker_log(tmp_path / "absent.csv")
    with pytest.raises(LogError, match="no such contour file"):
        read_contour_points(tmp_path / "absent.csv")
    with pytest.raises(LogError, match="'m' or 'mm'"):
        read_contour_points(tmp_path / "absent.csv", unit="in")


def test_contour_file_2d_and_3d(tmp_path, hole):
    theta = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    corners = np.array([[0, 0], [0.03, 0], [0.03, 0.02], [0, 0.02], [0, 0.0]])
    s = np.linspace(0, 4, 400)
    slot = np.column_stack([np.interp(s, np.arange(5), corners[:, 0]),
                            np.interp(s, np.arange(5), corners[:, 1])])
    c, sn = np.cos(0.04), np.sin(0.04)
    scan = (slot - [0.002, 0.001]) @ np.array([[c, -sn], [sn, c]])
    file = _write(tmp_path / "scan.csv", x=1e3 * scan[:, 0], y=1e3 * scan[:, 1])
    points = read_contour_points(file, unit="mm")
    assert points.shape == (400, 2)
    registration, moved = register_contour_file(points, corners)
    np.testing.assert_allclose(moved, slot, atol=1e-7)
    assert abs(registration.rotation_vector()[0] - 0.04) < 1e-6
    file3 = _write(tmp_path / "scan3.csv", X=np.cos(theta), Y=np.sin(theta), Z=theta)
    assert read_contour_points(file3).shape == (200, 3)
    with pytest.raises(LogError, match=r"lacks column\(s\) \['y'\]"):
        read_contour_points(_write(tmp_path / "bad.csv", x=theta, z=theta))
    with pytest.raises(LogError, match="3 rows are too few"):
        read_contour_points(_write(tmp_path / "few.csv", x=theta[:3], y=theta[:3]))


@pytest.mark.parametrize("registration", ["fiducials", "path"])
def test_simulated_tracker_mis_registration_is_undone(hole, registration):
    _path, t, p = hole
    error = np.array([0.8e-3, -0.4e-3, 0.0])  # the tool's own rigid error
    true_stamp, true_p = measure_timed(t, p + error, TrackerConfig())
    config = TrackerConfig(**MISREGISTERED, registration=registration)
    stamp, measured = measure_timed(t, p + error, config)
    assert np.abs(measured - true_p).max() > 0.1  # far off before registration
    stamp, measured, dut = register_simulated_timed(stamp, measured, t, p, config)
    np.testing.assert_allclose(stamp, true_stamp, atol=3e-4)
    # Fiducials keep the tool's error; the path registration absorbs it.
    expected = true_p if registration == "fiducials" else true_p - error
    assert np.sqrt(np.mean((measured - expected)**2)) < 5e-5
    assert dut.report()["points"] > 1000
    same = register_simulated_timed(true_stamp, true_p, t, p, TrackerConfig())
    assert same[0] is true_stamp and same[1] is true_p and same[2] is None


@pytest.mark.parametrize("registration", ["datums", "path"])
def test_simulated_scan_mis_registration_is_undone(hole, registration):
    path, t, p = hole
    on = path.hole_mask(t)
    cut = path.to_plane(p[on]) * 1.02 + [0.001, 0.0]  # wider and off-centre
    truth = measure_contour(cut, ContourScanConfig())
    config = ContourScanConfig(frame_rotation_rad=0.3, frame_offset_m=[0.05, -0.02],
                               registration=registration)
    scan = measure_contour(cut, config)
    assert np.abs(scan - truth).max() > 0.01
    back, dut = register_simulated_scan(scan, path.to_plane(p[on]), config)
    if registration == "datums":  # point for point, with the centre error kept
        np.testing.assert_allclose(back, truth, atol=2e-5)
    else:  # the centre error is absorbed; the radius error and the shape remain
        radius = np.linalg.norm(back, axis=1)
        np.testing.assert_allclose(radius, np.linalg.norm(truth - [0.001, 0.0], axis=1),
                                   atol=5e-6)
    assert dut is not None


def test_mis_registration_settings_are_checked():
    with pytest.raises(ConfigError, match=r"tracker\.frame_offset_m"):
        TrackerConfig(frame_offset_m=[0.0, 1.0]).validate()
    with pytest.raises(ConfigError, match=r"tracker\.clock_skew"):
        TrackerConfig(clock_skew=0.5).validate()
    with pytest.raises(ConfigError, match=r"tracker\.registration"):
        TrackerConfig(registration="guess").validate()
    with pytest.raises(ConfigError, match=r"contour_scan\.datums_m"):
        ContourScanConfig(datums_m=[[0.0, 0.0]]).validate()
    assert not TrackerConfig().misregistered and TrackerConfig(clock_skew=1e-6).misregistered
