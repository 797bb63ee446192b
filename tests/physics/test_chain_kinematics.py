"""The compiled serial chain against Drake's Jacobians (``sensor_kinematics``), to 1e-12."""


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from pydrake.systems.framework import DiagramBuilder

from ftdrake.config import ScenarioConfig
from ftdrake.errors import RobotModelError
from ftdrake.physics.chain import SerialChain, sensor_kinematics_row
from ftdrake.physics.rigid_body import sensor_kinematics
from ftdrake.physics.robot import RobotDescription, ftdrake_arm
from ftdrake.sim.scene import add_scene
from tests.helpers import DATA

USER_URDF = DATA / "prismatic_arm.urdf"  # 5 joints on the path (one prismatic), 1 off it
FIELDS = ("R_WS", "w_WS_S", "alpha_WS_S", "a_WSo_S", "g_S")
TOL = 1e-12
GRAVITY = np.array([0.0, 0.0, -9.81])  # sensor_kinematics' gravity


def assert_same_kinematics(got, expected):
    """Every field equal to 1e-12, relative to the field's scale (absolute below 1)."""
    for name in FIELDS:
        a, b = getattr(got, name), getattr(expected, name)
        scale = max(1.0, np.abs(b).max())
        np.testing.assert_allclose(a, b, rtol=0, atol=TOL * scale, err_msg=name)


def rows(n_joints, n_rows=3, q_range=np.pi):
    """Hypothesis rows of q, v, v̇ of a joint count: |q| ≤ q_range, |v| ≤ 3, |v̇| ≤ 20."""
    def block(bound):
        return arrays(np.float64, (n_rows, n_joints),
                      elements=st.floats(-bound, bound, allow_nan=False))
    return st.tuples(block(q_range), block(3.0), block(20.0))


@pytest.fixture(scope="module")
def scene():
    return add_scene(DiagramBuilder(), ScenarioConfig())


@pytest.fixture(scope="module")
def user_robot():
    plant, frame_S = RobotDescription(str(USER_URDF), "ft_sensor").build_plant()
    return plant, plant.CreateDefaultContext(), frame_S


@settings(max_examples=60, deadline=None)
@given(state=rows(7))
def test_ftdrake_arm_matches_drake(scene, state):
    q, v, vdot = state
    plant, frame_S = scene.plant, scene.sensor_frame
    dut = SerialChain.from_plant(plant, frame_S, scene.arm)
    expected = sensor_kinematics(plant, plant.CreateDefaultContext(), frame_S, q, v, vdot,
                                 scene.arm)
    assert_same_kinematics(dut.evaluate(q, v, vdot, GRAVITY), expected)


def test_ftdrake_arm_chain_is_the_arm_and_the_welds(scene):
    dut = SerialChain.from_plant(scene.plant, scene.sensor_frame, scene.arm)
    assert [j.name for j in dut.joints] == [
        "world_welds_to_arm_base", "joint_s", "joint_l", "joint_e", "joint_u", "joint_r",
        "joint_b", "joint_t", "flange_welds_to_ft_sensor", "ft_sensor_weld"]
    assert dut.num_moving_joints == 7 and list(dut.q_index) == list(range(7))


@settings(max_examples=60, deadline=None)
@given(state=rows(6), slide=st.floats(-0.5, 0.5))
def test_user_urdf_with_a_prismatic_joint_matches_drake(user_robot, state, slide):
    plant, context, frame_S = user_robot
    q, v, vdot = state
    j2 = plant.GetJointByName("j2_slide")
    q[:, j2.position_start()] = slide  # the slider within its travel (m)
    dut = SerialChain.from_plant(plant, frame_S)
    expected = sensor_kinematics(plant, context, frame_S, q, v, vdot)
    assert_same_kinematics(dut.evaluate(q, v, vdot, GRAVITY), expected)


def test_user_urdf_chain(user_robot):
    plant, _, frame_S = user_robot
    dut = SerialChain.from_plant(plant, frame_S)
    types = {j.name: j.type for j in dut.joints}
    assert types == {"world_joint": "weld", "j1": "revolute", "j2_slide": "prismatic",
                     "j3": "revolute", "j4": "revolute", "j5": "revolute"}  # no camera_mount
    for j in dut.joints[1:]:  # each joint's coordinate where Drake keeps it
        assert j.q_index == plant.GetJointByName(j.name).position_start()
    # S is off its body's origin and rotated: X_BS is kept.
    np.testing.assert_allclose(dut.X_BS, frame_S.GetFixedPoseInBodyFrame().GetAsMatrix4())


def test_gravity_is_the_given_one(user_robot):
    plant, context, frame_S = user_robot
    dut = SerialChain.from_plant(plant, frame_S)
    q = np.random.default_rng(0).uniform(-1, 1, (4, 6))
    got = dut.evaluate(q, 0 * q, 0 * q, gravity_W=(1.0, -2.0, 3.0))
    R_WS = sensor_kinematics(plant, context, frame_S, q, 0 * q, 0 * q).R_WS
    np.testing.assert_allclose(got.g_S, np.einsum("nji,j->ni", R_WS, [1.0, -2.0, 3.0]),
                               rtol=0, atol=TOL * 4)


def test_row_kernel_equals_batch(user_robot):
    plant, _, frame_S = user_robot
    dut = SerialChain.from_plant(plant, frame_S)
    q, v, vdot = np.random.default_rng(1).uniform(-2, 2, (3, 5, 6))
    batch = dut.evaluate(q, v, vdot, GRAVITY)
    R, out = np.empty((3, 3)), np.empty((4, 3))
    sensor_kinematics_row(q[2], v[2], vdot[2], GRAVITY, *dut.kernel_args(), R, out)
    np.testing.assert_array_equal(R, batch.R_WS[2])
    np.testing.assert_array_equal(out[1], batch.alpha_WS_S[2])


def test_rows_of_the_wrong_size_are_refused(user_robot):
    plant, _, frame_S = user_robot
    dut = SerialChain.from_plant(plant, frame_S)
    with pytest.raises(ValueError, match="6, 6, 6 columns"):
        dut.evaluate(np.zeros((2, 7)), np.zeros((2, 6)), np.zeros((2, 6)))


def test_floating_base_gives_a_clear_error(tmp_path):
    text = USER_URDF.read_text()
    start, end = text.index('<joint name="world_joint"'), text.index("</joint>") + len("</joint>")
    floating = tmp_path / "floating_arm.urdf"
    floating.write_text(text[:start] + text[end:])  # no world joint: the base floats
    plant, frame_S = RobotDescription(str(floating), "ft_sensor").build_plant()
    with pytest.raises(RobotModelError, match=r"is a quaternion_floating joint.*floating"):
        SerialChain.from_plant(plant, frame_S)


def test_path_outside_the_rows_instance_gives_a_clear_error(scene):
    # Rows of the tool's (empty) q cannot drive the arm's joints.
    with pytest.raises(RobotModelError, match=r"'joint_s' .* not in model instance"):
        SerialChain.from_plant(scene.plant, scene.sensor_frame, scene.tool)


def test_shipped_description_has_the_scenes_kinematics(scene):
    """ftdrake_arm() (what robot=None means) describes the simulated arm exactly."""
    plant, frame_S = ftdrake_arm().build_plant()
    assert frame_S.name() == scene.sensor_frame.name()
    q, v, vdot = np.random.default_rng(2).uniform(-3, 3, (3, 20, 7))
    got = SerialChain.from_plant(plant, frame_S).evaluate(q, v, vdot, GRAVITY)
    expected = sensor_kinematics(scene.plant, scene.plant.CreateDefaultContext(),
                                 scene.sensor_frame, q, v, vdot, scene.arm)
    assert_same_kinematics(got, expected)


def test_user_urdf_without_the_sensor_frame_names_it():
    with pytest.raises(RobotModelError, match="has no sensor frame named 'wrist_ft'"):
        RobotDescription(str(USER_URDF), "wrist_ft").build_plant()
