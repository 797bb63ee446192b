"""The robot a physics-based compensator was fitted on, carried inside the fitted model.

A compensator built on a robot description (the payload model, the whole-arm model) names its
robot by a path (its ``robot`` parameter; a model file keeps only the file's name,
:func:`file_name_only`). When it is fitted the robot's text
is embedded (``robot_model_``, :func:`~ftdrake.physics.robot.embed_model`), so that a saved
model loads and predicts on another computer, from another folder, or after the URDF moved.
``robot_portable_`` says whether the embedded text needs nothing else (model directives that
add files outside ftdrake's models do).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from pydrake.multibody.plant import MultibodyPlant

from ...errors import RobotModelError
from ...physics.robot import (
    DIRECTIVES_PREFIX,
    RobotDescription,
    add_robot_model,
    embed_model,
    frames_closest_first,
)


def check_robot_frames(robot: str, sensor_frame: str | None, base_frame: str | None = None,
                       package_xmls=(), command: str = "train") -> None:
    """Before any data is read: the robot file `robot` (``--robot``) loads and has the frames
    ``--sensor-frame`` and ``--base-frame`` name. RobotModelError names the file, the flag and
    the model's frames, those closest to the name given first (none given: the frames by
    name)."""
    if not sensor_frame:
        plant = MultibodyPlant(0.0)
        add_robot_model(plant, str(robot), tuple(package_xmls))
        plant.Finalize()
        raise RobotModelError(
            f"{command} --robot {robot} needs --sensor-frame NAME (the frame S of the measured "
            f"wrench in {robot}); "
            f"{frames_closest_first(plant, 'sensor', heading='its frames, sensor-like first')}")
    description = RobotDescription(str(robot), sensor_frame, base_frame, tuple(package_xmls))
    try:
        description.build_plant()
    except RobotModelError as e:
        flag = "--base-frame" if "no base frame" in str(e) else "--sensor-frame"
        raise RobotModelError(f"{flag}: {e}") from None


def file_name_only(robot):
    """What a model file keeps of a `robot` parameter whose text the model embeds: a file
    path's name alone (``/home/me/arm.urdf`` → ``arm.urdf``: a user's folders do not travel
    with the files they share); ``package://`` URLs, model text and None as they are."""
    if robot is None:
        return None
    text = str(robot)
    if "://" in text or "\n" in text or text.lstrip().startswith(("<", DIRECTIVES_PREFIX)):
        return robot
    return Path(text).name


class CarriesRobot:
    """Mixin: ``robot``/``package_xmls`` parameters; the fitted model carries the robot.

    Subclasses call :meth:`_embed_robot` in ``fit`` and build their robot from
    :meth:`_robot_source`; :meth:`_build_robot` is whatever builds it (and raises
    RobotModelError when it cannot be built).
    """

    def _embed_robot(self) -> None:
        if self.robot is None:  # ftdrake's own arm, from the models shipped with ftdrake
            self.robot_model_, self.robot_portable_ = None, True
            return
        self.robot_model_, self.robot_portable_ = embed_model(str(self.robot),
                                                              tuple(self.package_xmls))

    def _robot_source(self) -> tuple[str, tuple]:
        """(model text or path, package.xml files) to build the robot from."""
        embedded = getattr(self, "robot_model_", None)
        if embedded is None:
            return str(self.robot), tuple(self.package_xmls)
        return embedded, (() if self.robot_portable_ else tuple(self.package_xmls))

    def robot_digest(self) -> str | None:
        """SHA-256 of the embedded robot text (None when the robot is ftdrake's own arm)."""
        embedded = getattr(self, "robot_model_", None)
        return hashlib.sha256(embedded.encode()).hexdigest() if embedded else None

    def check_robot(self) -> list[str]:
        """Builds the robot the model needs; returns notes for the user (an older model that
        named its robot by path gets it embedded now, when the path is there). Raises
        RobotModelError with the fix when the robot cannot be built."""
        notes = []
        if self.robot is not None and not hasattr(self, "robot_model_"):
            try:
                self._embed_robot()
            except RobotModelError as e:
                raise RobotModelError(
                    f"the model names its robot by path ({self.robot!r}) and does not carry "
                    f"it (saved before model files embedded their robot): {e}. Load it once "
                    "where that file exists and save it again (ftdrake.save_model) to embed "
                    "the robot") from None
            notes.append(f"the robot {self.robot!r} was embedded now; save the model again "
                         "to make its file portable")
        if getattr(self, "robot_portable_", True) is False:
            notes.append(f"the robot's model directives ({self.robot!r}) add files outside "
                         "ftdrake's models: the model needs them where it is loaded")
        self._build_robot()
        return notes

    def _build_robot(self) -> None:
        raise NotImplementedError
