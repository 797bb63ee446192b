"""The new user's path, end to end, on an arm that is not ftdrake's.

A user has their own URDF (a 3-joint arm, a welded F/T sensor, a 0.9 kg gripper:
``tests/data/three_link_arm.urdf``) and their own Drake diagram (Drake's
InverseDynamicsController on its own model of the arm). With only ftdrake's public API they

1. record free motion from their diagram (``ftdrake.add_recorder``),
2. train a hybrid model (the gripper's physics from their URDF + a small residual forest),
3. save it, and load it from another folder after the URDF they trained with is gone
   (the model file went to the robot's computer),
4. put the runtime chain into their diagram and press on the gripper
   (an ExternallyAppliedSpatialForce of their own) — the press is detected, nothing before it,
5. replay the recorded loop offline (``ftdrake.replay``) and get the loop's numbers to 1e-12.
"""

import shutil

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

import ftdrake
from ftdrake.compensation.identification.payload_kinematics import kinematics_for
from tests.helpers import DATA, Press

URDF = DATA / "three_link_arm.urdf"
PERIOD = 1e-3  # s: the sensor's rate
MASS, COM = 0.9, np.array([12.0, -6.0, 65.0])  # kg, mm in S: the URDF's gripper
PRESS_N = np.array([0.0, 0.0, -6.0])  # N, world: a hand pressing down on the gripper
PRESS_START, PRESS_END = 3.0, 3.5  # s




def arm(time_step):
    plant = MultibodyPlant(time_step)
    Parser(plant).AddModels(str(URDF))  # the real robot: the URDF in the repository
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    return plant


def motion(seconds, seed):
    """Smooth multi-sine joint motion around a bent pose (rad), 0.05–0.3 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds + 0.01, 0.01)
    q = np.array([0.0, -0.6, 1.2])[:, None] + sum(
        rng.uniform(0.3, 0.6, (3, 1)) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3, (3, 1)))
        for f in (0.07, 0.13, 0.3))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        t, q, np.zeros((3, 1)), np.zeros((3, 1)))


def run_user_diagram(seconds, seed, model=None, press=False):
    """The user's diagram: plant, controller, their sensor (ftdrake's simulated one here),
    a recorder, and — with `model` — the runtime chain."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(arm(PERIOD))
    controller = builder.AddSystem(InverseDynamicsController(
        arm(0.0), np.full(3, 200.0), np.zeros(3), np.full(3, 30.0), False))
    q_d = motion(seconds, seed)
    desired = builder.AddSystem(TrajectorySource(q_d, output_derivative_order=1))
    builder.Connect(desired.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(plant.get_state_output_port(), controller.get_input_port_estimated_state())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port())
    if press:
        hand = builder.AddSystem(Press(plant.GetBodyByName("gripper"), PRESS_N, PRESS_START,
                                       PRESS_END))
        builder.Connect(hand.get_output_port(), plant.get_applied_spatial_force_input_port())
    ideal = builder.AddSystem(ftdrake.ForceTorqueSensor(
        plant, plant.GetJointByName("ft_sensor_weld")))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    ideal.get_input_port_reaction_forces())
    sensor = builder.AddSystem(ftdrake.NoisyForceTorqueSensor(ftdrake.SensorConfig(seed=seed)))
    builder.Connect(ideal.get_output_port_wrench(), sensor.get_input_port_wrench_ideal())
    chain = None
    if model is not None:
        chain = builder.AddSystem(ftdrake.CompensationChain(model, ftdrake.ChainConfig(),
                                                            period=PERIOD, n_joints=3))
        builder.Connect(sensor.get_output_port_wrench_measured(),
                        chain.get_input_port_wrench_measured())
        builder.Connect(plant.get_state_output_port(), chain.get_input_port_joint_state())
    recorder = ftdrake.add_recorder(builder, joint_state=plant.get_state_output_port(),
                                    wrench=sensor.get_output_port_wrench_measured(),
                                    period=PERIOD, chain=chain)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context), q_d.value(0.0).ravel())
    if chain is not None:
        chain.initialize(context)
    simulator.AdvanceTo(seconds)
    return recorder.to_frame(simulator.get_context())


@pytest.fixture(scope="module")
def recorded():
    return run_user_diagram(8.0, seed=1)


def test_record_train_ship_load_detect_replay(recorded, tmp_path, monkeypatch):
    # 1. The recording: the layout train reads, one row per sample.
    assert len(recorded) == 8000

    # 2. Train the hybrid on the user's URDF (a copy in their own folder).
    mine = tmp_path / "my_robot"
    mine.mkdir()
    shutil.copy(URDF, mine / "arm.urdf")
    physics = ftdrake.PhysicsPayloadCompensator(features="q,qd,qdd", robot=str(mine / "arm.urdf"),
                                                sensor_frame="gripper", base_frame="base")
    residual = ftdrake.RandomForestCompensator(features="q", per_output=False, n_estimators=10,
                                               min_samples_leaf=20, random_state=0)
    model = ftdrake.HybridCompensator(physics=physics, residual=residual)
    model.fit(ftdrake.joint_state_layout(recorded), ftdrake.wrench_targets(recorded))
    assert model.identified()["m"]["value"] == pytest.approx(MASS, rel=0.03)
    np.testing.assert_allclose(np.asarray(model.identified()["com"]["value"]) * 1e3, COM,
                               atol=15.0)  # mm

    # 3. Save; the URDF goes away; load from another folder.
    path = ftdrake.save_model(model, tmp_path / "shipped" / "arm_hybrid.ftd",
                              target_names=ftdrake.WRENCH_AXES,
                              target_units=ftdrake.WRENCH_UNITS)
    shutil.rmtree(mine)
    # The robot's computer is another process: nothing of the training's robot is cached.
    kinematics_for.cache_clear()
    elsewhere = tmp_path / "robot_computer"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    loaded = ftdrake.load_model(path, expect_n_joints=3)
    X = ftdrake.joint_state_layout(recorded)[:200]
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))

    # 4. The chain in the user's diagram: quiet in free motion, the press detected.
    loop = run_user_diagram(4.0, seed=2, model=loaded, press=True)
    t, detected = loop["t"].to_numpy(), loop["contact"].to_numpy() > 0
    assert not detected[t < PRESS_START].any(), "a false contact before the press"
    during = detected[(t >= PRESS_START) & (t < PRESS_END)]
    assert during.any(), "the press was not detected"
    first = t[(t >= PRESS_START) & detected][0]
    assert first - PRESS_START < 0.02  # s
    # What the chain saw of the press: ≈ the press's force, turned into S (|F| = 6 N).
    force = np.linalg.norm(loop.loc[(t > PRESS_START + 0.1) & (t < PRESS_END),
                                    [f"wrench_contact_F{a}" for a in "xyz"]].to_numpy(), axis=1)
    assert np.median(force) == pytest.approx(np.linalg.norm(PRESS_N), abs=1.0)

    # 5. The recorded loop replayed offline equals the loop.
    replayed = ftdrake.replay(loaded, loop, pairing="simulated")
    columns = [c for c in replayed.columns if c != "t"]
    assert {"wrench_internal_Fz", "wrench_contact_Fz", "wrench_std_Fz", "out_of_domain",
            "contact"} <= set(columns)
    np.testing.assert_allclose(replayed[columns].to_numpy(float), loop[columns].to_numpy(float),
                               rtol=0, atol=1e-12)
