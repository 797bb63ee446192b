"""How the robot-based compensators (physics, hybrid, arm) are built for training, and the
options they add to ``ftdrake train``.

On a wrench (6 targets named ``*Fx … *Tz``), physics is the payload model
(:class:`~.physics.PhysicsPayloadCompensator`) on the robot's chain to the sensor frame; on
joint torques (any other targets) physics and arm are the whole arm's rigid-body model
(:class:`~.arm.ArmDynamicsCompensator`). A hybrid is either of those plus a forest on its
residual. Errors name the option that fixes them (:func:`~ftdrake.errors.option_name`: a
:class:`~ftdrake.training.TrainOptions` field in Python, its flag on the command line).
"""

from __future__ import annotations

from pathlib import Path

from ...errors import ConfigError, option_name
from ...physics.robot import ftdrake_arm
from .arm import ArmDynamicsCompensator
from .build import (
    BUILTIN_ROBOT,
    BuildRequest,
    TrainOption,
    is_wrench,
    options_named,
    wrench_only_error,
)
from .hybrid import HybridCompensator, default_residual, joint_torque_residual
from .imu_physics import ImuPayloadCompensator
from .physics import PhysicsPayloadCompensator

#: ``train``'s arguments of each (the registry's defaults).
PHYSICS_DEFAULTS = {"features": "q,qd,qdd", "identification": "consistent"}
HYBRID_DEFAULTS = {"identification": "consistent"}
ARM_DEFAULTS = {"identification": "consistent"}

DRIVE_GAINS = TrainOption(
    "drive_gains", default="fixed", choices=("fixed", "identify"), scope="on joint torques",
    description="joint-torque targets with {robot}: 'identify' when they are only "
                "proportional to the torques (motor currents, as UR's CB3 driver publishes in "
                "effort, or another sign convention): a gain per joint is identified with the "
                "arm's parameters")
IDENTIFY_MOUNTING = TrainOption(
    "identify_mounting", default=False, kind=bool,
    scope="on a wrench (the sensor's mounting rotation)",
    description="physics/hybrid on a wrench: also identify the sensor's mounting rotation "
                "(the wrench is then reported in the model's frame S)")
IDENTIFY_CROSSTALK = TrainOption(
    "identify_crosstalk", default=False, kind=bool,
    scope="on a wrench (the sensor calibration's cross-talk)",
    description="physics/hybrid on a wrench, dynamic model: also identify the sensor "
                "calibration's cross-talk (the reading matrix's off-diagonal entries, each "
                "with a prior of ±2 %)")
WEIGHT_WITHOUT_INERTIA = TrainOption(
    "weight_without_inertia", default=False, kind=bool,
    scope="on a wrench (a weight the tool carries without its inertia)",
    description="physics/hybrid on a wrench, dynamic model: also identify a weight the tool "
                "carries without its inertia (a hanging cable), 4 parameters")
TETHER = TrainOption(
    "tether", default=None, metavar="auto|world|JOINT",
    scope="on a wrench (a cable tethered to the tool)",
    description="physics/hybrid on a wrench, dynamic model, with {weight_without_inertia}: "
                "also identify a cable tethered to the tool, its other end fixed after joint "
                "JOINT or on the world ('auto': the frame that explains the data best), 2 "
                "parameters and its geometry")
#: The options of physics and hybrid (arm takes DRIVE_GAINS only).
PAYLOAD_OPTIONS = (DRIVE_GAINS, IDENTIFY_MOUNTING, IDENTIFY_CROSSTALK, WEIGHT_WITHOUT_INERTIA,
                   TETHER)
_PAYLOAD_KINDS = ("physics", "hybrid")
#: The IMU model's options: the payload's (it is on a wrench only: no drive gains).
IMU_PAYLOAD_OPTIONS = tuple(o for o in PAYLOAD_OPTIONS if o is not DRIVE_GAINS)


def make_physics(request: BuildRequest):
    """The payload model on a wrench; the arm's model on joint torques."""
    _refuse_wrench_options_on_torques(request)
    if not request.on_wrench:
        return make_arm(request)
    if not is_wrench(request.target_names):
        raise wrench_only_error(request.kind, request.target_names)
    return payload_model(request, request.features or "q,qd,qdd")


def make_imu_physics(request: BuildRequest):
    """The payload model with its kinematics from an IMU at the sensor (dynamic, on a
    wrench; :class:`~.imu_physics.ImuPayloadCompensator`), with the payload options and robot
    of :func:`make_physics`."""
    if not is_wrench(request.target_names):
        raise wrench_only_error(request.kind, request.target_names)
    if request.features not in (None, "q,qd,qdd"):
        raise ConfigError(f"{option_name('kind')} imu-physics takes "
                          f"{option_name('features')} q,qd,qdd (it is the dynamic model; "
                          "the IMU gives its motion terms)")
    physics = payload_model(request, "q,qd,qdd")
    return ImuPayloadCompensator(**physics.get_params(deep=False))


def make_hybrid(request: BuildRequest):
    """Physics (the payload model, dynamic; or the arm's model on joint torques) plus a
    forest on its residual, on `request.features` (default: q on a wrench, q,qd,qdd on joint
    torques)."""
    _refuse_wrench_options_on_torques(request)
    if not request.on_wrench:
        physics = make_arm(request)
        base = joint_torque_residual()
    elif not is_wrench(request.target_names):
        raise wrench_only_error(request.kind, request.target_names)
    else:
        physics = payload_model(request, "q,qd,qdd")
        base = default_residual()
    # The library's default residual (one source for `train` and Python), on the features asked.
    residual = base.set_params(features=request.features or base.features,
                               random_state=request.seed)
    return HybridCompensator(**{**HYBRID_DEFAULTS, "physics": physics, "residual": residual})


def make_arm_entry(request: BuildRequest):
    """The arm's model on joint torques; on other targets, its defaults (it then has no
    robot, which its fit refuses)."""
    if not request.on_wrench:
        return make_arm(request)
    features = {"features": request.features} if request.features else {}
    return ArmDynamicsCompensator(**{**ARM_DEFAULTS, **features})


def make_arm(request: BuildRequest) -> ArmDynamicsCompensator:
    """The arm's rigid-body torque model on the robot of `request`."""
    robot = request.robot
    if robot.robot is None:
        raise ConfigError(f"{option_name('kind')} {request.kind} on joint torques needs "
                          f"{option_name('robot')} FILE (the arm's URDF/SDF), or "
                          f"{option_name('robot')} {BUILTIN_ROBOT} for the simulated arm")
    if robot.joint_mapping():
        raise ConfigError(f"{option_name('joints')}/{option_name('fixed_joints')} are for the "
                          "payload model (a wrench); the whole arm's torque model needs a "
                          "robot description of the log's joints alone")
    options = {**ARM_DEFAULTS, "drive_gains": request.options.get("drive_gains", "fixed")}
    if robot.is_simulated_arm:
        description = robot.simulated_arm()
        return ArmDynamicsCompensator(robot=description.model,
                                      package_xmls=description.package_xmls, **options)
    return ArmDynamicsCompensator(robot=robot.robot_file(), base_frame=robot.base_frame,
                                  **options)


def payload_model(request: BuildRequest, features: str) -> PhysicsPayloadCompensator:
    """The payload model with `features` (q: static, gravity only; q,qd,qdd: dynamic) on the
    robot of `request`."""
    robot = request.robot
    identify_mounting = bool(request.options.get("identify_mounting", False))
    weight_without_inertia = bool(request.options.get("weight_without_inertia", False))
    identify_crosstalk = bool(request.options.get("identify_crosstalk", False))
    tether = request.options.get("tether") or None
    if robot.robot is None:
        raise ConfigError(f"{option_name('kind')} {request.kind} needs {option_name('robot')} "
                          f"FILE (URDF/SDF) with {option_name('sensor_frame')} NAME, or "
                          f"{option_name('robot')} {BUILTIN_ROBOT} for the simulated arm")
    if features == "q,qd":
        raise ConfigError(f"physics takes {option_name('features')} q (static: gravity only) "
                          "or q,qd,qdd")
    mode = "static" if features == "q" else "dynamic"
    _refuse_dynamic_options_when_static(mode, request.options)
    if tether and not (weight_without_inertia and mode == "dynamic"):
        raise ConfigError(f"{option_name('tether')} needs "
                          f"{option_name('weight_without_inertia')} and "
                          f"{option_name('features')} q,qd,qdd (a cable's hanging weight is "
                          "a weight without inertia, which only accelerations tell from the "
                          "tool's mass)")
    settings = {**PHYSICS_DEFAULTS, "features": features, "mode": mode,
                "identify_mounting": identify_mounting, "identify_crosstalk": identify_crosstalk,
                "weight_without_inertia": weight_without_inertia, "tether": tether}
    if robot.is_simulated_arm and robot.joint_mapping():
        raise ConfigError(f"{option_name('joints')}/{option_name('fixed_joints')} need "
                          f"{option_name('robot')} FILE (the simulated arm's data holds its "
                          f"joints: {option_name('robot')} {BUILTIN_ROBOT} takes them as they "
                          "are)")
    if robot.is_simulated_arm:
        # The arm of the scenario that made the data (a collect dataset stores it), as a
        # robot description; the shipped default arm is robot=None.
        description = robot.simulated_arm()
        if description == ftdrake_arm():
            return PhysicsPayloadCompensator(**settings)
        return PhysicsPayloadCompensator(robot=description.model,
                                         sensor_frame=description.sensor_frame,
                                         package_xmls=description.package_xmls, **settings)
    path = robot.robot_file()
    if not robot.sensor_frame:
        raise ConfigError(f"{option_name('robot')} {Path(robot.robot)} needs "
                          f"{option_name('sensor_frame')} (the frame of the targets)")
    return PhysicsPayloadCompensator(robot=path, sensor_frame=robot.sensor_frame,
                                     base_frame=robot.base_frame, **robot.joint_mapping(),
                                     **settings)


#: Options of the dynamic payload model only, and what a static model's user can do instead.
_DYNAMIC_ONLY = {
    "identify_mounting": "{identify_mounting} needs {features} q,qd,qdd (the dynamic "
                         "model); calibrate identifies it from static poses",
    "identify_crosstalk": "{identify_crosstalk} needs {features} q,qd,qdd (the dynamic "
                          "model); calibrate with {correction} full identifies it from "
                          "static poses with known loads",
    "weight_without_inertia": "{weight_without_inertia} needs {features} q,qd,qdd (only "
                              "accelerations tell a weight without inertia from the tool's "
                              "mass)",
}


def _refuse_dynamic_options_when_static(mode: str, options) -> None:
    for name, message in _DYNAMIC_ONLY.items():
        if mode == "static" and options.get(name, False):
            raise ConfigError(options_named(message))


def _refuse_wrench_options_on_torques(request: BuildRequest) -> None:
    if request.on_wrench:
        return
    for option in (IDENTIFY_MOUNTING, IDENTIFY_CROSSTALK, WEIGHT_WITHOUT_INERTIA, TETHER):
        if option.given(request.options.get(option.name)):
            raise option.misuse(_PAYLOAD_KINDS)
