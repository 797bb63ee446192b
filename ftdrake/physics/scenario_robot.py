"""The scenario's robot without a simulation: model parsing with errors that name the config
field, the sensor weld, and :func:`robot_description` (what a physics compensator and the live
runtime's joint-state gravity need). ``sim.scene`` builds the full plant on the same helpers."""

from __future__ import annotations

from pathlib import Path

from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, WeldJoint

from ..assets import offline_parser
from ..config import ModelsConfig
from ..errors import ConfigError
from .robot import RobotDescription, arm_directives


def make_parser(plant: MultibodyPlant, models: ModelsConfig) -> Parser:
    """A parser that resolves package://ftdrake/ offline, plus the user's package.xml files."""
    try:
        return offline_parser(plant, models.package_xmls)
    except FileNotFoundError as e:
        raise ConfigError(f"scenario.models.package_xmls: {e}") from None


def add_model(parser: Parser, url: str, field: str) -> ModelInstanceIndex:
    """Adds one model by URL or path, with an error naming the config field on failure."""
    try:
        if "://" in url:
            instances = parser.AddModels(url=url)
        else:
            if not Path(url).is_file():
                raise ConfigError(f"scenario.models.{field}: no such model file {url!r}")
            instances = parser.AddModels(file_name=url)
    except ConfigError:
        raise
    except RuntimeError as e:  # Drake's parser reports every problem as RuntimeError
        raise ConfigError(f"scenario.models.{field}: cannot load {url!r}: {e}") from None
    if len(instances) != 1:
        raise ConfigError(f"scenario.models.{field}: {url!r} must hold exactly one model")
    return instances[0]


def robot_description(models: ModelsConfig) -> RobotDescription:
    """The kinematics of a scenario's robot (its ``models`` section) — arm, base pose, flange
    weld, sensor and tool — as a robot description a physics compensator can identify its
    payload on. Frame S is the sensor weld's child frame, as in the simulation."""
    plant = MultibodyPlant(0.0)
    tool = add_model(make_parser(plant, models), models.tool, "tool")
    joint = sensor_weld(plant, models.sensor_joint, tool)
    text = arm_directives(models.arm, models.tool, models.arm_base_frame, models.flange_frame,
                          models.tool_mount_frame, models.p_WArmBase)
    return RobotDescription(text, sensor_frame=f"tool::{joint.frame_on_child().name()}",
                            package_xmls=tuple(models.package_xmls))


def sensor_weld(plant: MultibodyPlant, name: str, instance=None) -> WeldJoint:
    """The weld joint named `name`; a clear error when it is missing or not a weld."""
    has = plant.HasJointNamed(name, instance) if instance is not None else plant.HasJointNamed(name)
    if not has:
        raise ConfigError(f"scenario.models.sensor_joint: no joint named {name!r} in the plant")
    joint = plant.GetJointByName(name, instance) if instance is not None else plant.GetJointByName(
        name
    )
    if not isinstance(joint, WeldJoint):
        raise ConfigError(
            f"scenario.models.sensor_joint: {name!r} is a {joint.type_name()} joint; "
            "an F/T sensor must be a weld"
        )
    return joint
