"""What a compensator is built from for training: the targets, a robot description and the
options its registry entry offers.

A registry entry (:mod:`ftdrake.compensation.estimators.registry`) builds its unfitted compensator
from a :class:`BuildRequest`: the feature set, a random seed, the names of the targets (a wrench
or joint torques, see :func:`is_wrench`), a :class:`RobotOptions` and the values of the
entry's own :class:`TrainOption` s, which ``ftdrake train`` offers as flags. Errors name the
``train`` flag that fixes them.
"""

from __future__ import annotations

import dataclasses as dc
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ...config import parse_config
from ...conventions import WRENCH_AXES
from ...errors import ConfigError, RobotModelError, option_name
from ...physics.robot import (
    RobotDescription,
    fixed_joint_values,
    ftdrake_arm,
    joint_mapping_file,
    joint_names,
)
from ...physics.scenario_robot import robot_description

BUILTIN_ROBOT = "ftdrake"  # RobotOptions.robot naming ftdrake's simulated arm


@dc.dataclass(frozen=True)
class RobotOptions:
    """The robot description a robot-based compensator identifies its model on.

    robot: URDF/SDF file, or ``"ftdrake"`` for the simulated arm (the arm of a ``collect``
    dataset's scenario, `scenario_yaml`, else the default arm); None: no robot.
    sensor_frame: frame S of the targets in `robot`.
    base_frame: frame of `robot` welded to the world (default: its root).
    scenario_yaml: the scenario a ``collect`` dataset was simulated with (its YAML text).
    joints: the joints of `robot` the log's position columns hold, in their order (names, one
      comma-separated string, or a YAML file of ``joints: [...]`` and optionally
      ``fixed_joints: {...}``); None: every joint of `robot`, in its order.
    fixed_joints: where `robot`'s other joints stand: a mapping name →
      rad or m, ``"a=0.2,b=0.01"`` or a YAML file of such a mapping; unnamed joints stand at 0.
    """

    robot: str | None = None
    sensor_frame: str | None = None
    base_frame: str | None = None
    scenario_yaml: str | None = None
    joints: str | tuple[str, ...] | None = None
    fixed_joints: object = None

    def joint_mapping(self) -> dict:
        """The payload model's ``joints``/``fixed_joints`` parameters (empty when none are
        given): the fixed positions read now (a YAML file too), so the model keeps them."""
        if self.joints is None and self.fixed_joints is None:
            return {}
        joints, fixed = self.joints, dict(fixed_joint_values(self.fixed_joints))
        if isinstance(joints, str) and joints.endswith((".yaml", ".yml")):
            joints, in_file = joint_mapping_file(joints)
            fixed = {**dict(in_file), **fixed}  # fixed_joints given overrides the file's
        if joints is None:
            raise ConfigError(f"{option_name('fixed_joints')} needs {option_name('joints')} (the "
                              "joints the log holds, in the order of its position columns)")
        return {"joints": joint_names(joints), "fixed_joints": fixed or None}

    @property
    def is_simulated_arm(self) -> bool:
        """Whether `robot` names ftdrake's simulated arm."""
        return self.robot == BUILTIN_ROBOT

    def simulated_arm(self) -> RobotDescription:
        """The arm of the scenario that made the data (`scenario_yaml`), else ftdrake's
        default arm."""
        if self.scenario_yaml:
            return robot_description(parse_config(self.scenario_yaml).models)
        return ftdrake_arm()

    def robot_file(self) -> str:
        """`robot` as an absolute path; a RobotModelError when there is no such file."""
        path = Path(self.robot)
        if not path.is_file():
            raise RobotModelError(f"{option_name('robot')} {path}: no such file")
        return str(path.resolve())


@dc.dataclass(frozen=True)
class TrainOption:
    """One option a registry entry reads when it builds its compensator (a
    :attr:`~ftdrake.training.TrainOptions.model_options` entry; ``ftdrake train`` offers it
    as a flag, a switch when `kind` is bool).

    name: the keyword in :attr:`BuildRequest.options` (``identify_mounting``).
    description: what it does; other options in it are written ``{name}``, filled by
      :meth:`describe`.
    default: its value when not given; a value other than this is "given".
    kind: the value's type (bool: a switch, given by its presence).
    choices, metavar: the values it takes and how help shows them.
    scope: when it applies, for the error that refuses it elsewhere (e.g. "on a wrench (the
      sensor's mounting rotation)").
    """

    name: str
    description: str
    default: Any = None
    kind: type = str
    choices: tuple | None = None
    metavar: str | None = None
    scope: str = ""

    def describe(self, spell=None) -> str:
        """:attr:`description` with each ``{option}`` named by `spell` (default
        :func:`~ftdrake.errors.option_name`: the name in Python, the flag on the command
        line)."""
        return options_named(self.description, spell)

    def given(self, value) -> bool:
        """Whether `value` differs from the default (the user asked for something)."""
        return value is not None and value != self.default

    def misuse(self, owners) -> ConfigError:
        """The error for this option given to a model that does not take it: it names the
        models (registry names `owners`) that do."""
        scope = f" {self.scope}" if self.scope else ""
        return ConfigError(f"{option_name(self.name)} is for {option_name('kind')} "
                           f"{join_or(owners)}{scope}")


def options_named(text: str, spell=None) -> str:
    """`text` with each ``{option}`` in it named by `spell` (default
    :func:`~ftdrake.errors.option_name`)."""
    return text.format_map(_Spelled(spell or option_name))


class _Spelled(dict):
    """``str.format_map``'s mapping: an option's name → how `spell` names it."""

    def __init__(self, spell):
        super().__init__()
        self.spell = spell

    def __missing__(self, key: str) -> str:
        return self.spell(key)


@dc.dataclass(frozen=True)
class BuildRequest:
    """What an entry builds its unfitted compensator for.

    kind: the registry name asked for (errors name it as the option ``kind``).
    features: ``q``, ``q,qd`` or ``q,qd,qdd``; None for the entry's default.
    seed: random state of the models that have one.
    target_names: the data's targets (a wrench, :func:`is_wrench`, or anything else).
    robot: the robot description of robot-based entries.
    options: the values of the entry's :class:`TrainOption` s (every one present).
    """

    kind: str
    features: str | None = None
    seed: int = 0
    target_names: tuple[str, ...] = ()
    robot: RobotOptions = RobotOptions()
    options: Mapping[str, Any] = dc.field(default_factory=dict)

    @property
    def on_wrench(self) -> bool:
        """Whether the targets are a wrench (or no targets were named)."""
        return not self.target_names or is_wrench(self.target_names)


def is_wrench(names) -> bool:
    """True for 6 names ending in Fx, Fy, Fz, Tx, Ty, Tz (or force_x … torque_z), in order."""
    if len(names) != 6:
        return False
    aliases = [(a.lower(), ("force" if a[0] == "F" else "torque") + a[1]) for a in WRENCH_AXES]
    squashed = [re.sub(r"[^a-z]", "", n.lower()) for n in names]
    return all(s.endswith(alias) for s, alias in zip(squashed, aliases, strict=True))


def same_targets(model_names, data_names) -> bool:
    """Whether a model's targets and a log's are the same outputs: equal names, or both a
    wrench in the same axis order (``Fx … Tz`` as ``calibrate`` names them, ``meas_Fx …``)."""
    model_names, data_names = list(model_names), list(data_names)
    return model_names == data_names or (is_wrench(model_names) and is_wrench(data_names))


def join_or(names) -> str:
    """``["a"]`` → ``"a"``; ``["a", "b", "c"]`` → ``"a, b or c"``."""
    names = list(names)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def wrench_only_error(kind: str, target_names) -> ConfigError:
    """The error of a wrench-only model asked to fit other targets."""
    return ConfigError(
        f"{option_name('kind')} {kind} predicts a wrench: 6 targets named *Fx, *Fy, *Fz, *Tx, "
        f"*Ty, *Tz (N, N·m) in the sensor frame; got {list(target_names)}. Joint torques need "
        f"rf, svr, gpr, or arm/physics/hybrid with {option_name('robot')} (or choose the "
        f"wrench columns with {option_name('read.targets')})"
    )
