"""The contour family's geometry: direction, tilted planes, slots, 3-D paths, tool tilt."""

import numpy as np
import pytest

from ftdrake.config import ScenarioConfig
from ftdrake.config.contour import HoleConfig
from ftdrake.errors import ConfigError
from ftdrake.experiments.hole_path import HolePath, Slot, hole_trajectory, plane_frame
from ftdrake.sim.station import robot_geometry

P_HOME = np.array([0.4, 0.0, 0.9])
DT = 1e-4


def _path(**kw) -> HolePath:
    return HolePath.from_config(HoleConfig(**kw), P_HOME)


def _sampled(path: HolePath):
    t = np.arange(0.0, path.duration, DT)
    p = path.position_W(t)
    return t, p, np.linalg.norm(np.diff(p, axis=0), axis=1) / DT


def _signed_area(p2) -> float:
    x, y = p2[:, 0], p2[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_clockwise_is_the_counter_clockwise_path_mirrored():
    ccw, cw = _path(diameter_m=0.02), _path(diameter_m=0.02, direction="cw")
    t = np.linspace(0.0, ccw.duration, 500)
    mirrored = ccw.position_W(t)
    mirrored[:, 1] = 2 * P_HOME[1] - mirrored[:, 1]
    np.testing.assert_allclose(cw.position_W(t), mirrored, atol=1e-15)
    on = ccw.hole_mask(t)
    # Independent: the shoelace area of the turn, +πr² counter-clockwise, −πr² clockwise.
    assert _signed_area(ccw.to_plane(ccw.position_W(t[on]))) == pytest.approx(
        np.pi * 0.01**2, rel=1e-3)
    assert _signed_area(cw.to_plane(cw.position_W(t[on]))) == pytest.approx(
        -np.pi * 0.01**2, rel=1e-3)
    np.testing.assert_allclose(cw.radial_error(cw.position_W(t[on])), 0.0, atol=1e-12)


@pytest.mark.parametrize("normal", [[0.0, 0.0, 1.0], [0.0, -0.34, 0.94], [0.3, 0.2, 0.93],
                                    [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
def test_plane_frame_is_a_rotation_with_z_along_the_normal(normal):
    dut = plane_frame(normal)
    np.testing.assert_allclose(dut.T @ dut, np.eye(3), atol=1e-12)
    assert np.linalg.det(dut) == pytest.approx(1.0)
    np.testing.assert_allclose(dut[:, 2], np.array(normal) / np.linalg.norm(normal), atol=1e-12)


def test_tilted_plane_path_lies_in_the_plane_at_constant_speed():
    normal = np.array([0.0, -np.sin(0.35), np.cos(0.35)])  # 20° about W's x
    dut = _path(diameter_m=0.03, normal=normal.tolist(), speed_m_s=0.04)
    t, p, speed = _sampled(dut)
    np.testing.assert_allclose((p - P_HOME) @ normal, 0.0, atol=1e-12)
    on = dut.hole_mask(t)
    # Independent: the distance from the centre is the radius on the turn.
    np.testing.assert_allclose(np.linalg.norm(p[on] - P_HOME, axis=1), 0.015, atol=1e-12)
    np.testing.assert_allclose(speed[on[:-1]], 0.04, rtol=1e-3)
    np.testing.assert_allclose(dut.tool_axis_W(t[:3]), np.tile(-normal, (3, 1)), atol=1e-12)


def _on_rounded_rectangle(p, hx, hy, rc) -> np.ndarray:
    """Independent of Slot: is each point on a side or on a corner's quarter circle?"""
    x, y = np.abs(p[:, 0]), np.abs(p[:, 1])
    on_side = ((np.abs(x - hx) < 1e-9) & (y <= hy - rc + 1e-9)) | (
        (np.abs(y - hy) < 1e-9) & (x <= hx - rc + 1e-9))
    in_corner = (x >= hx - rc - 1e-9) & (y >= hy - rc - 1e-9)
    on_arc = in_corner & (np.abs(np.hypot(x - (hx - rc), y - (hy - rc)) - rc) < 1e-9)
    return on_side | on_arc


def test_slot_runs_its_perimeter_at_constant_speed_through_rounded_corners():
    dut = _path(slot_m=[0.04, 0.012], corner_radius_m=0.002, speed_m_s=0.03)
    t, p, speed = _sampled(dut)
    on = dut.hole_mask(t)
    in_plane = dut.to_plane(p[on])
    assert _on_rounded_rectangle(in_plane, 0.02, 0.006, 0.002).all()
    np.testing.assert_allclose(dut.radial_error(p[on]), 0.0, atol=1e-12)
    perimeter = 2 * (0.04 + 0.012) - (8 - 2 * np.pi) * 0.002
    assert np.sum(np.linalg.norm(np.diff(p[on], axis=0), axis=1)) == pytest.approx(
        perimeter, rel=1e-3)
    assert dut.hole_window[1] - dut.hole_window[0] == pytest.approx(perimeter / 0.03)
    np.testing.assert_allclose(speed[on[:-1]], 0.03, rtol=1e-3)
    assert np.abs(np.diff(speed)).max() / DT < 1.0  # no jump in speed anywhere (m/s²)
    # The outward normal is perpendicular to the velocity and points away from the centre.
    normal = dut.normal_P(t[on][:-1] + 0.5 * DT)  # at each step's middle
    velocity = np.diff(in_plane, axis=0)
    np.testing.assert_allclose(np.sum(normal * velocity, axis=1), 0.0, atol=1e-9)
    assert (np.sum(normal * in_plane[:-1], axis=1) > 0).all()


@pytest.mark.parametrize("u", [0.001, 0.01, 0.0213, 0.03, 0.05, 0.07, 0.09])
@pytest.mark.parametrize("offset", [-3e-3, -1e-3, 2e-4, 3e-3])
def test_slot_signed_distance_along_its_normal(u, offset):
    dut = Slot(0.02, 0.006, 0.002)
    p = dut.point([u]) + offset * dut.normal([u])
    assert dut.signed_distance(p)[0] == pytest.approx(offset, abs=1e-12)


def test_three_d_path_rises_and_the_tool_leans_towards_the_outside():
    dut = _path(diameter_m=0.03, height_m=0.004, tool_tilt_deg=12.0)
    t, p, _ = _sampled(dut)
    on = dut.hole_mask(t)
    rise = p[on, 2] - P_HOME[2]
    assert rise.max() == pytest.approx(0.004, rel=1e-4) and rise.min() >= -1e-15
    np.testing.assert_allclose(dut.radial_error(p[on]), 0.0, atol=1e-12)
    axis = dut.tool_axis_W(t)
    np.testing.assert_allclose(np.linalg.norm(axis, axis=1), 1.0, atol=1e-12)
    lean = np.degrees(np.arccos(-axis[:, 2]))
    assert lean[~on].min() < 1e-6 and lean.max() == pytest.approx(12.0, abs=1e-3)
    # Leaning outwards: the axis' in-plane part along the position from the centre.
    outward = np.sum(axis[on, :2] * (p[on, :2] - P_HOME[:2]), axis=1)
    assert (outward >= -1e-15).all()


def test_new_hole_fields_say_which_field_is_wrong():
    for field, value in [("direction", "left"), ("normal", [0.0, 0.0, 0.0]),
                         ("slot_m", [0.04]), ("height_m", -1.0), ("tool_tilt_deg", 90.0)]:
        with pytest.raises(ConfigError, match=rf"hole\.{field}"):
            HoleConfig(**{field: value}).validate()
    with pytest.raises(ConfigError, match=r"hole\.corner_radius_m"):
        HoleConfig(slot_m=[0.04, 0.01], corner_radius_m=0.006).validate()


def test_ik_follows_a_tilted_clockwise_path_with_the_tool_reoriented():
    config = ScenarioConfig()
    geometry = robot_geometry(config)
    p_home = geometry.tip_and_axis(np.asarray(config.home_q))[0]
    path = HolePath.from_config(HoleConfig(diameter_m=0.02, direction="cw", height_m=0.002,
                                           tool_tilt_deg=8.0, rest_s=0.05,
                                           normal=[0.0, -0.26, 0.97]), p_home)
    dut = hole_trajectory(path, geometry, config.home_q)
    for t in np.linspace(0.0, path.duration, 17):
        tip, axis = geometry.tip_and_axis(dut.value(t).ravel())
        np.testing.assert_allclose(tip, path.position_W([t])[0], atol=2e-6)
        np.testing.assert_allclose(axis, path.tool_axis_W([t])[0], atol=1e-5)
