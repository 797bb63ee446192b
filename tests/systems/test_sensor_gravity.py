"""SensorGravity in motion (the payload tracker's regressor): g − a_So and S's ω, α against
Drake's kinematics of S (Jacobian and bias acceleration, and the frame's own spatial
velocity)."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig
from ftdrake.physics.rigid_body import sensor_kinematics
from ftdrake.sim.scene import add_scene
from ftdrake.systems.sensor_gravity import SensorGravity


@pytest.fixture(scope="module")
def scene():
    return add_scene(DiagramBuilder(), ScenarioConfig())


def gravity_S(scene, frame, q, v, vdot, port="gravity_S"):
    """The system's output `port` for `frame` with the arm at (q, v, v̇), its inputs from the
    plant's own computations (body poses and spatial velocities, spatial accelerations from
    v̇)."""
    plant, arm = scene.plant, scene.arm
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, arm, q)
    plant.SetVelocities(context, arm, v)
    full_vdot = np.zeros(plant.num_velocities())
    plant.SetVelocitiesInArray(arm, vdot, full_vdot)
    dut = SensorGravity(plant, frame)
    dut_context = dut.CreateDefaultContext()
    dut.get_input_port_body_poses().FixValue(
        dut_context, plant.get_body_poses_output_port().Eval(context))
    dut.get_input_port_body_spatial_velocities().FixValue(
        dut_context, plant.get_body_spatial_velocities_output_port().Eval(context))
    dut.get_input_port_body_spatial_accelerations().FixValue(
        dut_context, plant.CalcSpatialAccelerationsFromVdot(context, full_vdot))
    return dut.GetOutputPort(port).Eval(dut_context).copy(), context


# The sensor frame (at its body's origin) and two frames away from their body's origin, where
# the α × p and ω × (ω × p) terms of the shift to So count.
FRAMES = ["ft_sensor_weld_child", "tool_tip", "ft_sensor_weld_parent"]


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("name", FRAMES)
def test_apparent_gravity_is_g_minus_the_acceleration_of_So(scene, name, seed):
    frame = scene.plant.GetFrameByName(name)
    rng = np.random.default_rng(seed)
    q, v, vdot = rng.uniform(-1.5, 1.5, 7), rng.uniform(-2, 2, 7), rng.uniform(-8, 8, 7)
    got, context = gravity_S(scene, frame, q, v, vdot)
    kin = sensor_kinematics(scene.plant, context, frame, q, v, vdot, instance=scene.arm)
    np.testing.assert_allclose(got, kin.g_S[0] - kin.a_WSo_S[0], rtol=0, atol=1e-10)
    # At rest it is gravity rotated into S, nothing else.
    at_rest, _ = gravity_S(scene, frame, q, np.zeros(7), np.zeros(7))
    np.testing.assert_allclose(at_rest, kin.g_S[0], rtol=0, atol=1e-12)
    assert np.linalg.norm(got - at_rest) > 0.1  # the motion counts
    if name != "ft_sensor_weld_child":  # ω × (ω × p_BoSo) is in it (p of a few cm)
        X_BS = frame.GetFixedPoseInBodyFrame()
        p_S = X_BS.rotation().inverse() @ X_BS.translation()
        w = kin.w_WS_S[0]
        assert np.linalg.norm(np.cross(w, np.cross(w, p_S))) > 1e-3


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("name", FRAMES)
def test_motion_is_the_angular_velocity_and_acceleration_of_S_in_S(scene, name, seed):
    frame = scene.plant.GetFrameByName(name)
    rng = np.random.default_rng(10 + seed)
    q, v, vdot = rng.uniform(-1.5, 1.5, 7), rng.uniform(-2, 2, 7), rng.uniform(-8, 8, 7)
    got, context = gravity_S(scene, frame, q, v, vdot, port="motion_S")
    # ω straight from the frame's spatial velocity; α from S's Jacobian and bias acceleration.
    R_WS = frame.CalcPoseInWorld(context).rotation()
    w_S = R_WS.inverse() @ frame.CalcSpatialVelocityInWorld(context).rotational()
    kin = sensor_kinematics(scene.plant, context, frame, q, v, vdot, instance=scene.arm)
    np.testing.assert_allclose(got[:3], w_S, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[3:], kin.alpha_WS_S[0], rtol=0, atol=1e-10)
    assert np.linalg.norm(got[:3]) > 0.5 and np.linalg.norm(got[3:]) > 1.0
    at_rest, _ = gravity_S(scene, frame, q, np.zeros(7), np.zeros(7), port="motion_S")
    np.testing.assert_array_equal(at_rest, np.zeros(6))


def test_without_acceleration_only_the_poses_are_read(scene):
    plant, frame = scene.plant, scene.sensor_frame
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, scene.arm, np.linspace(-1.0, 1.0, 7))
    dut = SensorGravity(plant, frame, include_acceleration=False)
    assert dut.num_input_ports() == 1
    dut_context = dut.CreateDefaultContext()
    dut.get_input_port_body_poses().FixValue(
        dut_context, plant.get_body_poses_output_port().Eval(context))
    R_WS = frame.CalcPoseInWorld(context).rotation()
    np.testing.assert_allclose(dut.get_output_port_gravity_S().Eval(dut_context),
                               R_WS.inverse() @ plant.gravity_field().gravity_vector(),
                               atol=1e-12)
    np.testing.assert_array_equal(dut.get_output_port_motion_S().Eval(dut_context), np.zeros(6))
