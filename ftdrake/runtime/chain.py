"""CompensationChain: the product, one Diagram that the simulated and the live station both add.

    wrench_measured ──► CompensatorSystem ── wrench_compensated ──► OnlineBiasTracker
    joint_state ───────►  (model)                                 (bias, re-tare, grasp)
    temperature ───────►      │ wrench_std, out_of_domain, fault        │ wrench_contact
                              ▼                                         ▼
                        ContactDetector ◄───────────────────────────────┘
                              │ contact, contact_force
                              └──► (back to the tracker: it freezes during contact)

Built from a fitted compensator and the product's own :class:`~ftdrake.config.ChainConfig`
(its ``compensator``, ``bias_tracker``, ``detector``, ``sensor`` stream and ``robot``; a
simulated scenario contains one, ``scenario.chain_config()``). The model is checked against
the loop contract once, here (:func:`~ftdrake.compensation.contract.loop_view`). With the
tracker disabled the detector reads ``wrench_compensated`` directly. With
``bias_tracker.track_payload`` the tracker needs the apparent gravity at the sensor: from
the joint state through the robot's serial chain (``gravity="joint_state"``, the live
robot's way; :class:`JointStateGravity`, on the robot embedded in the model unless ``config.robot``
or `robot` names another), or from inputs (``gravity="input"``, the simulation's way: the plant's
kinematics).

Adding it to a diagram (frames, units and signs as in :mod:`ftdrake.conventions`)::

    chain = builder.AddSystem(CompensationChain(model, ftdrake.ChainConfig()))
    builder.Connect(sensor_reading, chain.get_input_port_wrench_measured())
    builder.Connect(plant.get_state_output_port(arm), chain.get_input_port_joint_state())
"""

from __future__ import annotations

import copy
import math

from pydrake.systems.framework import Diagram, DiagramBuilder

from ..compensation.contract import LoopView, loop_view
from ..config import ChainConfig, RobotConfig
from ..errors import ConfigError
from ..physics.chain import SerialChain
from ..physics.robot import RobotDescription, ftdrake_arm
from .bias_tracker import OnlineBiasTracker
from .compensator import CompensatorSystem
from .delay_line import DelayLine
from .detector import ContactDetector
from .joint_gravity import JointStateGravity
from .payload_change import PayloadChangeMonitor

GRAVITY_SOURCES = ("joint_state", "input")


class CompensationChain(Diagram):
    """Compensator → bias tracker → contact detector, with exported ports (held between
    samples, updated every `period` s; the compensator's output lags its inputs by one sample).

    Input ports:
      wrench_measured (6): the sensor reading ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m, in the frame
        the sensor measures in (S, or its own frame Sm when the model identified a mounting).
      joint_state (2n): ``[q; v]`` in rad, rad/s, in the model's joint order.
      temperature (1; only when the model was trained with it): the sensor's temperature, °C.
      imu (6; only when the model takes an IMU): ``[f_S; ω_S]`` of an IMU at So, axes along
        S: proper acceleration in m/s², angular velocity in rad/s (α is derived from ω at
        ``compensator.imu_alpha_cutoff_hz``); NaN for a missing or stale sample (a fault).
      tared (1; with the bias tracker): > 0.5 for a sample when the sensor was re-tared.
      payload_changed (1; with ``track_payload``): > 0.5 when a payload was grasped or let go.
        With ``bias_tracker.payload_change.enabled`` a change nobody signals is detected too.
      gravity_S (3), motion_S (6; with ``track_payload`` and ``gravity="input"``; motion_S
        with ``track_payload_motion``): ``g − a_So`` in m/s² and S's ``[ω; α]`` in rad/s,
        rad/s², all in S.
    Output ports:
      wrench_internal (6): the model's internal wrench as the sensor reads it, N, N·m.
      wrench_compensated (6): measured − internal, turned into S (N, N·m, about So).
      wrench_contact (6): the contact wrench estimate the detector judges: compensated − the
        tracker's bias and payload wrench (= wrench_compensated without the tracker).
      wrench_std (6): the model's predictive std (zeros for a model without one), N, N·m.
      out_of_domain (1), fault (1): 1.0 when a joint input is outside the training range /
        the latest inputs were not finite (outputs then hold their last good values).
      contact (1): 1.0 while the detector reports contact.
      contact_force (1): ‖F‖ of wrench_contact in N while in contact, else 0.
      bias (6; with the tracker): the tracker's published bias, N, N·m, in S.
      tracker_std (6; with the tracker): the predictive std of what the tracker subtracted
        (bias and payload wrench), N, N·m, in S; the detector's test whitens by
        √(wrench_std² + tracker_std²).
      payload (4; with ``track_payload``): ``[Δm; Δ(m·c)]`` in kg, kg·m (S).
      payload_change (1; with ``bias_tracker.payload_change.enabled``): 1.0 for a while
        after a payload change nobody signalled was recognised
        (:class:`~ftdrake.runtime.payload_change.PayloadChangeMonitor`).
      payload_state (1; with ``bias_tracker.payload_change.enabled``): the monitor's
        decision on a change of the contact wrench: 0 none, 1 undecided (no rotation yet to
        tell a weight from a press), 2 payload change (the detector then reports no contact),
        3 contact.

    `model`: a fitted ftdrake compensator (``load_model``), following the loop contract
    (:class:`~ftdrake.compensation.contract.LoopModel`). `config`: a
    :class:`~ftdrake.config.ChainConfig` (default: ``ChainConfig()``; the chain keeps a
    validated copy, ``self.config``, with ``detector.test: auto`` resolved: the χ² test for a
    model with a std of a reading when ``chi2_on`` is given, the norm test otherwise,
    :meth:`~ftdrake.config.DetectorConfig.for_model`).
    `period`: s (default: ``config.sensor``'s rate). `n_joints`: checked against the model.
    `gravity`: see above. `robot`: the RobotDescription whose chain gives ``gravity_S`` from
    the joint state; default: ``config.robot`` when it names a file, else the robot embedded
    in the model (``model.robot_description()``; ``self.robot`` holds the one used, None
    without joint-state gravity). ``config.sensor.wrench_delay_s``: how long the wrench
    stream lags the joint states (s; negative: the joint states lag), which a
    :class:`DelayLine` on the stream that is ahead corrects (its output interpolated between
    samples); null: the model's ``wrench_delay_s_`` (set by training with a delay
    alignment); with 0 there is no delay line.
    """

    def __init__(self, model, config: ChainConfig | None = None, *,
                 period: float | None = None, n_joints: int | None = None,
                 gravity: str = "joint_state", robot: RobotDescription | None = None):
        super().__init__()
        if gravity not in GRAVITY_SOURCES:
            raise ConfigError(f"CompensationChain: gravity must be one of {GRAVITY_SOURCES}; "
                              f"got {gravity!r}")
        config = _checked_config(config)
        view = self.view = loop_view(model, n_joints)
        period = float(period) if period is not None else config.sensor.period
        if not (period > 0 and math.isfinite(period)):
            raise ConfigError(f"CompensationChain: period must be a positive number of seconds; "
                              f"got {period!r}")
        # "auto" becomes the test this model supports (χ² with a std of a reading).
        config = config.replace(detector=config.detector.for_model(view.model))
        self.config, self.period, self.robot = config, period, None
        if config.detector.test == "chi2" and not view.reading_std:
            raise ConfigError(
                f"detector.test 'chi2' whitens the wrench by the model's std of a reading; "
                f"{type(model).__name__} has none (a forest's spread across trees is not "
                "one): use a physics, hybrid or GP model, or detector.test 'norm'")
        builder = DiagramBuilder()
        self.compensator = builder.AddNamedSystem("compensator", CompensatorSystem(
            view, period,
            acceleration_cutoff_hz=config.compensator.acceleration_cutoff_hz,
            imu_alpha_cutoff_hz=config.compensator.imu_alpha_cutoff_hz))
        self.detector = builder.AddNamedSystem("contact_detector",
                                               ContactDetector(config.detector, period))
        self.tracker = self.gravity = self.delay_line = self.payload_monitor = None
        comp = self.compensator
        contact_wrench = comp.get_output_port_wrench_compensated()
        if config.bias_tracker.enabled:
            self.tracker = builder.AddNamedSystem(
                "bias_tracker", OnlineBiasTracker(config.bias_tracker, config.sensor, period,
                                                  payload_map=view.payload_map))
            self._wire_tracker(builder)
            contact_wrench = self.tracker.get_output_port_wrench_contact()
        builder.Connect(contact_wrench, self.detector.get_input_port_wrench_contact())
        builder.Connect(comp.get_output_port_wrench_std(),
                        self.detector.get_input_port_wrench_std())

        wrench_in, joint_state_in = self._delayed_inputs(builder, view)
        builder.ExportInput(wrench_in, "wrench_measured")
        joint_state = builder.ExportInput(joint_state_in, "joint_state")
        if comp.needs_temperature:
            builder.ExportInput(comp.get_input_port_temperature(), "temperature")
        if comp.needs_imu:
            builder.ExportInput(comp.get_input_port_imu(), "imu")
        if self.tracker is not None:
            self._export_tracker_inputs(builder, gravity, joint_state, robot)

        builder.ExportOutput(comp.get_output_port_wrench_internal(), "wrench_internal")
        builder.ExportOutput(comp.get_output_port_wrench_compensated(), "wrench_compensated")
        builder.ExportOutput(contact_wrench, "wrench_contact")
        builder.ExportOutput(comp.get_output_port_wrench_std(), "wrench_std")
        builder.ExportOutput(comp.get_output_port_out_of_domain(), "out_of_domain")
        builder.ExportOutput(comp.get_output_port_fault(), "fault")
        builder.ExportOutput(self.detector.get_output_port_contact(), "contact")
        builder.ExportOutput(self.detector.get_output_port_contact_force(), "contact_force")
        if self.tracker is not None:
            self._export_tracker_outputs(builder)
        builder.BuildInto(self)
        self.set_name("compensation_chain")

    @property
    def needs_temperature(self) -> bool:
        """Whether the model takes the sensor temperature (the ``temperature`` input exists)."""
        return self.compensator.needs_temperature

    @property
    def needs_imu(self) -> bool:
        """Whether the model takes an IMU at the sensor (the ``imu`` input exists)."""
        return self.compensator.needs_imu

    def initialize(self, root_context) -> None:
        """Sets the tracker's starting estimate from ``config.bias_tracker`` (``initial_bias``,
        ``start_settled``) in `root_context` (the context of the diagram holding the chain)."""
        if self.tracker is None:
            return
        settings = self.config.bias_tracker
        self.tracker.set_estimate(self.tracker.GetMyMutableContextFromRoot(root_context),
                                  settings.initial_bias, [0.0] * 4,
                                  settled=settings.start_settled)

    def _delayed_inputs(self, builder, view: LoopView):
        """The compensator's wrench and joint-state inputs, one behind a DelayLine when the
        streams are ``wrench_delay_s`` apart (see the class docstring)."""
        comp = self.compensator
        wrench_in, state_in = (comp.get_input_port_wrench_measured(),
                               comp.get_input_port_joint_state())
        given = self.config.sensor.wrench_delay_s
        delay = view.wrench_delay_s if given is None else float(given)
        self.wrench_delay_s = delay
        if not math.isfinite(delay):
            raise ConfigError(f"CompensationChain: wrench_delay_s must be finite; got {delay!r}")
        if delay == 0.0:
            return wrench_in, state_in
        ahead = state_in if delay > 0 else wrench_in  # the stream that is early gets delayed
        self.delay_line = builder.AddNamedSystem(
            "joint_state_delay" if delay > 0 else "wrench_delay",
            DelayLine(ahead.size(), abs(delay) / self.period, self.period))
        builder.Connect(self.delay_line.get_output_port_delayed(), ahead)
        line_in = self.delay_line.get_input_port_signal()
        return (wrench_in, line_in) if delay > 0 else (line_in, state_in)

    def _wire_tracker(self, builder) -> None:
        comp, tracker = self.compensator, self.tracker
        builder.Connect(comp.get_output_port_wrench_compensated(),
                        tracker.get_input_port_wrench_compensated())
        builder.Connect(comp.get_output_port_out_of_domain(),
                        tracker.get_input_port_out_of_domain())
        builder.Connect(comp.get_output_port_fault(), tracker.get_input_port_fault())
        # The detector's contact is a state output (the previous sample's flag): no algebraic
        # loop through the pair.
        builder.Connect(self.detector.get_output_port_contact(), tracker.get_input_port_contact())
        # The detector whitens by the compensator's std and the tracker's together: a payload
        # still being identified after a grasp is not taken for contact.
        builder.Connect(tracker.get_output_port_wrench_std(),
                        self.detector.get_input_port_wrench_std_tracker())

    def _export_tracker_inputs(self, builder, gravity, joint_state, robot) -> None:
        tracker = self.tracker
        builder.ExportInput(tracker.get_input_port_tared(), "tared")
        if not tracker.track_payload:
            return
        self._wire_gravity(builder, gravity, joint_state, robot)
        builder.ExportInput(tracker.get_input_port_payload_changed(), "payload_changed")
        if self.config.bias_tracker.payload_change.enabled:
            self._wire_payload_monitor(builder, gravity)

    def _export_tracker_outputs(self, builder) -> None:
        builder.ExportOutput(self.tracker.get_output_port_bias(), "bias")
        builder.ExportOutput(self.tracker.get_output_port_wrench_std(), "tracker_std")
        if self.tracker.track_payload:
            builder.ExportOutput(self.tracker.get_output_port_payload(), "payload")
        if self.payload_monitor is not None:
            builder.ExportOutput(self.payload_monitor.get_output_port_payload_change(),
                                 "payload_change")
            builder.ExportOutput(self.payload_monitor.get_output_port_payload_state(),
                                 "payload_state")

    def _wire_payload_monitor(self, builder, gravity: str) -> None:
        """The unsignalled payload change's monitor: it reads what the tracker reads (its
        contact wrench, g_S, the detector's flag) and announces a change to the tracker."""
        tracker = self.tracker
        monitor = self.payload_monitor = builder.AddNamedSystem("payload_change_monitor",
            PayloadChangeMonitor(self.config.bias_tracker.payload_change, self.config.sensor))
        builder.Connect(tracker.get_output_port_wrench_contact(),
                        monitor.get_input_port_wrench_contact())
        builder.Connect(self.detector.get_output_port_contact(),
                        monitor.get_input_port_contact())
        # A recognised payload change is not reported as contact (the detector reads the
        # monitor's decision; both state outputs: no algebraic loop).
        builder.Connect(monitor.get_output_port_payload_state(),
                        self.detector.get_input_port_payload_state())
        if gravity == "input":
            builder.ConnectInput("gravity_S", monitor.get_input_port_gravity_S())
        else:
            builder.Connect(self.gravity.get_output_port_gravity_S(),
                            monitor.get_input_port_gravity_S())
        # Both are state outputs: no algebraic loop through the tracker and the monitor.
        builder.Connect(monitor.get_output_port_payload_change(),
                        tracker.get_input_port_payload_change_detected())

    def _wire_gravity(self, builder, gravity: str, joint_state, robot) -> None:
        tracker = self.tracker
        motion = self.config.bias_tracker.track_payload_motion
        if gravity == "input":
            builder.ExportInput(tracker.get_input_port_gravity_S(), "gravity_S")
            if motion:
                builder.ExportInput(tracker.get_input_port_motion_S(), "motion_S")
            return
        self.robot = self._gravity_robot(robot)
        self.gravity = builder.AddNamedSystem(
            "sensor_gravity", _joint_state_gravity(self.config, self.robot, self.view.n_joints,
                                                   self.period))
        if self.delay_line is not None and self.wrench_delay_s > 0:  # the delayed joint state
            builder.Connect(self.delay_line.get_output_port_delayed(),
                            self.gravity.get_input_port_joint_state())
        else:
            builder.ConnectInput(joint_state, self.gravity.get_input_port_joint_state())
        builder.Connect(self.gravity.get_output_port_gravity_S(),
                        tracker.get_input_port_gravity_S())
        if motion:
            builder.Connect(self.gravity.get_output_port_motion_S(),
                            tracker.get_input_port_motion_S())

    def _gravity_robot(self, robot: RobotDescription | None) -> RobotDescription:
        """The robot joint-state gravity is computed on: `robot`, else ``config.robot``, else
        the model's own; a ConfigError when there is none."""
        if robot is not None:
            return robot
        if self.config.robot.file:
            return configured_robot(self.config.robot)
        if self.view.robot is not None:
            return self.view.robot
        raise ConfigError(
            f"bias_tracker.track_payload computes gravity at the sensor from the joint state, "
            f"on the robot's kinematics; a {type(self.view.model).__name__} carries no robot "
            "(physics and hybrid models do): set chain.robot.file and chain.robot.sensor_frame "
            "(--robot FILE --sensor-frame NAME on the command line), or pass "
            "CompensationChain(..., robot=RobotDescription(...))")

    # Named accessors of the exported ports (those a configuration leaves out raise).
    def get_input_port_wrench_measured(self):
        return self.GetInputPort("wrench_measured")

    def get_input_port_joint_state(self):
        return self.GetInputPort("joint_state")

    def get_input_port_temperature(self):
        return self.GetInputPort("temperature")

    def get_input_port_imu(self):
        return self.GetInputPort("imu")

    def get_input_port_tared(self):
        return self.GetInputPort("tared")

    def get_input_port_payload_changed(self):
        return self.GetInputPort("payload_changed")

    def get_input_port_gravity_S(self):
        return self.GetInputPort("gravity_S")

    def get_input_port_motion_S(self):
        return self.GetInputPort("motion_S")

    def get_output_port_wrench_internal(self):
        return self.GetOutputPort("wrench_internal")

    def get_output_port_wrench_compensated(self):
        return self.GetOutputPort("wrench_compensated")

    def get_output_port_wrench_contact(self):
        return self.GetOutputPort("wrench_contact")

    def get_output_port_wrench_std(self):
        return self.GetOutputPort("wrench_std")

    def get_output_port_out_of_domain(self):
        return self.GetOutputPort("out_of_domain")

    def get_output_port_fault(self):
        return self.GetOutputPort("fault")

    def get_output_port_contact(self):
        return self.GetOutputPort("contact")

    def get_output_port_contact_force(self):
        return self.GetOutputPort("contact_force")

    def get_output_port_bias(self):
        return self.GetOutputPort("bias")

    def get_output_port_tracker_std(self):
        return self.GetOutputPort("tracker_std")

    def get_output_port_payload(self):
        return self.GetOutputPort("payload")

    def get_output_port_payload_change(self):
        return self.GetOutputPort("payload_change")

    def get_output_port_payload_state(self):
        return self.GetOutputPort("payload_state")


def _checked_config(config) -> ChainConfig:
    """A validated copy of `config` (``ChainConfig()`` for None): the chain owns its config."""
    if config is None:
        return ChainConfig()
    if not isinstance(config, ChainConfig):
        raise ConfigError(
            f"CompensationChain takes a ChainConfig (the product's own config); got "
            f"{type(config).__name__}. For a simulated scenario pass scenario.chain_config(); "
            "a live config file's chain section loads with "
            "ftdrake.load_chain_config(path)")
    return copy.deepcopy(config).validate()


def configured_robot(robot: RobotConfig) -> RobotDescription:
    """The RobotDescription a ``chain.robot`` section names (``ftdrake``: ftdrake's arm)."""
    if robot.file == "ftdrake":
        return ftdrake_arm()
    return RobotDescription(robot.file, robot.sensor_frame, robot.base_frame or None)


def _joint_state_gravity(config: ChainConfig, description: RobotDescription, n_joints: int,
                         period: float) -> JointStateGravity:
    """g_S − a_So and S's [ω; α] from the joint state, on `description`'s serial chain (there
    is no plant on a live robot)."""
    plant, frame_S = description.build_plant()
    chain = SerialChain.from_plant(plant, frame_S)
    if description.joints:  # a log's joints in a bigger description; the others held still
        chain, _ = chain.with_joint_columns(description.joints, dict(description.fixed_joints))
    if chain.num_positions != n_joints:
        raise ConfigError(f"bias_tracker.track_payload: the robot {description.label} has "
                          f"{chain.num_positions} joints, the model {n_joints}; give the robot "
                          "the model was trained on (chain.robot; --robot on the command line)")
    return JointStateGravity(chain, period,
                             acceleration_cutoff_hz=config.compensator.acceleration_cutoff_hz,
                             gravity_W=plant.gravity_field().gravity_vector())


def model_payload_map(model):
    """The model's map from a wrench at the sensor to its compensated wrench (None: the
    identity, as for a model without a reading matrix, e.g. a forest)."""
    return loop_view(model).payload_map
