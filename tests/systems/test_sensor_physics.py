"""The sensor's reading checked against independent physics: statics, Newton–Euler, contact.

A discrete plant's sampled outputs at sample k (reaction forces, contact results, v̇) come
from the step that started at sample k−1: the consistent state for an independent computation
is (q_{k−1}, v_{k−1}) with v̇_k. With that alignment the checks below hold to round-off.
"""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from ftdrake import ForceTorqueSensor, ScenarioConfig, build_station, simulate
from ftdrake import conventions as col
from ftdrake.physics.rigid_body import (
    GRAVITY_W,
    newton_euler_wrench,
    sensor_kinematics,
    tool_inertia,
)
from ftdrake.sim.scene import add_scene


def ideal_config(kind="fourier", duration=4.0):
    config = ScenarioConfig()
    config.sensor.imperfections = False
    config.cable.enabled = False
    config.trajectory.kind = kind
    config.trajectory.duration_s = duration
    return config


def static_reading(config, q):
    """Holds the arm at q with exact gravity compensation; returns (sensor reading, scene)."""
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant
    dut = builder.AddSystem(ForceTorqueSensor(plant, scene.sensor_joint))
    builder.Connect(plant.get_reaction_forces_output_port(), dut.get_input_port())
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, scene.arm, q)
    tau = -plant.CalcGravityGeneralizedForces(context)
    source = builder.AddSystem(ConstantVectorSource(tau))
    builder.Connect(source.get_output_port(), plant.get_applied_generalized_force_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    root = simulator.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(root), scene.arm, q)
    simulator.AdvanceTo(config.time_step)
    return dut.get_output_port().Eval(dut.GetMyContextFromRoot(root)), scene, context


@pytest.mark.parametrize("seed", range(4))
def test_static_pose_reads_weight_and_gravity_torque(seed):
    config = ideal_config()
    rng = np.random.default_rng(seed)
    q = np.asarray(config.home_q) + rng.uniform(-0.8, 0.8, 7) * (seed > 0)
    wrench, scene, context = static_reading(config, q)
    # Independent: mass and CoM from the model's inertias, orientation from kinematics.
    m, p_SoScm_S, _ = tool_inertia(scene.plant, context, scene.sensor_frame, scene.tool_bodies)
    R_WS = scene.sensor_frame.CalcPoseInWorld(context).rotation()
    weight_S = R_WS.inverse() @ (m * np.asarray(GRAVITY_W))
    expected = np.concatenate([weight_S, np.cross(p_SoScm_S, weight_S)])
    assert m == pytest.approx(1.5)
    np.testing.assert_allclose(wrench, expected, rtol=0, atol=1e-6 * np.linalg.norm(expected))
    # The force is the weight: magnitude m·g whatever the pose.
    assert np.linalg.norm(wrench[:3]) == pytest.approx(1.5 * 9.81, rel=1e-6)


@pytest.fixture(scope="module")
def free_motion():
    config = ideal_config("fourier", 4.0)
    config.trajectory.speed_fraction = 0.6
    sim = build_station(config)
    log = simulate(sim, progress=False).log
    return sim, log


def newton_euler_for_rows(sim, log, rows):
    """Newton–Euler wrench of the tool for log rows, at each step's start state."""
    plant = sim.scene.plant
    context = plant.CreateDefaultContext()
    m, p, I = tool_inertia(plant, context, sim.scene.sensor_frame, sim.scene.tool_bodies)
    q = log[col.joint_columns(col.Q)].to_numpy()
    v = log[col.joint_columns(col.QD)].to_numpy()
    vd = log[col.joint_columns(col.QDD)].to_numpy()
    kin = sensor_kinematics(
        plant, context, sim.scene.sensor_frame, q[rows - 1], v[rows - 1], vd[rows], sim.scene.arm
    )
    return newton_euler_wrench(m, p, I, kin), kin


def test_moving_sensor_equals_newton_euler(free_motion):
    sim, log = free_motion
    rows = np.arange(50, len(log), 37)
    expected, kin = newton_euler_for_rows(sim, log, rows)
    measured = log[col.wrench_columns(col.IDEAL)].to_numpy()[rows]
    # The motion must really be dynamic, or this would only re-test statics.
    inertial = np.abs(measured[:, :3] - 1.5 * kin.g_S).max()
    assert inertial > 0.1  # N of inertial force
    scale = np.abs(measured).max(axis=0)
    np.testing.assert_allclose(measured, expected, rtol=0, atol=1e-9 * scale.max())


def test_sampled_outputs_read_zero_before_first_step():
    config = ideal_config()
    sim = build_station(config)
    context = sim.diagram.CreateDefaultContext()
    wrench = sim.sensor.get_output_port().Eval(sim.sensor.GetMyContextFromRoot(context))
    np.testing.assert_array_equal(wrench, np.zeros(6))


@pytest.fixture(scope="module")
def contact_run():
    config = ideal_config("contact", 12.0)
    sim = build_station(config)
    log = simulate(sim, progress=False).log
    return sim, log


def test_contact_wrench_equals_ideal_minus_newton_euler(contact_run):
    sim, log = contact_run
    in_contact = np.flatnonzero(log[col.CONTACT_TRUE].to_numpy() == 1)
    assert len(in_contact) > 1000  # seconds of pressing at 1 kHz
    rows = in_contact[in_contact > 0][::25]
    newton_euler, _ = newton_euler_for_rows(sim, log, rows)
    ideal = log[col.wrench_columns(col.IDEAL)].to_numpy()[rows]
    external = log[col.wrench_columns(col.EXTERNAL_TRUE)].to_numpy()[rows]
    force = np.linalg.norm(external[:, :3], axis=1)
    assert 5.0 < np.median(force) < 50.0  # a realistic press
    # ContactTruth maps forces with the pose at sample k while the contact solve used the
    # configuration at k−1: while pressing that differs by < 1e-4 m, hence the tolerance.
    np.testing.assert_allclose(ideal - newton_euler, external, rtol=0, atol=0.01)


def test_contact_flag_matches_force(contact_run):
    _, log = contact_run
    force = np.linalg.norm(log[col.wrench_columns(col.EXTERNAL_TRUE)].to_numpy()[:, :3], axis=1)
    contact = log[col.CONTACT_TRUE].to_numpy() == 1
    assert not np.any(force[~contact] > 0)
    assert np.median(force[contact]) > 5.0
    # The tool presses once and leaves: one interval of contact, and truth clears after it.
    assert np.count_nonzero(np.diff(contact.astype(int)) == 1) == 1
    assert np.count_nonzero(np.diff(contact.astype(int)) == -1) == 1
    assert not contact[-500:].any() and not force[-500:].any()


def test_sensor_works_on_any_plant_weld():
    """A box hanging from the world by a weld, rotated: reads its weight in the weld frame."""
    plant = MultibodyPlant(1e-3)
    G_BoB = UnitInertia.SolidBox(0.1, 0.1, 0.1).ShiftFromCenterOfMass([-0.1, 0.0, 0.0])
    box = plant.AddRigidBody("box", SpatialInertia(2.0, [0.1, 0.0, 0.0], G_BoB))
    X_WJ = RigidTransform(RollPitchYaw(0.3, -0.2, 0.5), [0, 0, 1])
    joint = plant.WeldFrames(plant.world_frame(), box.body_frame(), X_WJ)
    plant.Finalize()
    builder = DiagramBuilder()
    builder.AddSystem(plant)
    dut = builder.AddSystem(ForceTorqueSensor(plant, joint))
    builder.Connect(plant.get_reaction_forces_output_port(), dut.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(1e-3)
    wrench = dut.get_output_port().Eval(dut.GetMyContextFromRoot(simulator.get_context()))
    weight_J = X_WJ.rotation().inverse() @ (2.0 * np.asarray(GRAVITY_W))
    np.testing.assert_allclose(wrench[:3], weight_J, atol=1e-9)
    np.testing.assert_allclose(wrench[3:], np.cross([0.1, 0, 0], weight_J), atol=1e-9)


def test_sensor_refuses_non_weld_joint():
    config = ideal_config()
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    with pytest.raises(TypeError, match="weld"):
        ForceTorqueSensor(scene.plant, scene.plant.GetJointByName("joint_t"))


def test_cable_force_is_read_by_the_sensor():
    """With the cable on: reading = tool Newton–Euler + cable force at its attachment point."""
    from ftdrake.sim.cable import cable_force_W

    config = ideal_config("fourier", 3.0)
    config.cable.enabled = True
    sim = build_station(config)
    log = simulate(sim, progress=False).log
    rows = np.arange(50, len(log), 41)
    newton_euler, _ = newton_euler_for_rows(sim, log, rows)
    plant, frame_S = sim.scene.plant, sim.scene.sensor_frame
    context = plant.CreateDefaultContext()
    q = log[col.joint_columns(col.Q)].to_numpy()
    v = log[col.joint_columns(col.QD)].to_numpy()
    cable = np.empty((len(rows), 6))
    for i, k in enumerate(rows):
        plant.SetPositions(context, sim.scene.arm, q[k - 1])
        plant.SetVelocities(context, sim.scene.arm, v[k - 1])
        f_W, p_WQ = cable_force_W(plant, context, sim.scene.cable, config.cable)
        X_WS = frame_S.CalcPoseInWorld(context)
        f_S = X_WS.rotation().inverse() @ f_W
        cable[i] = np.concatenate([f_S, np.cross(X_WS.inverse() @ p_WQ, f_S)])
    ideal = log[col.wrench_columns(col.IDEAL)].to_numpy()[rows]
    assert np.linalg.norm(cable[:, :3], axis=1).min() > 1.0  # N: the cable really pulls
    np.testing.assert_allclose(ideal, newton_euler + cable, rtol=0, atol=1e-3)


def test_wrench_conversions_follow_the_convention():
    from pydrake.multibody.math import SpatialForce

    from ftdrake.systems.ft_sensor import (
        _negated_wrench,
        spatial_force_from_wrench,
        wrench_from_spatial_force,
    )

    F = SpatialForce(tau=np.array([0.1, 0.2, 0.3]), f=np.array([1.0, 2.0, 3.0]))
    w = wrench_from_spatial_force(F)
    np.testing.assert_array_equal(w, [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])  # force first
    np.testing.assert_array_equal(spatial_force_from_wrench(w).get_coeffs(), F.get_coeffs())
    out = np.empty(6)
    _negated_wrench(F.get_coeffs(), out)  # the sensor's compiled form: −F as a wrench
    np.testing.assert_array_equal(out, -w)
