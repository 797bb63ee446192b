"""The whole block diagram on one screen: start here.

    trajectory ──► inverse-dynamics controller ──► plant ──► reaction forces ──► F/T sensor
     (q_d, v_d, v̇_d)      (nominal tool model)       │                          │ wrench_ideal
                                                     │◄── cable (spring + weight)          ▼
                                                     ├──► contact truth           noisy sensor
                                                     │                   wrench_measured │
                                                     └── joint_state ──► compensator ◄───┘
                                           wrench_compensated, wrench_std │
                                                                          ▼
                                                 bias tracker (drift, re-tare, grasp)
                                                           wrench_contact │
                                                                          ▼
                                                                   contact detector

Compensator, bias tracker and detector are the runtime chain
(:class:`~ftdrake.runtime.chain.CompensationChain`), the same the live station adds.
:func:`build_station` builds it from one :class:`~ftdrake.config.ScenarioConfig`; the
compensator and detector are added when a fitted compensator is given (and the sensor's
``temperature`` port feeds the compensator's when its model was trained with it). Every part has a
typed handle and a logger on :class:`Station`; :func:`ftdrake.sim.simulate.simulate` runs it.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    Adder,
    LogVectorOutput,
    TrajectorySource,
    VectorLogSink,
    ZeroOrderHold,
)
from pydrake.trajectories import PiecewisePolynomial

from ..config import ConfigError, ScenarioConfig
from ..offline.recorder import add_output_loggers
from ..runtime.chain import CompensationChain
from ..systems.contact_truth import ContactTruth
from ..systems.controller import DiscreteInverseDynamicsController
from ..systems.encoders import JointEncoders
from ..systems.friction import JointFriction, check_explicit_stability
from ..systems.ft_sensor import ForceTorqueSensor
from ..systems.imu import ImuNoise, add_imu
from ..systems.noisy_sensor import NoisyForceTorqueSensor
from ..systems.payload_feedforward import PayloadFeedforward
from ..systems.sensor_gravity import SensorGravity
from ..systems.transmission import MotorSide
from ..systems.wrench_arrows import WrenchArrows
from .events import EventSignals, add_sensor_events
from .scene import CONTROL_SENSOR_FRAME, Scene, add_scene, make_control_plant
from .trajectories import JointLimits, RobotGeometry
from .trajectory_plan import make_trajectory


@dc.dataclass
class Loggers:
    """Loggers sampled at the sensor rate. Each holds one signal's time series."""

    state: VectorLogSink  # arm q (rad), v (rad/s)
    acceleration: VectorLogSink  # arm v̇ (rad/s²), from the plant's step
    ideal: VectorLogSink  # ideal sensor wrench (N, N·m; S)
    measured: VectorLogSink  # the sensor reading the compensator gets (after a re-tare offset)
    saturated: VectorLogSink
    wrench_contact_true: VectorLogSink  # true contact wrench at the sensor (N, N·m; S)
    contact_true: VectorLogSink  # true contact flag
    offset: VectorLogSink | None = None  # the driver's zero offset (with a re-tare event)
    push: VectorLogSink | None = None  # the push's wrench at the sensor (with a push event)
    temperature: VectorLogSink | None = None  # the sensor's temperature, °C
    imu: VectorLogSink | None = None  # with scenario.imu.enabled: [acc (m/s²), gyro (rad/s)], S


@dc.dataclass
class Compensation:
    """The runtime chain in the loop, with its loggers: one per output port the chain has,
    under the port's name, sampled at the sensor rate
    (:func:`~ftdrake.offline.recorder.add_output_loggers`)."""

    chain: CompensationChain
    loggers: dict  # port name → VectorLogSink

    @property
    def compensator(self):
        return self.chain.compensator

    @property
    def detector(self):
        return self.chain.detector

    @property
    def tracker(self):
        """The bias tracker; None with ``scenario.chain.bias_tracker.enabled`` off."""
        return self.chain.tracker


@dc.dataclass
class Station:
    """A built diagram with typed handles to every part users and tests need."""

    config: ScenarioConfig
    diagram: Diagram
    scene: Scene
    trajectory: PiecewisePolynomial  # q(t), rad
    controller: DiscreteInverseDynamicsController
    sensor: ForceTorqueSensor
    noisy_sensor: NoisyForceTorqueSensor
    truth: ContactTruth
    loggers: Loggers
    compensation: Compensation | None = None  # None when built without a compensator
    arrows: WrenchArrows | None = None  # with a compensator and Meshcat
    events: EventSignals | None = None  # the scenario's events' signals (see sim/events.py)
    friction: JointFriction | None = None  # with scenario.friction.enabled
    # The learned (or ILC) feedforward after the controller, and its logger of
    # [correction (n), correction_std (n), confidence (n)]; see systems/learned_feedforward.py.
    feedforward: object = None
    feedforward_log: VectorLogSink | None = None
    # With scenario.transmission.enabled: the motors (systems/transmission.py) and a logger of
    # their [φ, φ̇] (the motor-side angles the controller reads, rad, rad/s).
    transmission: MotorSide | None = None
    motor_state_log: VectorLogSink | None = None
    # With controller.adapt_to_payload: the torque for the tracker's payload estimate.
    payload_feedforward: PayloadFeedforward | None = None
    # With scenario.encoders.enabled: the encoders' reading (offsets, sag) that the
    # controller, the runtime chain and the state logger get instead of the joint state.
    encoders: JointEncoders | None = None
    # With scenario.imu.enabled: the IMU at the sensor (systems/imu.py), its reading logged.
    imu: ImuNoise | None = None

    @property
    def plant(self) -> MultibodyPlant:
        return self.scene.plant

    @property
    def period(self) -> float:
        """The sensor's sample period (s): every logger and the compensator run at it."""
        return self.noisy_sensor.period


def build_station(config: ScenarioConfig, compensator=None, *, meshcat=None,
                  trajectory: PiecewisePolynomial | None = None, feedforward=None) -> Station:
    """Builds the simulated arm, sensor and environment for `config`.

    `compensator` (a fitted ftdrake compensator, e.g. from ``load_model``) adds the
    CompensatorSystem and ContactDetector (configured by ``config.chain``, with the simulated
    sensor's stream: ``config.chain_config()``) in the loop. `trajectory` overrides the one
    ``config.trajectory`` describes. `feedforward` (a ``LearnedFeedforward`` or
    ``TimeIndexedFeedforward``) adds its torque correction to the controller's output.
    `meshcat` (a pydrake Meshcat) adds a visualizer (and, with a compensator, the wrench arrows).
    The models are parsed once for the simulation and once for the controller's own (imperfect)
    model.

    `config` is taken as valid: :func:`~ftdrake.config.load_config` checks a file, and a
    config built or edited in Python is checked by ``config.validate()``. What only the
    models can tell (frame names, the joint count) is checked here, naming the field.
    """
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant
    home = np.asarray(config.home_q, dtype=float).reshape(-1, 1)
    # Planning needs the built diagram (IK and clearance queries on its scene graph), so the
    # trajectory sources start with a placeholder and get the planned trajectory after Build.
    placeholder = PiecewisePolynomial(home)
    q_source = builder.AddNamedSystem(
        "trajectory", TrajectorySource(placeholder, output_derivative_order=1))
    vd_source = builder.AddNamedSystem(
        "trajectory_acceleration", TrajectorySource(placeholder.derivative(2)))
    controller, friction, transmission, payload_ff, encoders = _add_control(
        builder, config, scene, q_source, vd_source, feedforward)
    joint_state = _measured_joint_state(config, scene, encoders, transmission)
    sensor, noisy = _add_sensor(builder, config, scene)

    period = noisy.period
    events = add_sensor_events(builder, config.events, scene,
                               noisy.get_output_port_wrench_measured())
    truth = builder.AddNamedSystem(
        "contact_truth",
        ContactTruth(plant, scene.sensor_frame, scene.tool_bodies, scene.environment_bodies,
                     period),
    )
    builder.Connect(plant.get_contact_results_output_port(),
                    truth.get_input_port_contact_results())
    builder.Connect(plant.get_body_poses_output_port(), truth.get_input_port_body_poses())

    def log(port):
        return LogVectorOutput(port, builder, period)

    loggers = Loggers(
        state=log(joint_state),
        acceleration=log(plant.get_generalized_acceleration_output_port(scene.arm)),
        ideal=log(sensor.get_output_port_wrench()),
        measured=log(events.reading),
        saturated=log(noisy.get_output_port_saturated()),
        wrench_contact_true=log(truth.get_output_port_wrench_contact_true()),
        contact_true=log(truth.get_output_port_contact_true()),
        offset=log(events.offset) if events.offset is not None else None,
        push=log(events.push.get_output_port_wrench_S()) if events.push is not None else None,
        temperature=log(noisy.get_output_port_temperature()),
    )
    imu = None
    if config.imu.enabled:
        imu = add_imu(builder, plant, scene.sensor_frame, config.imu, period)
        # Logged as the loop reads it: sampled at each update time before the discrete
        # updates (the accelerometer's reading depends on the actuation they change).
        hold = builder.AddNamedSystem("imu_sample", ZeroOrderHold(period, 6))
        builder.Connect(imu.get_output_port_imu(), hold.get_input_port())
        loggers.imu = log(hold.get_output_port())
    feedforward_log = (log(feedforward.get_output_port_status()) if feedforward is not None
                       else None)
    motor_state_log = (log(transmission.get_output_port_motor_state())
                       if transmission is not None else None)
    compensation = arrows = None
    if compensator is not None:
        compensation = _add_compensation(builder, config, compensator, scene, events, period,
                                         noisy.get_output_port_temperature(),
                                         joint_state, imu)
        if payload_ff is not None:  # adaptive computed torque: the tracker's payload
            if not compensation.chain.HasOutputPort("payload"):
                raise ConfigError("controller.adapt_to_payload: the payload comes from the "
                                  "bias tracker; set bias_tracker.enabled: true")
            builder.Connect(compensation.chain.get_output_port_payload(),
                            payload_ff.get_input_port_payload())
        if meshcat is not None:
            arrows = _add_arrows(builder, meshcat, scene, events, compensation)
    if meshcat is not None:
        from pydrake.visualization import (  # noqa: PLC0415 (only with Meshcat)
            AddDefaultVisualization,
        )

        AddDefaultVisualization(builder, meshcat=meshcat)
    diagram = builder.Build()
    diagram.set_name("ftdrake")

    if trajectory is None:
        robot = RobotGeometry(diagram, plant, scene.scene_graph, scene)
        trajectory = plan_trajectory(config, robot)
    q_source.UpdateTrajectory(trajectory)
    vd_source.UpdateTrajectory(trajectory.derivative(2))
    return Station(config, diagram, scene, trajectory, controller, sensor, noisy, truth,
                   loggers, compensation, arrows, events, friction, feedforward, feedforward_log,
                   transmission, motor_state_log, payload_ff, encoders, imu)


def _measured_joint_state(config: ScenarioConfig, scene: Scene, encoders, transmission):
    """The joint state the loop reads: the plant's, the encoders' (with their offsets), or the
    motor side's with compliant joints and ``transmission.chain_reads_motors``."""
    if encoders is not None:
        return encoders.get_output_port_measured_state()
    if transmission is not None and config.transmission.chain_reads_motors:
        return transmission.get_output_port_motor_state()  # the motor-side encoders
    return scene.plant.get_state_output_port(scene.arm)


def _add_sensor(builder, config: ScenarioConfig, scene: Scene):
    """The ideal F/T sensor at the weld and its noisy reading (whose vibration, when on, grows
    with the arm's true motion). Returns both."""
    plant = scene.plant
    sensor = builder.AddNamedSystem("ft_sensor", ForceTorqueSensor(plant, scene.sensor_joint))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    sensor.get_input_port_reaction_forces())
    noisy = builder.AddNamedSystem("noisy_ft_sensor", NoisyForceTorqueSensor(
        config.sensor, n_joints=plant.num_velocities(scene.arm)))
    builder.Connect(sensor.get_output_port_wrench(), noisy.get_input_port_wrench_ideal())
    if noisy.HasInputPort("joint_state"):
        builder.Connect(plant.get_state_output_port(scene.arm), noisy.get_input_port_joint_state())
        builder.Connect(plant.get_generalized_acceleration_output_port(scene.arm),
                        noisy.get_input_port_joint_acceleration())
    return sensor, noisy


def _add_control(builder, config: ScenarioConfig, scene: Scene, q_source, vd_source,
                 feedforward):
    """trajectory → controller (→ + feedforward) (→ − joint friction) → the plant's actuation,
    or the motors' with compliant transmissions. Returns the controller, the friction system
    (None unless ``friction.enabled``), the motors (None unless ``transmission.enabled``),
    the payload feedforward and the encoders (None unless ``encoders.enabled``)."""
    plant = scene.plant
    c = config.controller
    controller = builder.AddNamedSystem(
        "controller",
        DiscreteInverseDynamicsController(
            make_control_plant(config, scene), kp=c.kp, ki=c.ki, kd=c.kd, period=config.time_step
        ),
    )
    # The controller and friction read the joint angles where the encoders are: the links'
    # (rigid joints) or the motors' (compliant transmissions).
    transmission = None
    encoder_state = plant.get_state_output_port(scene.arm)
    if config.transmission.enabled:
        transmission = builder.AddNamedSystem(
            "transmission", MotorSide(config.transmission, config.time_step))
        builder.Connect(plant.get_state_output_port(scene.arm),
                        transmission.get_input_port_link_state())
        spring_end = (transmission.get_output_port_link_reference()
                      if config.transmission.has_transmission_error()
                      else transmission.get_output_port_motor_state())
        builder.Connect(spring_end, plant.get_desired_state_input_port(scene.arm))
        encoder_state = transmission.get_output_port_motor_state()
    encoders = None
    if config.encoders.enabled:  # their zero offsets and gravity sag
        encoders = builder.AddNamedSystem("joint_encoders",
                                          JointEncoders(config.encoders, plant, scene.arm))
        builder.Connect(encoder_state, encoders.get_input_port_state())
        encoder_state = encoders.get_output_port_measured_state()
    builder.Connect(encoder_state, controller.get_input_port_estimated_state())
    builder.Connect(q_source.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(vd_source.get_output_port(), controller.get_input_port_desired_acceleration())
    actuation = controller.get_output_port_control()
    payload_ff = None
    if c.adapt_to_payload:  # controller → + the payload's torque
        payload_ff, actuation = _add_payload_feedforward(builder, config, scene, encoder_state,
                                                         vd_source, actuation)
    if feedforward is not None:  # controller → + learned correction → (friction) → plant
        builder.AddNamedSystem("feedforward", feedforward)
        builder.Connect(actuation, feedforward.get_input_port_control())
        builder.Connect(q_source.get_output_port(), feedforward.get_input_port_desired_state())
        builder.Connect(vd_source.get_output_port(),
                        feedforward.get_input_port_desired_acceleration())
        actuation = feedforward.get_output_port_control()
    friction = None
    if config.friction.enabled:  # joint friction the controller's model does not know
        friction = builder.AddNamedSystem(
            "joint_friction", JointFriction(config.friction, plant.num_velocities(scene.arm)))
        check_explicit_stability(friction, plant, scene.arm, config.home_q, config.time_step)
        builder.Connect(actuation, friction.get_input_port_actuation())
        builder.Connect(encoder_state, friction.get_input_port_joint_state())
        actuation = friction.get_output_port_actuation()
    if transmission is not None:  # the motors take the torque; the links get the spring's
        builder.Connect(actuation, transmission.get_input_port_motor_torque())
    else:
        builder.Connect(actuation, plant.get_actuation_input_port(scene.arm))
    return controller, friction, transmission, payload_ff, encoders


def _add_payload_feedforward(builder, config, scene, encoder_state, vd_source, actuation):
    """The torque for the bias tracker's payload estimate, added to `actuation` (its payload
    input is connected once the chain is there). Returns (system, the summed actuation)."""
    if not config.chain.bias_tracker.track_payload:
        raise ConfigError("controller.adapt_to_payload: the payload comes from the bias "
                          "tracker; set bias_tracker.track_payload: true")
    control_plant = make_control_plant(config, scene)
    payload_ff = builder.AddNamedSystem("payload_feedforward", PayloadFeedforward(
        control_plant, control_plant.GetFrameByName(CONTROL_SENSOR_FRAME)))
    builder.Connect(encoder_state, payload_ff.get_input_port_estimated_state())
    builder.Connect(vd_source.get_output_port(), payload_ff.get_input_port_desired_acceleration())
    total = builder.AddNamedSystem("payload_torque", Adder(2, control_plant.num_velocities()))
    builder.Connect(actuation, total.get_input_port(0))
    builder.Connect(payload_ff.get_output_port_control(), total.get_input_port(1))
    return payload_ff, total.get_output_port()


def _add_arrows(builder, meshcat, scene: Scene, events: EventSignals,
                compensation: Compensation) -> WrenchArrows:
    """The measured and the estimated contact force drawn in Meshcat."""
    plant = scene.plant
    arrows = builder.AddNamedSystem("wrench_arrows", WrenchArrows(meshcat, plant, scene))
    builder.Connect(events.reading, arrows.get_input_port_measured())
    builder.Connect(compensation.chain.get_output_port_wrench_contact(),
                    arrows.get_input_port_external())
    builder.Connect(plant.get_body_poses_output_port(), arrows.get_input_port_body_poses())
    return arrows


def _add_compensation(builder, config, model, scene, events: EventSignals, period,
                      temperature, joint_state, imu=None) -> Compensation:
    """The runtime chain in the loop: the sensor's reading and the arm's state in (and the
    IMU's reading for a model that takes one); the tracker's payload regressor from the
    plant's own kinematics (SensorGravity)."""
    plant = scene.plant
    chain = builder.AddNamedSystem("compensation_chain", CompensationChain(
        model, config.chain_config(), period=period, n_joints=plant.num_positions(scene.arm),
        gravity="input"))
    builder.Connect(events.reading, chain.get_input_port_wrench_measured())
    builder.Connect(joint_state, chain.get_input_port_joint_state())
    if chain.needs_temperature:  # a model trained with the sensor temperature (°C)
        builder.Connect(temperature, chain.get_input_port_temperature())
    if chain.needs_imu:  # a model with its kinematics from an IMU at the sensor
        if imu is None:
            raise ConfigError(f"the model ({type(chain.view.model).__name__}) takes an IMU at "
                              "the sensor: set scenario.imu.enabled: true")
        builder.Connect(imu.get_output_port_imu(), chain.get_input_port_imu())
    if events.tared is not None and chain.HasInputPort("tared"):
        builder.Connect(events.tared, chain.get_input_port_tared())
    if chain.HasInputPort("gravity_S"):
        _add_sensor_gravity(builder, scene, chain)
    if events.payload_changed is not None and chain.HasInputPort("payload_changed"):
        builder.Connect(events.payload_changed, chain.get_input_port_payload_changed())
    return Compensation(chain, add_output_loggers(builder, chain, period))


def _add_sensor_gravity(builder, scene, chain: CompensationChain) -> None:
    """g_S − a_So and S's [ω; α] from the plant's kinematics, into the chain's tracker."""
    plant = scene.plant
    gravity = builder.AddNamedSystem("sensor_gravity", SensorGravity(plant, scene.sensor_frame))
    builder.Connect(plant.get_body_poses_output_port(), gravity.get_input_port_body_poses())
    builder.Connect(plant.get_body_spatial_velocities_output_port(),
                    gravity.get_input_port_body_spatial_velocities())
    builder.Connect(plant.get_body_spatial_accelerations_output_port(),
                    gravity.get_input_port_body_spatial_accelerations())
    builder.Connect(gravity.get_output_port_gravity_S(), chain.get_input_port_gravity_S())
    if chain.HasInputPort("motion_S"):
        builder.Connect(gravity.get_output_port_motion_S(), chain.get_input_port_motion_S())


def plan_trajectory(config: ScenarioConfig, geometry: RobotGeometry | None = None):
    """The trajectory `config.trajectory` describes, checked against limits and collisions.

    `geometry` answers the IK and clearance queries; without one, a kinematics-only copy of
    the scene is built (for planning outside a simulation).
    """
    geometry = geometry or robot_geometry(config)
    limits = JointLimits.from_plant(geometry.plant, geometry.arm,
                                    config.trajectory.acceleration_limit)
    return make_trajectory(config.trajectory, config.home_q, limits, geometry)


def robot_geometry(config: ScenarioConfig) -> RobotGeometry:
    """Kinematics-only copy of the scene, for planning (IK, clearance) outside a simulation."""
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    diagram = builder.Build()
    return RobotGeometry(diagram, scene.plant, scene.scene_graph, scene)
