"""Put a trained ftdrake compensator and contact detector into your own Drake diagram.

Your diagram has a robot (here: a plant built from ftdrake's models, but any MultibodyPlant
with a weld for the sensor works), a source of F/T readings, and the robot's joint state.
ftdrake adds one system, the runtime chain (compensator → bias tracker → contact detector):

    wrench_measured ──► CompensationChain ──► wrench_contact, contact, contact_force, ...
    joint_state ──────►

Run:  python examples/compensate_in_your_diagram.py [--model MODEL.ftd]
Without --model it trains a small forest first (a few seconds of simulated data).
"""

import argparse
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput

import ftdrake


def train_small_model(path: Path) -> Path:
    data = ftdrake.collect(ftdrake.ScenarioConfig(), 2, kind="fourier", duration=5.0,
                           progress=False)
    model = ftdrake.RandomForestCompensator(features="q", n_estimators=20, per_output=False)
    model.fit(ftdrake.joint_state_layout(data), ftdrake.wrench_targets(data))
    return ftdrake.save_model(model, path, target_names=ftdrake.WRENCH_AXES,
                              target_units=ftdrake.WRENCH_UNITS, sensor_frame="S")


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--model", type=Path)
    args = parser.parse_args()
    model_path = args.model or train_small_model(Path("out/example_model.ftd"))

    # --- your diagram --------------------------------------------------------------------
    builder = DiagramBuilder()
    scene = ftdrake.add_scene(builder, ftdrake.ScenarioConfig())  # or your own plant
    plant = scene.plant
    ideal = builder.AddSystem(ftdrake.ForceTorqueSensor(plant, scene.sensor_joint))
    builder.Connect(plant.get_reaction_forces_output_port(), ideal.GetInputPort("reaction_forces"))
    # Your sensor's readings (simulated here with the same sensor the model was trained on).
    sensor = builder.AddSystem(ftdrake.NoisyForceTorqueSensor(ftdrake.SensorConfig(seed=42)))
    builder.Connect(ideal.GetOutputPort("wrench"), sensor.GetInputPort("wrench_ideal"))
    # Your controller: here inverse dynamics holding the arm at its home pose.
    config = ftdrake.ScenarioConfig()
    home, n = np.asarray(config.home_q), plant.num_positions(scene.arm)
    controller = builder.AddSystem(InverseDynamicsController(
        ftdrake.make_control_plant(config, scene), np.full(n, 400.0), np.zeros(n), np.full(n, 40.0),
        False))
    target = builder.AddSystem(ConstantVectorSource(np.concatenate([home, np.zeros(n)])))
    builder.Connect(target.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(plant.get_state_output_port(scene.arm),
                    controller.get_input_port_estimated_state())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port(scene.arm))

    # --- ftdrake's runtime chain, from a saved model ---------------------------------------
    model = ftdrake.load_model(model_path, expect_n_joints=n)
    chain = builder.AddSystem(ftdrake.CompensationChain(model, config.chain_config()))
    builder.Connect(sensor.get_output_port_wrench_measured(),
                    chain.get_input_port_wrench_measured())
    builder.Connect(plant.get_state_output_port(scene.arm), chain.get_input_port_joint_state())

    period = chain.period  # s: the sensor's rate in config.sensor
    external = LogVectorOutput(chain.get_output_port_wrench_contact(), builder, period)
    contact = LogVectorOutput(chain.get_output_port_contact(), builder, period)

    simulator = Simulator(builder.Build())
    plant.SetPositions(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                       scene.arm, home)
    simulator.AdvanceTo(0.5)
    root = simulator.get_context()
    w = external.FindLog(root).data()[:, -1]
    print(f"contact wrench at rest (should be near zero): {np.round(w, 3)}")
    print(f"contact detected: {bool(contact.FindLog(root).data()[0, -1])}")


if __name__ == "__main__":
    main()
