"""SensorGravity in motion (the payload tracker's regressor), against Drake's kinematics of S."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig
from ftdrake.physics.rigid_body import sensor_kinematics
from ftdrake.sim.scene import add_scene
from ftdrake.systems.events import SensorGravity


@pytest.fixture(scope="module")
def scene():
    return add_scene(DiagramBuilder(), ScenarioConfig())


def gravity_S(scene, frame, q, v, vdot):
    """The system's output for `frame` with the arm at (q, v, v̇), its inputs from the plant's
    own computations (body poses, spatial accelerations from v̇)."""
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
    dut.get_input_port_body_spatial_accelerations().FixValue(
        dut_context, plant.CalcSpatialAccelerationsFromVdot(context, full_vdot))
    return dut.get_output_port_gravity_S().Eval(dut_context), context


# The sensor frame (at its body's origin) and two frames away from their body's origin, where
# the α × p term and the neglected ω × (ω × p) term count.
FRAMES = ["ft_sensor_weld_child", "tool_tip", "ft_sensor_weld_parent"]


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("name", FRAMES)
def test_apparent_gravity_is_g_minus_the_acceleration_of_So_but_the_omega_term(scene, name,
                                                                               seed):
    frame = scene.plant.GetFrameByName(name)
    rng = np.random.default_rng(seed)
    q, v, vdot = rng.uniform(-1.5, 1.5, 7), rng.uniform(-2, 2, 7), rng.uniform(-8, 8, 7)
    got, context = gravity_S(scene, frame, q, v, vdot)
    kin = sensor_kinematics(scene.plant, context, frame, q, v, vdot, instance=scene.arm)
    # The documented approximation: ω×(ω×p_BoSo) is left out (the plant's port has no ω).
    X_BS = frame.GetFixedPoseInBodyFrame()
    p_S = X_BS.rotation().inverse() @ X_BS.translation()  # p_BoSo in S
    w = kin.w_WS_S[0]
    expected = kin.g_S[0] - kin.a_WSo_S[0] + np.cross(w, np.cross(w, p_S))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10)
    # At rest it is gravity rotated into S, nothing else.
    at_rest, _ = gravity_S(scene, frame, q, np.zeros(7), np.zeros(7))
    np.testing.assert_allclose(at_rest, kin.g_S[0], rtol=0, atol=1e-12)
    assert np.linalg.norm(got - at_rest) > 0.1  # the motion counts
