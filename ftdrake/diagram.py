"""The whole block diagram on one screen: start here.

    trajectory ──► inverse-dynamics controller ──► plant ──► reaction forces ──► F/T sensor
        (q_d, v_d, v̇_d)     (nominal tool model)      │                          │ wrench_ideal
                                                      │◄── cable (spring + weight)          ▼
                                                      ├──► contact truth    noisy sensor
                                                      └──► loggers ◄──────── wrench_measured

The compensator and contact detector (ftdrake.systems) are added by
:func:`ftdrake.closed_loop.add_compensation` on top of this.
"""

from __future__ import annotations

import dataclasses as dc

from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    LogVectorOutput,
    TrajectorySource,
    VectorLogSink,
)

from .config import ScenarioConfig
from .controller import DiscreteInverseDynamicsController
from .scene import Scene, add_scene, make_control_plant
from .sensor import ForceTorqueSensor, NoisyForceTorqueSensor
from .trajectories import JointLimits, RobotGeometry, make_trajectory
from .truth import ContactTruth


@dc.dataclass
class Loggers:
    """Loggers sampled at the sensor rate. Each holds one signal's time series."""

    state: VectorLogSink  # arm q (rad), v (rad/s)
    acceleration: VectorLogSink  # arm v̇ (rad/s²), from the plant's step
    ideal: VectorLogSink  # ideal sensor wrench (N, N·m; S)
    measured: VectorLogSink  # noisy sensor wrench
    saturated: VectorLogSink
    external: VectorLogSink  # true contact wrench at the sensor
    contact: VectorLogSink  # true contact flag


@dc.dataclass
class Simulation:
    """A built diagram with handles to the parts users and tests need."""

    config: ScenarioConfig
    diagram: Diagram
    scene: Scene
    trajectory: object  # PiecewisePolynomial q(t)
    sensor: ForceTorqueSensor
    noisy_sensor: NoisyForceTorqueSensor
    truth: ContactTruth
    loggers: Loggers
    builder_extras: dict = dc.field(default_factory=dict)
    simulator: object = None  # the Simulator of the last `simulation.run` (its context holds logs)


def build_diagram(config: ScenarioConfig, *, trajectory=None, extra=None, meshcat=None) -> Simulation:
    """Builds the simulated arm, sensor and environment for `config`.

    `trajectory` overrides the one `config.trajectory` describes. `extra(builder, sim_parts)`
    may add systems (e.g. a compensator) before the diagram is built; its return value is kept
    in ``Simulation.builder_extras``. `meshcat` (a pydrake Meshcat) adds a visualizer.
    """
    config.validate()
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant

    if trajectory is None:
        trajectory = plan_trajectory(config, scene)
    q_source = builder.AddNamedSystem(
        "trajectory", TrajectorySource(trajectory, output_derivative_order=1)
    )
    vd_source = builder.AddNamedSystem("trajectory_acceleration", TrajectorySource(trajectory.derivative(2)))

    c = config.controller
    controller = builder.AddNamedSystem(
        "controller",
        DiscreteInverseDynamicsController(
            make_control_plant(config, scene), kp=c.kp, ki=c.ki, kd=c.kd, period=config.time_step
        ),
    )
    builder.Connect(plant.get_state_output_port(scene.arm), controller.get_input_port_estimated_state())
    builder.Connect(q_source.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(vd_source.get_output_port(), controller.get_input_port_desired_acceleration())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port(scene.arm))

    sensor = builder.AddNamedSystem("ft_sensor", ForceTorqueSensor(plant, scene.sensor_joint))
    builder.Connect(plant.get_reaction_forces_output_port(), sensor.GetInputPort("reaction_forces"))
    noisy = builder.AddNamedSystem("noisy_ft_sensor", NoisyForceTorqueSensor(config.sensor))
    builder.Connect(sensor.GetOutputPort("wrench"), noisy.GetInputPort("wrench_ideal"))

    truth = builder.AddNamedSystem(
        "contact_truth",
        ContactTruth(plant, scene.sensor_frame, scene.tool_bodies, scene.environment_bodies,
                     noisy.period),
    )
    builder.Connect(plant.get_contact_results_output_port(), truth.GetInputPort("contact_results"))
    builder.Connect(plant.get_body_poses_output_port(), truth.GetInputPort("body_poses"))

    period = noisy.period
    loggers = Loggers(
        state=LogVectorOutput(plant.get_state_output_port(scene.arm), builder, period),
        acceleration=LogVectorOutput(
            plant.get_generalized_acceleration_output_port(scene.arm), builder, period
        ),
        ideal=LogVectorOutput(sensor.GetOutputPort("wrench"), builder, period),
        measured=LogVectorOutput(noisy.GetOutputPort("wrench_measured"), builder, period),
        saturated=LogVectorOutput(noisy.GetOutputPort("saturated"), builder, period),
        external=LogVectorOutput(truth.GetOutputPort("wrench_external"), builder, period),
        contact=LogVectorOutput(truth.GetOutputPort("contact"), builder, period),
    )
    parts = {"scene": scene, "sensor": sensor, "noisy_sensor": noisy, "truth": truth,
             "period": period}
    extras = extra(builder, parts) if extra is not None else {}
    if meshcat is not None:
        from pydrake.visualization import AddDefaultVisualization

        AddDefaultVisualization(builder, meshcat=meshcat)
    diagram = builder.Build()
    diagram.set_name("ftdrake")
    return Simulation(config, diagram, scene, trajectory, sensor, noisy, truth, loggers,
                      extras or {})


def plan_trajectory(config: ScenarioConfig, scene: Scene | None = None):
    """The trajectory `config.trajectory` describes, checked against limits and collisions."""
    geometry = robot_geometry(config)
    limits = JointLimits.from_plant(
        geometry._plant, geometry._scene.arm, config.trajectory.acceleration_limit
    )
    return make_trajectory(config.trajectory, config.home_q, limits, geometry)


def robot_geometry(config: ScenarioConfig) -> RobotGeometry:
    """Kinematics-only copy of the scene, for planning (IK, clearance) outside a simulation."""
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    diagram = builder.Build()
    return RobotGeometry(diagram, scene.plant, scene.scene_graph, scene)
