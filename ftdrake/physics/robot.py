"""Robot descriptions: the kinematic chain a physics model identifies its payload on.

A :class:`RobotDescription` names a robot model — a URDF or SDF file, a Drake model-directives
file (``.dmd.yaml``), a ``package://`` URL of either, or model-directives text — and the frame
S of the F/T sensor in it. It is all a physics compensator needs: no simulation, no scenario.
``package://ftdrake/...`` resolves offline to ftdrake's shipped models (``models/package.xml``);
``package_xmls`` add the user's own packages.

ftdrake's simulated arm is described by :func:`ftdrake_arm` (the SDA10D-like arm with the
sensor and tool welded to its flange, as :func:`ftdrake.sim.scene.add_scene` builds it);
``physics.scenario_robot.robot_description(config)`` gives the description of any scenario's arm.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant

from ..assets import offline_parser
from ..errors import RobotModelError

DIRECTIVES_PREFIX = "directives:"


@dc.dataclass(frozen=True)
class RobotDescription:
    """A robot model and the sensor frame S in it.

    model: a file path or ``package://`` URL (URDF, SDF, ``.dmd.yaml``), or model-directives
      text starting with ``directives:``.
    sensor_frame: frame S, as ``"model::frame"`` or a frame name unique in the plant.
    base_frame: a frame to weld to the world (None: the model is already welded or fixed,
      as model directives and most URDFs with a world joint are).
    package_xmls: extra package.xml files for the model's ``package://`` URLs.
    """

    model: str
    sensor_frame: str
    base_frame: str | None = None
    package_xmls: tuple[str, ...] = ()

    def build_plant(self) -> tuple[MultibodyPlant, object]:
        """A finalized kinematics-only plant of the robot and its frame S.

        Raises RobotModelError naming the model and what is wrong with it.
        """
        plant = MultibodyPlant(0.0)
        add_robot_model(plant, self.model, self.package_xmls)
        frame_S = self._frame(plant, self.sensor_frame, "sensor frame")
        if self.base_frame:
            base = self._frame(plant, self.base_frame, "base frame")
            plant.WeldFrames(plant.world_frame(), base, RigidTransform())
        plant.Finalize()
        return plant, frame_S

    @property
    def label(self) -> str:
        """A short name for messages (directives text is not one)."""
        return model_label(self.model)

    def _frame(self, plant, name: str, what: str):
        model, _, frame = name.rpartition("::")
        try:
            if model:
                return plant.GetFrameByName(frame, plant.GetModelInstanceByName(model))
            return plant.GetFrameByName(frame)
        except RuntimeError:
            raise RobotModelError(
                f"robot model {self.label} has no {what} named {name!r}"
            ) from None


def arm_directives(arm: str, tool: str, arm_base_frame: str, flange_frame: str,
                   tool_mount_frame: str, p_WArmBase) -> str:
    """Model directives for an arm welded to the world at `p_WArmBase` (m) with a tool (sensor
    + gripper + workpiece) welded to its flange: the kinematics of the simulated robot."""
    x, y, z = (float(v) for v in np.asarray(p_WArmBase, dtype=float))
    return f"""{DIRECTIVES_PREFIX}
- add_model:
    name: arm
    file: {arm}
- add_weld:
    parent: world
    child: arm::{arm_base_frame}
    X_PC:
      translation: [{x!r}, {y!r}, {z!r}]
- add_model:
    name: tool
    file: {tool}
- add_weld:
    parent: arm::{flange_frame}
    child: tool::{tool_mount_frame}
"""


def ftdrake_arm() -> RobotDescription:
    """ftdrake's simulated arm with its default models; S is the sensor weld's child frame
    (at the gripper's body frame, ``models/ft_sensor_tool.sdf``)."""
    return RobotDescription(
        arm_directives("package://ftdrake/sda10d_arm.sdf", "package://ftdrake/ft_sensor_tool.sdf",
                       "arm_base", "flange", "ft_sensor", (0.0, 0.0, 0.95)),
        sensor_frame="tool::ft_sensor_weld_child",
    )


def model_label(model: str) -> str:
    """A short name of a robot model for messages (directives text is not one)."""
    if model.lstrip().startswith(DIRECTIVES_PREFIX):
        return "(model directives)"
    return repr(model)


def add_robot_model(plant, model: str, package_xmls=()) -> None:
    """Parses `model` (a file, a ``package://`` URL or model-directives text) into `plant`
    with the offline parser (every model from ``models/``, nothing downloaded). Raises
    RobotModelError naming the model and what is wrong with it."""
    label = model_label(model)
    try:
        parser = offline_parser(plant, package_xmls)
    except FileNotFoundError as e:
        raise RobotModelError(f"robot {label}: {e}") from None
    try:
        if model.lstrip().startswith(DIRECTIVES_PREFIX):
            parser.AddModelsFromString(model, "dmd.yaml")
        elif "://" in model:
            parser.AddModels(url=model)
        elif not Path(model).is_file():
            raise RobotModelError(f"robot model {model!r}: no such file")
        else:
            parser.AddModels(file_name=model)
    except RuntimeError as e:  # Drake's parser reports every problem as RuntimeError
        raise RobotModelError(f"cannot load robot model {label}: {e}") from None
