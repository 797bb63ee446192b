"""Registering tool measurements: injected frames, clock offsets and skews are recovered, and
the standard errors match the scatter of repeated estimates."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ftdrake.config.contour import HoleConfig
from ftdrake.errors import LogError
from ftdrake.experiments.hole_path import HolePath
from ftdrake.experiments.tool_registration import (
    densify,
    register_contour,
    register_timed,
    rigid_fit,
)

P_HOME = np.array([0.4, 0.0, 0.9])
ROTVEC = np.array([0.01, -0.02, 0.5])  # rad: R_BT
P_BT = np.array([1.2, -0.3, 0.05])  # m
NOISE = 10e-6  # m


def _tracker(p_W, R_BT, p_BT, rng):
    """What a tracker at (R_BT, p_BT) reports for points p_W, with noise."""
    return (p_W - p_BT) @ R_BT + rng.normal(0.0, NOISE, p_W.shape)


@pytest.fixture(scope="module")
def hole():
    path = HolePath.from_config(HoleConfig(diameter_m=0.02), P_HOME)
    t = np.arange(0.0, path.duration, 1e-3)
    return path, t, path.position_W(t)


def test_timed_registration_recovers_frame_clock_offset_and_skew(hole):
    path, t, p = hole
    R = Rotation.from_rotvec(ROTVEC).as_matrix()
    offset, skew = 0.0373, 2e-4
    measured = _tracker(p, R, P_BT, np.random.default_rng(1))
    dut = register_timed((1 + skew) * t + offset, measured, t, p)
    rotation_error = Rotation.from_matrix(dut.R @ R.T).magnitude()
    assert rotation_error < 1e-4  # rad
    np.testing.assert_allclose(dut.p, P_BT, atol=1e-4)
    assert abs(dut.offset_s - offset) < 2e-4  # s: 6 µm of path at 30 mm/s
    assert abs(dut.skew - skew) < 3e-5
    # The estimates lie within 4 standard errors of the truth (the errors are honest).
    assert abs(dut.offset_s - offset) < 4 * dut.offset_se
    assert abs(dut.skew - skew) < 4 * dut.skew_se
    assert np.all(np.abs(dut.p - P_BT) < 4 * dut.p_se + 1e-9)
    # Mapped back, the measurement lands on the path at the controller's times.
    back = dut.apply(measured)
    on_path = path.position_W(dut.to_controller_time((1 + skew) * t + offset))
    assert np.sqrt(np.mean(np.sum((back - on_path)**2, 1))) < 3 * NOISE


def test_path_registration_hides_a_rigid_tool_error_that_fiducials_keep(hole):
    _, t, p = hole
    R = Rotation.from_rotvec(ROTVEC).as_matrix()
    rng = np.random.default_rng(2)
    error = np.array([1.0e-3, -0.5e-3, 0.0])  # the tool cut 1.1 mm off the path, rigidly
    measured = _tracker(p + error, R, P_BT, rng)
    stamp = t + 0.02
    by_path = register_timed(stamp, measured, t, p)
    np.testing.assert_allclose(by_path.apply(measured).mean(0) - p.mean(0), 0.0, atol=2e-5)
    known = np.array([[0.8, 0.6, 0.0], [0.8, -0.6, 0.0], [-0.3, 0.6, 0.2], [-0.3, -0.6, 0.5]])
    fiducials = rigid_fit(_tracker(known, R, P_BT, rng), known)
    by_fiducials = register_timed(stamp, measured, t, p, fiducials=fiducials)
    np.testing.assert_allclose(by_fiducials.apply(measured).mean(0) - p.mean(0), error,
                               atol=5e-5)
    assert abs(by_fiducials.offset_s - 0.02) < 2e-4


def test_rigid_fit_standard_errors_match_the_scatter_of_repeated_fits():
    R = Rotation.from_rotvec(ROTVEC).as_matrix()
    known = np.array([[0.8, 0.6, 0.0], [0.8, -0.6, 0.0], [-0.3, 0.6, 0.2], [-0.3, -0.6, 0.5],
                      [0.2, 0.0, 1.0]])
    rng = np.random.default_rng(3)
    fits = [rigid_fit(_tracker(known, R, P_BT, rng), known) for _ in range(400)]
    offsets = np.array([f.p for f in fits])
    angles = np.array([Rotation.from_matrix(f.R @ R.T).as_rotvec() for f in fits])
    np.testing.assert_allclose(offsets.mean(0), P_BT, atol=5e-6)
    # The reported standard errors against the empirical std (400 fits: ±7 % sampling).
    reported_p = np.mean([f.p_se for f in fits], axis=0)
    reported_w = np.mean([f.rotation_se for f in fits], axis=0)
    np.testing.assert_allclose(reported_p, offsets.std(0), rtol=0.25)
    np.testing.assert_allclose(reported_w, angles.std(0), rtol=0.25)


def test_rigid_fit_refuses_fiducials_on_a_line_or_mismatched():
    line = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    with pytest.raises(LogError, match="one line"):
        rigid_fit(line, line)
    with pytest.raises(LogError, match="same points"):
        rigid_fit(np.eye(3), np.eye(4)[:, :3])
    with pytest.raises(LogError, match="too few"):
        rigid_fit(np.eye(3)[:2], np.eye(3)[:2])


def _rotation_2d(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def test_contour_registration_of_a_slot_recovers_rotation_and_offset():
    corners = np.array([[0, 0], [0.03, 0], [0.03, 0.02], [0, 0.02], [0, 0.0]])
    points = densify(corners, 1e-4)
    R, offset = _rotation_2d(0.05), np.array([0.003, 0.002])
    rng = np.random.default_rng(4)
    scan = (points - offset) @ R + rng.normal(0.0, NOISE, points.shape)
    dut = register_contour(scan[::-1], corners)  # order does not matter
    assert abs(dut.rotation_vector()[0] - 0.05) < 1e-4
    np.testing.assert_allclose(dut.p, offset, atol=5e-6)
    assert abs(dut.rotation_vector()[0] - 0.05) < 4 * dut.rotation_se[0]
    assert dut.rms_m < 2 * NOISE


def test_contour_registration_of_a_round_hole_matches_centres_and_flags_the_spin():
    theta = np.linspace(0.0, 2 * np.pi, 400, endpoint=False)
    ideal = 0.01 * np.column_stack([np.cos(theta), np.sin(theta)])
    cut = 1.03 * ideal + [0.001, -0.0005]  # wider and off-centre
    rng = np.random.default_rng(5)
    scan = (cut - [0.003, 0.002]) @ _rotation_2d(0.05) + rng.normal(0.0, NOISE, cut.shape)
    dut = register_contour(scan, np.vstack([ideal, ideal[:1]]))
    moved = dut.apply(scan)
    np.testing.assert_allclose(moved.mean(0), 0.0, atol=1e-5)  # the centre error is gone
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1).mean(), 0.0103, atol=1e-5)
    # The spin about the centre is barely determined: its standard error is degrees, 20×
    # what the offset's is at the radius.
    assert dut.rotation_se[0] > max(0.02, 20 * dut.p_se.max() / 0.01)


def test_contour_registration_in_3d():
    s = np.linspace(0.0, 1.0, 300)
    path = np.column_stack([0.05 * np.cos(4 * s), 0.03 * np.sin(6 * s), 0.02 * s])
    R = Rotation.from_rotvec([0.02, 0.01, -0.03]).as_matrix()
    rng = np.random.default_rng(6)
    scan = _tracker(path[::3], R, np.array([0.004, -0.002, 0.001]), rng)
    dut = register_contour(scan, path, spacing=5e-6)
    assert Rotation.from_matrix(dut.R @ R.T).magnitude() < 1e-3
    np.testing.assert_allclose(dut.p, [0.004, -0.002, 0.001], atol=2e-5)


def test_contour_registration_refuses_mismatched_dimensions():
    with pytest.raises(LogError, match="2-D but the commanded path is 3-D"):
        register_contour(np.zeros((20, 2)), np.zeros((5, 3)))
