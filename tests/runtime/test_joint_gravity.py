"""JointStateGravity (the hardware station's gravity at the sensor) against Drake's kinematics."""

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator

from ftdrake import ScenarioConfig
from ftdrake.physics.chain import SerialChain
from ftdrake.physics.scenario_robot import robot_description
from ftdrake.runtime.joint_gravity import JointStateGravity

PERIOD = 0.001


@pytest.fixture(scope="module")
def robot():
    plant, frame_S = robot_description(ScenarioConfig().models).build_plant()
    return plant, frame_S, SerialChain.from_plant(plant, frame_S)


def drake_apparent_gravity(plant, frame_S, q, v):
    """g_S − a_So_S with q̈ = 0 (the bias acceleration), from Drake's own kinematics."""
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    plant.SetVelocities(context, v)
    R_WS = frame_S.CalcPoseInWorld(context).rotation()
    A_bias = plant.CalcBiasSpatialAcceleration(context, JacobianWrtVariable.kV, frame_S,
                                               np.zeros(3), plant.world_frame(),
                                               plant.world_frame())
    g_W = plant.gravity_field().gravity_vector()
    return R_WS.inverse() @ (g_W - A_bias.translational())


@pytest.mark.parametrize("include_acceleration", [True, False])
def test_constant_joint_velocities_give_drakes_gravity_minus_bias_acceleration(
        robot, include_acceleration):
    plant, frame_S, chain = robot
    rng = np.random.default_rng(4)
    q0, v = rng.uniform(-1.5, 1.5, 7), rng.uniform(-0.8, 0.8, 7)
    dut = JointStateGravity(chain, PERIOD, include_acceleration=include_acceleration)
    simulator = Simulator(dut)
    context = simulator.get_mutable_context()
    port = dut.get_input_port_joint_state().FixValue(context, np.r_[q0, v])
    steps = 20
    for k in range(steps):  # constant v: the causal q̈ estimate is exactly 0 once primed
        port.GetMutableData().get_mutable_value().SetFromVector(np.r_[q0 + v * k * PERIOD, v])
        simulator.AdvanceTo((k + 0.5) * PERIOD)
    q_last = q0 + v * (steps - 1) * PERIOD
    expected = (drake_apparent_gravity(plant, frame_S, q_last, v) if include_acceleration
                else drake_apparent_gravity(plant, frame_S, q_last, 0 * v))
    got = dut.get_output_port_gravity_S().Eval(context)
    np.testing.assert_allclose(got, expected, atol=1e-9)
    if include_acceleration:  # the centripetal part is really there
        static = drake_apparent_gravity(plant, frame_S, q_last, 0 * v)
        assert np.linalg.norm(expected - static) > 0.05


def test_a_nan_joint_state_keeps_the_last_value(robot):
    _, _, chain = robot
    dut = JointStateGravity(chain, PERIOD)
    simulator = Simulator(dut)
    context = simulator.get_mutable_context()
    port = dut.get_input_port_joint_state().FixValue(context, np.zeros(14))
    simulator.AdvanceTo(0.5 * PERIOD)
    before = dut.get_output_port_gravity_S().Eval(context).copy()
    port.GetMutableData().get_mutable_value().SetFromVector(np.full(14, np.nan))
    simulator.AdvanceTo(1.5 * PERIOD)
    np.testing.assert_array_equal(dut.get_output_port_gravity_S().Eval(context), before)
    assert np.linalg.norm(before) == pytest.approx(9.81, rel=1e-9)


def drake_motion(plant, frame_S, q, v, vdot):
    """[ω_WS_S; α_WS_S] and g_S − a_So_S at (q, v, v̇) from Drake: the frame's spatial
    velocity, and its Jacobian times v̇ plus the bias acceleration."""
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    plant.SetVelocities(context, v)
    W = plant.world_frame()
    R_SW = frame_S.CalcPoseInWorld(context).rotation().inverse()
    J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, frame_S, np.zeros(3),
                                          W, W)
    bias = plant.CalcBiasSpatialAcceleration(context, JacobianWrtVariable.kV, frame_S,
                                             np.zeros(3), W, W)
    A = J @ vdot + np.r_[bias.rotational(), bias.translational()]
    w = R_SW @ frame_S.CalcSpatialVelocityInWorld(context).rotational()
    g_S = R_SW @ (plant.gravity_field().gravity_vector() - A[3:])
    return np.r_[w, R_SW @ A[:3]], g_S


@pytest.mark.parametrize("include_acceleration", [True, False])
def test_motion_is_drakes_angular_velocity_and_acceleration_of_S(robot, include_acceleration):
    """Constant q̈: the loop's causal q̈ estimate converges to it (to round-off within the
    run, at the default cut-off), so ω, α (and g − a_So) must be Drake's at the last sample."""
    plant, frame_S, chain = robot
    rng = np.random.default_rng(7)
    q0, v0, a = rng.uniform(-1.5, 1.5, 7), rng.uniform(-0.8, 0.8, 7), rng.uniform(-3, 3, 7)
    dut = JointStateGravity(chain, PERIOD, include_acceleration=include_acceleration)
    simulator = Simulator(dut)
    context = simulator.get_mutable_context()
    port = dut.get_input_port_joint_state().FixValue(context, np.r_[q0, v0])
    steps = 300
    for k in range(steps):
        t = k * PERIOD
        port.GetMutableData().get_mutable_value().SetFromVector(
            np.r_[q0 + v0 * t + 0.5 * a * t**2, v0 + a * t])
        simulator.AdvanceTo((k + 0.5) * PERIOD)
    t = (steps - 1) * PERIOD
    q, v = q0 + v0 * t + 0.5 * a * t**2, v0 + a * t
    got = dut.get_output_port_motion_S().Eval(context)
    motion, g_S = drake_motion(plant, frame_S, q, v, a)
    if not include_acceleration:
        np.testing.assert_array_equal(got, np.zeros(6))
        return
    np.testing.assert_allclose(got[:3], motion[:3], atol=1e-10)
    np.testing.assert_allclose(got[3:], motion[3:], atol=1e-8)
    np.testing.assert_allclose(dut.get_output_port_gravity_S().Eval(context), g_S, atol=1e-8)
    assert np.linalg.norm(motion[3:]) > 1.0  # α is really there
    # and q̈ counts in it: at q̈ = 0 the angular acceleration differs
    assert np.linalg.norm(drake_motion(plant, frame_S, q, v, 0 * a)[0][3:] - motion[3:]) > 0.5
