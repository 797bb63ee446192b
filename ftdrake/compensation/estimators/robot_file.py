"""The robot a physics-based compensator was fitted on, carried inside the fitted model.

A compensator built on a robot description (the payload model, the whole-arm model) names its
robot by a path (its ``robot`` parameter, stored as given). When it is fitted the robot's text
is embedded (``robot_model_``, :func:`~ftdrake.physics.robot.embed_model`), so that a saved
model loads and predicts on another computer, from another folder, or after the URDF moved.
``robot_portable_`` says whether the embedded text needs nothing else (model directives that
add files outside ftdrake's models do).
"""

from __future__ import annotations

import hashlib

from ...errors import RobotModelError
from ...physics.robot import embed_model


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
