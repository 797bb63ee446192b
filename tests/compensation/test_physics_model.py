"""Physics payload compensator and the hybrid physics + learned residual."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig
from ftdrake import conventions as col
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import (
    ExcitationWarning,
    PhysicsPayloadCompensator,
    payload_regressor,
)
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.errors import RobotModelError
from ftdrake.physics.rigid_body import SensorKinematics, newton_euler_wrench, sensor_kinematics
from ftdrake.physics.robot import ftdrake_arm
from ftdrake.physics.scenario_robot import robot_description
from ftdrake.sim.collection import collect
from ftdrake.sim.scene import add_scene
from ftdrake.testing import split_by_trajectory
from tests.helpers import DATA

TRUE_MASS = 1.5
TRUE_COM = np.array([0.02, 0.2 / 30, 0.26 / 3])  # m, from ft_sensor_tool.sdf

vec3 = arrays(np.float64, (4, 3), elements=st.floats(-5, 5))


@settings(max_examples=30, deadline=None)
@given(w=vec3, alpha=vec3, a=vec3, g=vec3)
def test_regressor_matches_newton_euler(w, alpha, a, g):
    rng = np.random.default_rng(1)
    mass, com = 1.3, rng.uniform(-0.1, 0.1, 3)
    L = rng.normal(size=(3, 3))
    I_cm = L @ L.T * 0.01 + np.eye(3) * 1e-3
    kin = SensorKinematics(np.tile(np.eye(3), (4, 1, 1)), w, alpha, a, g)
    expected = newton_euler_wrench(mass, com, I_cm, kin)
    I_So = I_cm + mass * (com @ com * np.eye(3) - np.outer(com, com))  # parallel axis
    phi = np.concatenate([[mass], mass * com, I_So[0], I_So[1, 1:], [I_So[2, 2]], np.zeros(6)])
    phi[4:10] = [I_So[0, 0], I_So[0, 1], I_So[0, 2], I_So[1, 1], I_So[1, 2], I_So[2, 2]]
    got = payload_regressor(w, alpha, a - g) @ phi
    np.testing.assert_allclose(got, expected, atol=1e-9 * (1 + np.abs(expected).max()))


def test_dynamic_identification_recovers_the_tool(rigid_dataset):
    X = joint_state_layout(rigid_dataset, source="plant")
    Y = wrench_targets(rigid_dataset)  # noisy, biased, drifting measured wrench
    # The simulated sensor is mounted rotated by sensor.mounting_rpy_deg (a few degrees, which
    # moves a CoM 87 mm out by ~4 mm): identify that rotation too.
    dut = PhysicsPayloadCompensator(identify_mounting=True).fit(X[::4], Y[::4])
    p = dut.identified()
    assert p["m"]["value"] == pytest.approx(TRUE_MASS, rel=0.01)
    np.testing.assert_allclose(p["com"]["value"], TRUE_COM, atol=1e-3)
    np.testing.assert_allclose(p["mounting_rpy_deg"]["value"],
                               ScenarioConfig().sensor.mounting_rpy_deg, atol=0.1)
    # The bias the sensor config adds (drift is small over 10 s runs).
    np.testing.assert_allclose(dut.parameters_[10:13], [0.6, -0.4, 1.2], atol=0.1)
    # Standard errors are reported and small for the well-excited mass.
    assert 0 < p["m"]["std_error"] < 0.01
    assert dut.condition_number_ > 1


def test_physics_predicts_internal_wrench_near_noise_floor(rigid_dataset):
    train, test = split_by_trajectory(rigid_dataset, [2])
    dut = PhysicsPayloadCompensator().fit(joint_state_layout(train, "plant")[::3],
                                          wrench_targets(train)[::3])
    error = dut.predict(joint_state_layout(test, "plant")) - wrench_targets(test, col.INTERNAL_TRUE)
    rms = np.sqrt(np.mean(error**2, axis=0))
    sigma = np.array([1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800])  # ati_gamma preset
    assert np.all(rms < 6 * sigma), rms / sigma


def test_static_hold_data_warns_about_excitation(rigid_dataset):
    X = joint_state_layout(rigid_dataset, "plant")[:200]  # the first 0.2 s: nearly at rest
    Y = wrench_targets(rigid_dataset)[:200]
    with pytest.warns(ExcitationWarning, match="does not excite"):
        PhysicsPayloadCompensator().fit(X, Y)


def test_dynamic_mode_refuses_position_only_features():
    X = np.zeros((20, 21))
    with pytest.raises(ValueError, match="needs features='q,qd,qdd'"):
        PhysicsPayloadCompensator(features="q").fit(X, np.zeros((20, 6)))


def test_robot_joint_count_must_match():
    X = np.random.default_rng(0).normal(size=(30, 18))  # 6 joints
    with pytest.raises(ValueError, match="6 joints; the robot model has 7"):
        PhysicsPayloadCompensator().fit(X, np.zeros((30, 6)))


def test_hybrid_beats_physics_and_forest_with_cable_and_crosstalk(realistic_dataset):
    train, test = split_by_trajectory(realistic_dataset, [3])
    Xtr, Ytr = joint_state_layout(train), wrench_targets(train)
    Xte, truth = joint_state_layout(test), wrench_targets(test, col.INTERNAL_TRUE)
    forest = RandomForestCompensator(features="q", n_estimators=40, min_samples_leaf=5,
                                     random_state=0, n_jobs=2)
    models = {
        "physics": PhysicsPayloadCompensator(),
        "forest": forest,
        "hybrid": HybridCompensator(residual=forest),
    }
    rms = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        for name, model in models.items():
            model.fit(Xtr[::3], Ytr[::3])
            rms[name] = np.sqrt(np.mean((model.predict(Xte) - truth) ** 2, axis=0))
    force = {k: np.linalg.norm(v[:3]) for k, v in rms.items()}
    assert force["hybrid"] < force["physics"], force
    assert force["hybrid"] < force["forest"], force


URDF = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="upper">
    <inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="forearm">
    <inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="ft_frame"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="forearm"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="sensor_mount" type="fixed"><parent link="forearm"/><child link="ft_frame"/>
    <origin xyz="0 0 0.4" rpy="0.3 0 0"/></joint>
</robot>
"""


def test_identifies_payload_on_a_users_urdf(tmp_path):
    """A user's robot: readings made from known payload parameters are identified back."""
    path = tmp_path / "two_link.urdf"
    path.write_text(URDF)
    dut = PhysicsPayloadCompensator(robot=str(path), sensor_frame="ft_frame", base_frame="base")
    rng = np.random.default_rng(3)
    t = np.linspace(0, 20, 2000)[:, None]
    w = np.array([0.7, 1.3])
    q = np.hstack([np.sin(w[0] * t), 1.2 * np.sin(w[1] * t + 1)])
    qd = np.hstack([w[0] * np.cos(w[0] * t), 1.2 * w[1] * np.cos(w[1] * t + 1)])
    qdd = np.hstack([-w[0] ** 2 * np.sin(w[0] * t), -1.2 * w[1] ** 2 * np.sin(w[1] * t + 1)])
    X = np.hstack([q, qd, qdd])
    mass, com = 0.8, np.array([0.01, -0.02, 0.05])
    phi = np.concatenate([[mass], mass * com, [0.004, 0, 0, 0.004, 0, 0.002],
                          [0.3, -0.2, 0.5, 0.01, 0.02, -0.01]])
    Y = dut.regressor(X) @ phi + rng.normal(0, 0.01, (len(X), 6))
    dut.fit(X, Y)
    assert dut.identified()["m"]["value"] == pytest.approx(mass, rel=0.01)
    np.testing.assert_allclose(dut.identified()["com"]["value"], com, atol=2e-3)
    np.testing.assert_allclose(dut.parameters_[10:], phi[10:], atol=0.01)


def test_users_robot_without_the_sensor_frame_is_refused(tmp_path):
    path = tmp_path / "two_link.urdf"
    path.write_text(URDF)
    dut = PhysicsPayloadCompensator(robot=str(path), sensor_frame="nope", base_frame="base")
    with pytest.raises(RobotModelError, match="has no sensor frame named 'nope'"):
        dut.fit(np.zeros((50, 6)), np.zeros((50, 6)))
    with pytest.raises(RobotModelError, match="needs sensor_frame"):
        PhysicsPayloadCompensator(robot=str(path)).fit(np.zeros((50, 6)), np.zeros((50, 6)))
    with pytest.raises(RobotModelError, match="no such file"):
        PhysicsPayloadCompensator(robot=str(tmp_path / "none.urdf"), sensor_frame="tip").fit(
            np.zeros((50, 6)), np.zeros((50, 6)))


def test_the_simulations_robot_description_has_the_scenes_kinematics():
    """The physics model needs no scenario: the scene describes its arm as model directives,
    and that description's sensor-frame motion equals the simulated plant's to round-off."""
    config = ScenarioConfig()
    description = robot_description(config.models)
    assert description == ftdrake_arm()  # robot=None means exactly this arm
    scene = add_scene(DiagramBuilder(), config)
    plant, frame_S = description.build_plant()
    rng = np.random.default_rng(3)
    q, v, vd = rng.uniform(-1.5, 1.5, (3, 25, 7))
    expected = sensor_kinematics(scene.plant, scene.plant.CreateDefaultContext(),
                                 scene.sensor_frame, q, v, vd, scene.arm)
    got = sensor_kinematics(plant, plant.CreateDefaultContext(), frame_S, q, v, vd)
    for name in ("R_WS", "w_WS_S", "alpha_WS_S", "a_WSo_S", "g_S"):
        np.testing.assert_allclose(getattr(got, name), getattr(expected, name), atol=1e-12)
    # A scenario with the arm based elsewhere gets its own description, same sensor frame.
    config.models.p_WArmBase = [0.1, 0.0, 0.8]
    moved = robot_description(config.models)
    assert moved != ftdrake_arm() and "[0.1, 0.0, 0.8]" in moved.model
    assert moved.sensor_frame == description.sensor_frame


# -- the compiled row path ------------------------------------------------------------------
USER_ARM = str(DATA / "prismatic_arm.urdf")


def drake_prediction(model, X, plant, frame_S, instance=None):
    """Independent of the compiled chain: Drake's Jacobians, numpy's regressor, the product."""
    n = X.shape[1] // 3
    kin = sensor_kinematics(plant, plant.CreateDefaultContext(), frame_S, X[:, :n],
                            X[:, n:2 * n], X[:, 2 * n:], instance)
    g_S = np.einsum("nji,j->ni", kin.R_WS, np.asarray(model.gravity, dtype=float))
    moving = model.mode == "dynamic"
    A = payload_regressor(kin.w_WS_S * moving, kin.alpha_WS_S * moving,
                          kin.a_WSo_S * moving - g_S)
    wrench = A @ model.parameters_[:16]
    if model.weight_without_inertia:  # [m_w·g; (m_w·c_w) × g], written out independently
        m_w, h_w = model.parameters_[16], model.parameters_[17:20]
        wrench = wrench + np.hstack([m_w * g_S, np.cross(h_w, g_S)])
    return wrench


def fitted_by_hand(model, n_joints, seed=0):
    """The estimator with random parameters set as `fit` would (no data needed)."""
    model.parameters_ = np.random.default_rng(seed).normal(size=model.n_parameters)
    model.n_joints_ = n_joints
    return model


@settings(max_examples=40, deadline=None)
@given(X=arrays(np.float64, (3, 21), elements=st.floats(-3, 3)),
       static=st.booleans(), scale=st.floats(1, 8), weight=st.booleans())
def test_row_kernel_equals_drake_on_ftdrake_arm(X, static, scale, weight):
    X[:, 14:] *= scale  # q̈ up to 24 rad/s²
    scene = _arm_scene()
    dut = fitted_by_hand(PhysicsPayloadCompensator(
        mode="static" if static else "dynamic", features="q" if static else "q,qd,qdd",
        weight_without_inertia=weight and not static), 7)
    expected = drake_prediction(dut, X, scene.plant, scene.sensor_frame, scene.arm)
    tol = 1e-12 * max(1.0, np.abs(expected).max())
    rows = np.array([dut.predict_row(x) for x in X])
    np.testing.assert_allclose(rows, expected, rtol=0, atol=tol)
    loop = dut.row_predictor()
    np.testing.assert_allclose([loop(x)[0] for x in X], expected, rtol=0, atol=tol)
    np.testing.assert_allclose(dut.regressor(X) @ dut.parameters_, expected, rtol=0, atol=tol)


@settings(max_examples=40, deadline=None)
@given(X=arrays(np.float64, (3, 18), elements=st.floats(-3, 3)),
       gravity=arrays(np.float64, 3, elements=st.floats(-10, 10)))
def test_row_kernel_equals_drake_on_a_users_urdf(X, gravity):
    X[:, 1] /= 6  # the prismatic joint within its travel (m)
    dut = fitted_by_hand(PhysicsPayloadCompensator(robot=USER_ARM, sensor_frame="ft_sensor",
                                                   gravity=tuple(gravity)), 6)
    plant, frame_S = dut.robot_description().build_plant()
    expected = drake_prediction(dut, X, plant, frame_S)
    tol = 1e-12 * max(1.0, np.abs(expected).max())
    np.testing.assert_allclose([dut.predict_row(x) for x in X], expected, rtol=0, atol=tol)
    np.testing.assert_allclose(dut.regressor(X) @ dut.parameters_, expected, rtol=0, atol=tol)


def test_row_path_follows_parameter_changes():
    X = np.random.default_rng(4).uniform(-1, 1, (2, 18))
    dut = fitted_by_hand(PhysicsPayloadCompensator(robot=USER_ARM, sensor_frame="ft_sensor"), 6)
    before = dut.predict_row(X[0])
    dut.set_params(gravity=(0.0, 0.0, -1.62))  # the same arm on the Moon
    np.testing.assert_allclose(dut.predict_row(X[0]), dut.regressor(X)[0] @ dut.parameters_,
                               atol=1e-12)
    assert not np.allclose(dut.predict_row(X[0]), before)
    dut.parameters_ = dut.parameters_ * 2
    np.testing.assert_allclose(dut.predict_row(X[0]), dut.regressor(X)[0] @ dut.parameters_,
                               atol=1e-12)


def test_hybrid_row_predictor_equals_predict(rigid_dataset):
    X = joint_state_layout(rigid_dataset, source="plant")[::10]
    Y = wrench_targets(rigid_dataset)[::10]
    residual = RandomForestCompensator(features="q", n_estimators=5, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        dut = HybridCompensator(residual=residual).fit(X, Y)
    row = dut.row_predictor()
    np.testing.assert_allclose([row(x)[0] for x in X[:50]], dut.predict(X[:50]), atol=1e-9)


_SCENE = []


def _arm_scene():
    if not _SCENE:
        _SCENE.append(add_scene(DiagramBuilder(), ScenarioConfig()))
    return _SCENE[0]


def test_a_weight_carried_without_inertia_is_told_from_the_tool_mass():
    """The cable's hanging weight alone (its spring off, no cross-talk): a force along gravity
    that does not follow the tool's accelerations. The rigid model takes it for tool mass; with
    ``weight_without_inertia`` both come out right (truth from the scene's SDF and config)."""
    config = ScenarioConfig()
    config.sensor.crosstalk = 0.0
    config.cable.stiffness = 0.0
    data = collect(config, 2, kind="fourier", duration=10.0, seed=3, n_jobs=2, progress=False)
    X, Y = joint_state_layout(data)[::4], wrench_targets(data)[::4]
    fits = {}
    for weight in (False, True):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            fits[weight] = PhysicsPayloadCompensator(
                identify_mounting=True, weight_without_inertia=weight).fit(X, Y).parameters_
    cable_mass = config.cable.weight_n / 9.81
    assert fits[False][0] - TRUE_MASS > 0.8 * cable_mass  # the weight taken for mass
    p = fits[True]
    assert p[0] == pytest.approx(TRUE_MASS, rel=0.01)
    np.testing.assert_allclose(p[1:4] / p[0], TRUE_COM, atol=1e-3)
    assert p[16] == pytest.approx(cable_mass, rel=0.05)
    np.testing.assert_allclose(p[17:20] / p[16], config.cable.p_SAttach, atol=0.01)


def test_weight_without_inertia_needs_motion():
    X = np.zeros((40, 21))
    with pytest.raises(ValueError, match="static"):
        PhysicsPayloadCompensator(mode="static", features="q",
                                  weight_without_inertia=True).fit(X[:, :7], np.zeros((40, 6)))
