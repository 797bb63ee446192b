"""The rig's joint encoders (systems/encoders.py, scenario.encoders): off by default and then
without effect; their convention q_measured = q_link + τ/k − offset checked against Drake's
potential energy; the station's readers get their reading; and offsets injected in the rig
recovered from the simulated wrench."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig, build_station, simulate
from ftdrake import conventions as col
from ftdrake.compensation.calibration.joint_offsets import identify_joint_offsets
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.config import EncoderConfig, dump_config, parse_config
from ftdrake.errors import ConfigError
from ftdrake.sim.scene import add_scene
from ftdrake.sim.station import robot_geometry
from ftdrake.sim.trajectories import _min_jerk_path, _spline
from ftdrake.systems.encoders import JointEncoders

OFFSETS = [0.0, np.radians(2.0), 0.0, 0.0, 0.0, np.radians(2.0), 0.0]  # L and B, as the real arm


def short_config(duration=0.3):
    config = ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", duration
    return config


def test_off_by_default_and_without_effect_when_on_with_nothing_to_add():
    assert ScenarioConfig().encoders == EncoderConfig()
    assert not EncoderConfig().enabled
    station = build_station(short_config())
    assert station.encoders is None
    assert "joint_encoders" not in {s.get_name() for s in station.diagram.GetSystems()}
    log = simulate(station, progress=False).log
    config = short_config()
    config.encoders.enabled = True  # zero offsets, no sag: the links' angles exactly
    on = build_station(config.validate())
    assert on.encoders is not None
    log_on = simulate(on, progress=False).log
    assert log_on.equals(log)


def _potential_slope(plant, arm, q):
    """∂V/∂q by central differences of Drake's potential energy: the holding torque."""
    context = plant.CreateDefaultContext()
    slope = np.zeros(len(q))
    for j in range(len(q)):
        step = np.zeros(len(q))
        step[j] = 1e-6
        plant.SetPositions(context, arm, q + step)
        plus = plant.CalcPotentialEnergy(context)
        plant.SetPositions(context, arm, q - step)
        slope[j] = (plus - plant.CalcPotentialEnergy(context)) / 2e-6
    return slope


def test_the_reading_is_the_link_angle_plus_the_sag_minus_the_offset():
    config = ScenarioConfig()
    stiffness = [0.0, 1000.0, 0.0, 2000.0, 0.0, 0.0, 0.0]
    config.encoders = EncoderConfig(enabled=True, offsets=OFFSETS, sag_stiffness=stiffness)
    scene = add_scene(DiagramBuilder(), config.validate())
    dut = JointEncoders(config.encoders, scene.plant, scene.arm)
    q = np.asarray(config.home_q) + 0.1
    v = np.arange(7) * 0.1
    context = dut.CreateDefaultContext()
    dut.get_input_port_state().FixValue(context, np.r_[q, v])
    out = dut.get_output_port_measured_state().Eval(context)
    tau = _potential_slope(scene.plant, scene.arm, q)
    expected = q - np.asarray(OFFSETS) + tau / np.where(np.asarray(stiffness) > 0, stiffness,
                                                        np.inf)
    np.testing.assert_allclose(out[:7], expected, atol=1e-9)
    np.testing.assert_array_equal(out[7:], v)
    assert tau[1] < 0 and out[1] < q[1] - OFFSETS[1]  # the holding torque's sign: the sag's


@pytest.mark.parametrize(("change", "message"), [
    ({"sag_stiffness": [1.0, -2.0]}, r"scenario.encoders.sag_stiffness\[1\]: must be >= 0"),
    ({"offsets": [0.0, float("nan")]}, r"scenario.encoders.offsets: entries must be finite"),
    ({"offsets": [0.0] * 7, "sag_stiffness": [0.0] * 6}, "one entry per joint like"),
])
def test_bad_encoder_fields_are_named(change, message):
    config = ScenarioConfig()
    config.encoders = EncoderConfig(enabled=True, **change)
    with pytest.raises(ConfigError, match=message):
        config.validate()


def test_joint_count_and_transmission_conflict_are_named():
    config = ScenarioConfig()
    config.encoders = EncoderConfig(enabled=True, offsets=[0.01] * 6)
    with pytest.raises(ConfigError, match=r"encoders.offsets: must have one entry per arm joint "
                                          r"\(7\), got 6"):
        build_station(config.validate())
    config.encoders = EncoderConfig(enabled=True, sag_stiffness=[1e3] * 7)
    config.transmission.enabled = True
    with pytest.raises(ConfigError, match="sag_stiffness: the compliant transmissions"):
        config.validate()


def test_the_yaml_section_round_trips():
    config = ScenarioConfig()
    config.encoders = EncoderConfig(enabled=True, offsets=OFFSETS, sag_stiffness=[500.0] * 7)
    assert parse_config(dump_config(config)).encoders == config.encoders


def held_poses(config, count=12, move=0.8, hold=0.5, seed=0):
    """Rest-to-rest moves through `count` random poses about home, each clear of the
    environment, held `hold` s."""
    home = np.asarray(config.home_q, dtype=float)
    spread = np.array([0.8, 0.3, 0.8, 0.4, 1.2, 0.8, 1.2])
    geometry = robot_geometry(config)
    rng = np.random.default_rng(seed)
    poses = [home]
    while len(poses) <= count:
        pose = home + rng.uniform(-1, 1, 7) * spread
        leg = _spline(_min_jerk_path(np.array([0.0, 1.0, 2.0]), np.array([poses[-1], pose,
                                                                          pose])), 2.0)
        if geometry.clear_of_environment(leg):
            poses.append(pose)
    poses.append(home)
    times, points = [0.0], [home]
    for pose in poses[1:]:
        times += [times[-1] + move, times[-1] + move + hold]
        points += [pose, pose]
    return _spline(_min_jerk_path(np.array(times), np.array(points)), times[-1])


def test_offsets_injected_in_the_rig_are_recovered_from_its_wrench():
    config = ScenarioConfig()
    config.cable.enabled = False  # a rigid payload: what the physics model describes
    config.encoders = EncoderConfig(enabled=True, offsets=OFFSETS)
    station = build_station(config.validate(), trajectory=held_poses(config))
    result = simulate(station, progress=False)
    log = result.log
    # The log's q is what the encoders read: the links' angle minus the offset (the arm
    # ends held at home; its last sample is one step before the final state).
    plant = station.plant
    q_end = plant.GetPositions(plant.GetMyContextFromRoot(result.context), station.scene.arm)
    np.testing.assert_allclose(log[col.joint_columns(col.Q, 7)].to_numpy()[-1],
                               q_end - OFFSETS, atol=1e-4)  # the offsets: 0.035 rad
    X = np.hstack([log[col.joint_columns(p, 7)].to_numpy() for p in (col.Q, col.QD, col.QDD)])
    Y = log[col.wrench_columns(col.IDEAL)].to_numpy()
    dut = identify_joint_offsets(X[::10], Y[::10], PhysicsPayloadCompensator(mode="dynamic"),
                                 include="all")
    for name, i in (("joint_l", 1), ("joint_b", 5)):
        assert abs(dut.offsets_deg[name] - np.degrees(OFFSETS[i])) <= 0.05, dut.summary()
    for name in ("joint_e", "joint_u", "joint_r"):
        assert abs(dut.offsets_deg[name]) <= 0.05, dut.summary()
    assert set(dut.unidentifiable) == {"joint_s", "joint_t"}


def test_a_sag_in_the_rig_is_reported_as_offset_or_sag():
    """A compliance on the shoulder pitch L alone, whose gravity torque keeps its sign: the
    identification finds an 'offset' on L alone, names it as offset or sag, and its value is
    a sag the torques over the rows give (−τ/k, within their range)."""
    config = ScenarioConfig()
    config.cable.enabled = False
    k = 1000.0
    config.encoders = EncoderConfig(enabled=True, sag_stiffness=[0.0, k, 0, 0, 0, 0, 0])
    station = build_station(config.validate(), trajectory=held_poses(config))
    log = simulate(station, progress=False).log
    X = np.hstack([log[col.joint_columns(p, 7)].to_numpy() for p in (col.Q, col.QD, col.QDD)])
    Y = log[col.wrench_columns(col.IDEAL)].to_numpy()
    dut = identify_joint_offsets(X[::10], Y[::10], PhysicsPayloadCompensator(mode="dynamic"))
    assert dut.included == ("joint_l",), dut.summary()
    assert "keeps its sign" in dut.confounded_with_sag["joint_l"]
    low, high = dut.identifiability.gravity_torque_range["joint_l"]
    assert np.degrees(-high / k) <= dut.offsets_deg["joint_l"] <= np.degrees(-low / k)
