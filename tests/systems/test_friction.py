"""Joint friction: the law, its sign, the stability check, and its effect in the station."""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig
from ftdrake.config import FrictionConfig
from ftdrake.errors import ConfigError
from ftdrake.sim.scene import add_scene
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.systems.friction import JointFriction, check_explicit_stability


def _evaluate(dut, tau, q, v):
    context = dut.CreateDefaultContext()
    dut.get_input_port_actuation().FixValue(context, tau)
    dut.get_input_port_joint_state().FixValue(context, np.concatenate([q, v]))
    return (dut.get_output_port_actuation().Eval(context),
            dut.get_output_port_friction().Eval(context))


def test_friction_law_and_sign():
    config = FrictionConfig(coulomb=[3.0, 0.5], viscous=[1.0, 0.2], velocity_scale=0.3)
    dut = JointFriction(config, 2)
    tau = np.array([10.0, -2.0])
    for v in ([0.0, 0.0], [0.6, -0.1], [-2.0, 5.0]):
        v = np.array(v)
        actuation, friction = _evaluate(dut, tau, np.zeros(2), v)
        expected = np.array([1.0, 0.2]) * v + np.array([3.0, 0.5]) * np.tanh(v / 0.3)
        np.testing.assert_allclose(friction, expected, rtol=0, atol=1e-12)
        np.testing.assert_allclose(actuation, tau - expected, rtol=0, atol=1e-12)
        assert np.all(friction * v >= 0)  # friction always opposes the motion
    # Fast: Coulomb's full level; the smooth sign reaches it within 1e-6 at 5 scales.
    _, friction = _evaluate(dut, tau, np.zeros(2), np.array([10.0, -10.0]))
    np.testing.assert_allclose(friction, [3.0 + 10.0, -0.5 - 2.0], atol=1e-6)


def test_wrong_joint_count_and_bad_values_name_the_field():
    with pytest.raises(ConfigError, match=r"friction\.coulomb"):
        JointFriction(FrictionConfig(coulomb=[1.0] * 3, viscous=[1.0] * 3), 7)
    with pytest.raises(ConfigError, match=r"friction\.viscous"):
        FrictionConfig(coulomb=[1.0] * 7, viscous=[1.0] * 6).validate()
    with pytest.raises(ConfigError, match=r"friction\.velocity_scale"):
        FrictionConfig(velocity_scale=0.0).validate()


def test_too_stiff_friction_is_refused_naming_the_joint():
    config = ScenarioConfig()
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant
    ok = JointFriction(FrictionConfig(), 7)
    check_explicit_stability(ok, plant, scene.arm, config.home_q, config.time_step)  # defaults
    stiff = JointFriction(FrictionConfig(velocity_scale=0.01), 7)
    with pytest.raises(ConfigError, match=r"joint joint_t .*too\s+stiff"):
        check_explicit_stability(stiff, plant, scene.arm, config.home_q, config.time_step)


def _tracking_error(friction: bool) -> np.ndarray:
    config = ScenarioConfig()
    config = dc.replace(
        config, friction=dc.replace(config.friction, enabled=friction),
        trajectory=dc.replace(config.trajectory, kind="fourier", duration_s=3.0, seed=1),
        sensor=dc.replace(config.sensor, imperfections=False), cable=dc.replace(
            config.cable, enabled=False))
    station = build_station(config)
    assert (station.friction is not None) == friction
    log = simulate(station, progress=False).log
    q = log[[f"q_{i}" for i in range(7)]].to_numpy()
    return np.sqrt(((station.trajectory.vector_values(log.t.to_numpy()).T - q) ** 2).mean(0))


def test_friction_unknown_to_the_controller_worsens_tracking():
    without, with_friction = _tracking_error(False), _tracking_error(True)
    # The controller's model has no friction: every joint tracks worse, the base joint S
    # (no gravity, high inertia) by far the most relative to its error without.
    assert np.all(with_friction > without)
    assert with_friction[0] > 5 * without[0]
