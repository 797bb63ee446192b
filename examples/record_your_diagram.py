"""Record your own Drake diagram in the layout ftdrake trains on, train, and check the loop.

Your diagram: a MultibodyPlant from your robot's URDF (here a 3-joint arm with a welded F/T
sensor and a 0.9 kg gripper, ``tests/data/three_link_arm.urdf``), your controller (Drake's
InverseDynamicsController on its own model of the arm), and your sensor's reading (simulated
here with ftdrake's ForceTorqueSensor + NoisyForceTorqueSensor). ftdrake adds a recorder:

    recorder = ftdrake.add_recorder(builder, joint_state=..., wrench=..., period=0.001)
    ...simulate...
    log = recorder.to_frame(context)    # t, q_i, qd_i, qd_est_i, qdd_est_i, meas_*, ...

``qdd_est`` is the loop's own q̈ estimate, so ``joint_state_layout(log)`` is what the
compensator will see at run time. The example then

1. records free motion and identifies the gripper on it (the physics model, from the
   URDF's kinematics),
2. puts the trained model's runtime chain into the same diagram, records new motion with
   the chain's outputs, and
3. replays that log offline (``ftdrake.replay``), which gives the loop's numbers.

Run:  python examples/record_your_diagram.py [--urdf FILE] [--seconds 12] [--out DIR]
Prints one JSON line: rows recorded, the free-motion residual over the sensor's noise, the
largest difference between the replay and the loop, samples flagged in contact.
"""

import argparse
import json
from pathlib import Path

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

import ftdrake

URDF = Path(__file__).resolve().parents[1] / "tests" / "data" / "three_link_arm.urdf"
PERIOD = 1e-3  # s: the sensor's rate, 1 kHz
SENSOR_WELD = "ft_sensor_weld"


def arm(urdf: Path, time_step: float) -> MultibodyPlant:
    """The arm from its URDF, base welded to the world."""
    plant = MultibodyPlant(time_step)
    Parser(plant).AddModels(str(urdf))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    return plant


def motion(n: int, seconds: float, seed: int) -> PiecewisePolynomial:
    """Smooth multi-sine joint motion around a bent pose (rad)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds + 0.01, 0.01)
    home = np.array([0.0, -0.6, 1.2])[:n]
    q = home[:, None] + sum(
        rng.uniform(0.2, 0.5, (n, 1)) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3, (n, 1)))
        for f in (0.05, 0.09, 0.14))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        t, q, np.zeros((n, 1)), np.zeros((n, 1)))


def record(urdf: Path, seconds: float, seed: int, model=None):
    """Your diagram, with a recorder (and the runtime chain of `model`, when given)."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(arm(urdf, PERIOD))
    n = plant.num_positions()
    controller = builder.AddSystem(InverseDynamicsController(
        arm(urdf, 0.0), np.full(n, 200.0), np.zeros(n), np.full(n, 30.0), False))
    q_d = motion(n, seconds, seed)
    desired = builder.AddSystem(TrajectorySource(q_d, output_derivative_order=1))
    builder.Connect(desired.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(plant.get_state_output_port(), controller.get_input_port_estimated_state())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port())
    ideal = builder.AddSystem(ftdrake.ForceTorqueSensor(plant, plant.GetJointByName(SENSOR_WELD)))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    ideal.get_input_port_reaction_forces())
    sensor = builder.AddSystem(ftdrake.NoisyForceTorqueSensor(ftdrake.SensorConfig(seed=seed)))
    builder.Connect(ideal.get_output_port_wrench(), sensor.get_input_port_wrench_ideal())
    reading = sensor.get_output_port_wrench_measured()

    chain = None
    if model is not None:  # the runtime chain in the loop, as in compensate_in_your_diagram
        chain = builder.AddSystem(ftdrake.CompensationChain(model, ftdrake.ChainConfig(),
                                                            period=PERIOD, n_joints=n))
        builder.Connect(reading, chain.get_input_port_wrench_measured())
        builder.Connect(plant.get_state_output_port(), chain.get_input_port_joint_state())
    recorder = ftdrake.add_recorder(builder, joint_state=plant.get_state_output_port(),
                                    wrench=reading, period=PERIOD, chain=chain,
                                    temperature=sensor.get_output_port_temperature())
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.SetPositions(plant_context, q_d.value(0.0).ravel())
    if chain is not None:
        chain.initialize(context)
    simulator.AdvanceTo(seconds)
    return recorder.to_frame(simulator.get_context())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urdf", type=Path, default=URDF)
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--out", type=Path, default=Path("out/record_your_diagram"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    # 1. Record free motion, train on it (the layout's [q, q̇, loop's q̈] and the reading).
    log = record(args.urdf, args.seconds, seed=1)
    log.to_parquet(args.out / "recorded.parquet")
    # The physics model on your robot's own description: the gripper's mass, centre of
    # mass and inertia (and the sensor's biases) by least squares.
    model = ftdrake.PhysicsPayloadCompensator(features="q,qd,qdd", robot=str(args.urdf),
                                              sensor_frame="gripper", base_frame="base")
    model.fit(ftdrake.joint_state_layout(log), ftdrake.wrench_targets(log))
    path = ftdrake.save_model(model, args.out / "model.ftd", target_names=ftdrake.WRENCH_AXES,
                              target_units=ftdrake.WRENCH_UNITS)

    # 2. New motion with the trained chain in the loop; 3. the same stream replayed offline.
    model = ftdrake.load_model(path)
    loop = record(args.urdf, args.seconds / 2, seed=2, model=model)
    replayed = ftdrake.replay(model, loop, pairing="simulated")
    columns = [c for c in replayed.columns if c != "t"]
    noise = np.asarray(ftdrake.SensorConfig().spec().noise_std)
    residual = loop[[f"wrench_contact_{a}" for a in ftdrake.WRENCH_AXES]].to_numpy()[500:]
    print(json.dumps({
        "rows_recorded": len(log),
        "mass_kg": round(model.parameters_[0], 4),  # the gripper: 0.9 kg
        "com_mm": np.round(np.asarray(model.identified()["com"]["value"]) * 1e3, 1).tolist(),
        "columns": list(log.columns[:1 + 4 * 3]),
        "free_motion_residual_over_noise": np.round(
            np.sqrt(np.mean(residual**2, axis=0)) / noise, 2).tolist(),
        "replay_minus_loop_max": float(np.max(np.abs(
            replayed[columns].to_numpy(float) - loop[columns].to_numpy(float)))),
        "contact_samples": int(loop["contact"].sum()),
    }))


if __name__ == "__main__":
    main()
