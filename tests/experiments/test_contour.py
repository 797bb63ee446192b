"""The hole-cutting benchmark's parts: path, IK, tool-side measurements, part two's GP."""

import numpy as np
import pytest

from ftdrake.config import ScenarioConfig
from ftdrake.config.contour import ContourScanConfig, HoleConfig, TrackerConfig
from ftdrake.errors import ConfigError
from ftdrake.experiments.hole_path import HolePath, hole_trajectory
from ftdrake.experiments.reference_correction import ReferenceCorrection
from ftdrake.sim.station import robot_geometry
from ftdrake.sim.tool_measurement import (
    measure_contour,
    measure_timed,
    normal_deviation,
    timed_error,
)
from ftdrake.systems.learned_feedforward import fit_feedforward_gp

P_HOME = np.array([0.4, 0.0, 0.9])


def _path(**kw) -> HolePath:
    return HolePath.from_config(HoleConfig(**kw), P_HOME)


def test_path_cuts_the_hole_at_constant_speed_after_a_tangent_lead_in():
    dut = _path(diameter_m=0.02, speed_m_s=0.03)
    dt = 1e-4
    t = np.arange(0.0, dut.duration, dt)
    p = dut.position_W(t)
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt
    on = dut.hole_mask(t[:-1])
    np.testing.assert_allclose(speed[on], 0.03, rtol=1e-3)
    np.testing.assert_allclose(dut.radial_error(p[dut.hole_mask(t)]), 0.0, atol=1e-12)
    # One full turn: the hole's first and last points coincide.
    start, end = dut.hole_window
    np.testing.assert_allclose(dut.position_W([start]), dut.position_W([end]), atol=1e-9)
    # Smooth everywhere: no jump in velocity (the lead-in meets the hole tangentially).
    assert np.abs(np.diff(speed)).max() / dt < 1.0  # m/s²
    np.testing.assert_allclose(p[0], P_HOME, atol=1e-12)  # pierced at the centre
    assert np.abs(p[:, 2] - P_HOME[2]).max() < 1e-12  # in the plane


def test_ik_puts_the_tip_on_the_path_with_the_tool_normal_to_the_plane():
    config = ScenarioConfig()
    geometry = robot_geometry(config)
    p_home = geometry.tip_and_axis(np.asarray(config.home_q))[0]
    path = HolePath.from_config(HoleConfig(diameter_m=0.02), p_home)
    dut = hole_trajectory(path, geometry, config.home_q)
    for t in np.linspace(0.0, path.duration, 23):
        tip, axis = geometry.tip_and_axis(dut.value(t).ravel())
        np.testing.assert_allclose(tip, path.position_W([t])[0], atol=2e-6)
        assert np.linalg.norm(axis[:2]) < 1e-5  # rad: the tool points straight down


def test_timed_measurement_samples_at_its_rate_with_its_latency():
    t = np.arange(0.0, 2.0, 1e-3)
    p = np.column_stack([np.sin(t), np.cos(t), t])
    dut = TrackerConfig(rate_hz=250.0, noise_std_m=0.0, latency_s=0.02, stamp_corrected=False)
    stamp, measured = measure_timed(t, p, dut)
    np.testing.assert_allclose(np.diff(stamp), 1 / 250.0)
    taken = stamp - 0.02
    np.testing.assert_allclose(measured, np.column_stack([np.sin(taken), np.cos(taken), taken]),
                               atol=1e-6)
    assert stamp[-1] <= t[-1] + 1e-12  # only what has arrived by the end
    # The error at the desired times: zero where the desired path is the true one.
    error = timed_error(taken[5:-5], measured[5:-5], taken, measured)
    np.testing.assert_allclose(error, 0.0, atol=1e-12)


def test_timed_measurement_noise_has_its_std():
    t = np.arange(0.0, 10.0, 1e-3)
    p = np.zeros((len(t), 3))
    _, measured = measure_timed(t, p, TrackerConfig(noise_std_m=1e-5))
    assert measured.std() == pytest.approx(1e-5, rel=0.05)


def test_contour_scan_is_evenly_spaced_and_untimed():
    theta = np.linspace(0, 2 * np.pi, 5000)
    circle = 0.01 * np.column_stack([np.cos(theta), np.sin(theta)])
    dut = measure_contour(circle, ContourScanConfig(spacing_m=2e-4, noise_std_m=0.0))
    assert dut.shape[1] == 2  # points in the plane, nothing else
    step = np.linalg.norm(np.diff(dut, axis=0), axis=1)
    np.testing.assert_allclose(step, 2e-4, rtol=1e-3)


def test_normal_deviation_of_a_shifted_and_wider_circle():
    r, dr, shift = 0.01, 50e-6, np.array([30e-6, 0.0])
    theta = np.linspace(0, 2 * np.pi, 3000, endpoint=False)
    unit = np.column_stack([np.cos(theta), np.sin(theta)])
    measured = (r + dr) * unit + shift
    ideal_theta = np.linspace(0, 2 * np.pi, 97, endpoint=False)
    normal = np.column_stack([np.cos(ideal_theta), np.sin(ideal_theta)])
    dut = normal_deviation(r * normal, normal, measured)
    # Independent: a circle of radius r + dr about `shift` crosses the normal line at
    # distance ≈ dr + shift · n (to first order in shift / r).
    np.testing.assert_allclose(dut, dr + normal @ shift, atol=1e-6)


def test_normal_deviation_is_nan_where_nothing_was_measured():
    measured = np.column_stack([np.linspace(0, 1e-2, 50), np.zeros(50)])
    ideal = np.array([[5e-3, 0.0], [5e-3, 0.01]])
    normal = np.array([[0.0, 1.0], [0.0, 1.0]])
    dut = normal_deviation(ideal, normal, measured)
    assert dut[0] == pytest.approx(0.0, abs=1e-12)
    assert np.isnan(dut[1])


def test_reference_correction_learns_inside_and_lets_go_outside():
    rng = np.random.default_rng(0)
    n = 2
    X = np.hstack([rng.uniform(-0.2, 0.2, (600, n)), rng.normal(0, 0.01, (600, 2 * n))])
    y = np.column_stack([1e-4 * np.sin(15 * X[:, 0]), -2e-4 * np.cos(12 * X[:, 1])])
    dut = ReferenceCorrection(fit_feedforward_gp(X, y, max_points=150), trust_ratio=0.5,
                              reject_ratio=0.9)
    inside = X[:50]
    correction, _, confidence = dut.evaluate(inside)
    np.testing.assert_allclose(correction, y[:50], atol=1e-5)
    assert (confidence == 1).all()
    far = np.hstack([np.full((3, n), 3.0), np.zeros((3, 2 * n))])
    correction, _, confidence = dut.evaluate(far)
    assert (confidence == 0).all() and (correction == 0).all()


def test_configs_say_which_field_is_wrong():
    with pytest.raises(ConfigError, match=r"hole\.diameter_m"):
        HoleConfig(diameter_m=1.0).validate()
    with pytest.raises(ConfigError, match=r"tracker\.rate_hz"):
        TrackerConfig(rate_hz=0).validate()
    with pytest.raises(ConfigError, match=r"contour_scan\.spacing_m"):
        ContourScanConfig(spacing_m=-1).validate()
