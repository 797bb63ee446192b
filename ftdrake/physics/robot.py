"""Robot descriptions: the kinematic chain a physics model identifies its payload on.

A :class:`RobotDescription` names a robot model — a URDF or SDF file, a Drake model-directives
file (``.dmd.yaml``), a ``package://`` URL of either, or model-directives text — and the frame
S of the F/T sensor in it. It is all a physics compensator needs: no simulation, no scenario.
``package://ftdrake/...`` resolves offline to ftdrake's shipped models (``models/package.xml``);
``package_xmls`` add the user's own packages.

A fitted physics model carries its robot inside its file (:func:`embed_model`): a URDF or SDF
file's text replaces its path, so the model loads on another computer; the URDF's meshes are
not needed (a kinematics-only plant registers no geometry).

ftdrake's simulated arm is described by :func:`ftdrake_arm` (the SDA10D-like arm with the
sensor and tool welded to its flange, as :func:`ftdrake.sim.scene.add_scene` builds it);
``physics.scenario_robot.robot_description(config.models)`` gives the description of any
scenario's arm.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses as dc
import difflib
import hashlib
import logging
import warnings
from pathlib import Path

import numpy as np
import yaml
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import FrameIndex

from ..assets import offline_parser
from ..errors import RobotModelError, option_name, spelled

DIRECTIVES_PREFIX = "directives:"
# The opening tag of a robot description held as text, and its format for Drake's parser.
_INLINE_TAGS = (("<robot", "urdf"), ("<sdf", "sdf"))
_SHIPPED = "package://ftdrake/"


@dc.dataclass(frozen=True)
class RobotDescription:
    """A robot model and the sensor frame S in it.

    model: a file path or ``package://`` URL (URDF, SDF, ``.dmd.yaml``), model-directives
      text starting with ``directives:``, or a URDF/SDF's text (see :func:`embed_model`).
    sensor_frame: frame S, as ``"model::frame"`` or a frame name unique in the plant.
    base_frame: a frame to weld to the world (None: the model is already welded or fixed,
      as model directives and most URDFs with a world joint are).
    package_xmls: extra package.xml files for the model's ``package://`` URLs.
    joints: the joints a log's position columns hold, in their order (a log of 8 joints on
      a description of 24: torso, arm, head, fingers); () when the rows hold every joint of
      the model in its own order.
    fixed_joints: ``((name, value), …)``, where the joints not in `joints` stand (rad for
      revolute, m for prismatic); a joint given in neither stands at 0.
    """

    model: str
    sensor_frame: str
    base_frame: str | None = None
    package_xmls: tuple[str, ...] = ()
    joints: tuple[str, ...] = ()
    fixed_joints: tuple[tuple[str, float], ...] = ()
    #: What messages call the model when it is held as text (the file it was read from).
    name: str | None = dc.field(default=None, compare=False)

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
        label = model_label(self.model)
        return f"{self.name!r} {label}" if self.name and label.startswith("(") else label

    def _frame(self, plant, name: str, what: str):
        model, _, frame = name.rpartition("::")
        try:
            if model:
                return plant.GetFrameByName(frame, plant.GetModelInstanceByName(model))
            return plant.GetFrameByName(frame)
        except RuntimeError:
            raise RobotModelError(
                f"robot model {self.label} has no {what} named {name!r}; "
                f"{frames_closest_first(plant, name)}"
            ) from None


def frame_names(plant) -> list[str]:
    """The frames of `plant` by the names a sensor or base frame is given by: the frame's own
    name when it is unique in the plant, else ``model::frame`` (Drake's internal
    ``__model__`` frames and the world left out)."""
    frames = [plant.get_frame(FrameIndex(i)) for i in range(plant.num_frames())]
    frames = [f for f in frames if not f.name().startswith("__") and f.name() != "world"]
    counts: dict[str, int] = {}
    for f in frames:
        counts[f.name()] = counts.get(f.name(), 0) + 1
    return [f.name() if counts[f.name()] == 1
            else f"{plant.GetModelInstanceName(f.model_instance())}::{f.name()}" for f in frames]


def frames_closest_first(plant, name: str, shown: int = 12,
                         heading: str | None = None) -> str:
    """``"its frames, closest to NAME first: a, b, …"``: the frames of `plant`, those most
    like `name` first (difflib's ratio), at most `shown` of them; `heading` replaces the words
    before the colon."""
    names = frame_names(plant)
    ranked = sorted(names, key=lambda n: -difflib.SequenceMatcher(
        None, name.lower(), n.lower()).ratio())
    more = f", … ({len(ranked) - shown} more)" if len(ranked) > shown else ""
    heading = heading or f"its frames, closest to {name!r} first"
    return f"{heading}: {', '.join(ranked[:shown])}{more}"


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
    """A short name of a robot model for messages (text held inline is not one)."""
    if model.lstrip().startswith(DIRECTIVES_PREFIX):
        return "(model directives)"
    kind = inline_format(model)
    if kind is not None:
        return f"(embedded {kind.upper()}, {len(model)} characters)"
    return repr(model)


def inline_format(model: str) -> str | None:
    """``"urdf"`` or ``"sdf"`` when `model` is the description's text itself, else None."""
    head = model.lstrip()
    if not head.startswith("<"):
        return None
    first = min(((head.find(tag), kind) for tag, kind in _INLINE_TAGS if tag in head),
                default=None)
    return first[1] if first else None


def embed_model(model: str, package_xmls=()) -> tuple[str, bool]:
    """`model` as text that loads without the file it came from, and whether it does.

    A URDF/SDF file or ``package://`` URL becomes its text (portable unless an SDF
    ``<include>``s other files); model directives (text or a ``.dmd.yaml`` file) stay as they
    are, portable when every model they add is one of ftdrake's (``package://ftdrake/``).
    Text already inline is returned as it is. RobotModelError names a file that cannot be read.
    """
    if inline_format(model) is not None:
        return model, "<include" not in model
    if model.lstrip().startswith(DIRECTIVES_PREFIX):
        return model, _directives_portable(model)
    path = _resolve(model, package_xmls)
    if not Path(path).is_file():
        raise RobotModelError(f"robot model {model!r}: no such file")
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise RobotModelError(f"robot model {model!r}: cannot read {path}: {e}") from None
    if path.endswith((".dmd.yaml", ".yaml")):
        return text, _directives_portable(text)
    if inline_format(text) is None:
        raise RobotModelError(f"robot model {model!r}: {path} is neither URDF nor SDF")
    return text, "<include" not in text


def _resolve(model: str, package_xmls) -> str:
    """The file behind a path or ``package://`` URL."""
    if "://" not in model:
        return model
    plant = MultibodyPlant(0.0)
    try:
        return offline_parser(plant, package_xmls).package_map().ResolveUrl(model)
    except (FileNotFoundError, RuntimeError) as e:
        raise RobotModelError(f"robot model {model!r}: {e}") from None


def _directives_portable(text: str) -> bool:
    files = [line.split("file:", 1)[1].strip() for line in text.splitlines()
             if line.strip().startswith("file:")]
    return all(f.strip("'\"").startswith(_SHIPPED) for f in files)


def add_robot_model(plant, model: str, package_xmls=()) -> None:
    """Parses `model` (a file, a ``package://`` URL or model-directives text) into `plant`
    with the offline parser (every model from ``models/``, nothing downloaded). Raises
    RobotModelError naming the model and what is wrong with it."""
    label = model_label(model)
    try:
        parser = offline_parser(plant, package_xmls)
    except FileNotFoundError as e:
        raise RobotModelError(f"robot {label}: {e}") from None
    with _parser_warnings_summarised(model, label):
        _parse(parser, model, label)


def _parse(parser, model: str, label: str) -> None:
    try:
        if model.lstrip().startswith(DIRECTIVES_PREFIX):
            parser.AddModelsFromString(model, "dmd.yaml")
        elif inline_format(model) is not None:
            parser.AddModelsFromString(model, inline_format(model))
        elif "://" in model:
            parser.AddModels(url=model)
        elif not Path(model).is_file():
            raise RobotModelError(f"robot model {model!r}: no such file")
        else:
            parser.AddModels(file_name=model)
    except RuntimeError as e:  # Drake's parser reports every problem as RuntimeError
        raise RobotModelError(f"cannot load robot model {label}: {e}") from None


class RobotDescriptionWarning(UserWarning):
    """Drake's parser warned about a robot description (tags it ignores, joint friction …):
    summarised once per description and process."""


#: The logger Drake's parser warnings go to after their summary (INFO; ``--verbose`` shows it).
PARSER_LOGGER = "ftdrake.robot_parser"
_SHOW_PARSER_WARNINGS: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "ftdrake_show_parser_warnings", default=False)
_SUMMARISED: set[str] = set()  # descriptions whose parser warnings were summarised


@contextlib.contextmanager
def show_parser_warnings(show: bool = True):
    """Within the block (``ftdrake --verbose``), every parser warning of a robot description
    prints on stderr after its summary."""
    token = _SHOW_PARSER_WARNINGS.set(bool(show))
    try:
        yield
    finally:
        _SHOW_PARSER_WARNINGS.reset(token)


class _Collect(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def _parser_warnings_summarised(model: str, label: str):
    """Drake's parser warnings (Python logger ``drake``) while parsing `model`, held back and
    summarised in one :class:`RobotDescriptionWarning` the first time the process parses
    this description; each is logged at INFO on :data:`PARSER_LOGGER`."""
    drake = logging.getLogger("drake")
    collect, propagate = _Collect(), drake.propagate
    drake.addHandler(collect)
    drake.propagate = False
    try:
        yield
    finally:
        drake.removeHandler(collect)
        drake.propagate = propagate
    if not collect.messages:
        return
    key = hashlib.sha256(model.encode()).hexdigest()
    if key in _SUMMARISED:
        return
    _SUMMARISED.add(key)
    messages = [m.split(" warning: ", 1)[-1] for m in collect.messages]
    how = spelled(f"logging.getLogger({PARSER_LOGGER!r}) at INFO shows them",
                  "--verbose shows them")
    warnings.warn(RobotDescriptionWarning(
        f"the robot description {label} gave {len(messages)} parser warning(s) (e.g. "
        f"{messages[0]}); ftdrake does not need what they are about; {how}"), stacklevel=4)
    log = logging.getLogger(PARSER_LOGGER)
    show = _SHOW_PARSER_WARNINGS.get()
    handler = logging.StreamHandler() if show else None
    if handler is not None:
        handler.setFormatter(logging.Formatter("drake parser: %(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)
    try:
        for message in collect.messages:
            log.info(message)
    finally:
        if handler is not None:
            log.removeHandler(handler)


def floating_base_hint(plant) -> str:
    """What to say of a plant with more positions than velocities: which body floats and the
    option (``base_frame``, :func:`~ftdrake.errors.option_name`) that welds it to the world."""
    floating = [plant.get_joint(j).child_body().name() for j in plant.GetJointIndices()
                if "floating" in plant.get_joint(j).type_name()]
    if not floating:
        return "a floating body?"
    return (f"{', '.join(repr(b) for b in floating)} floats: weld it to the world with "
            f"{option_name('base_frame')} {floating[0]}")



def movable_joint_names(plant) -> list[str]:
    """The names of the joints of finalized `plant` that have coordinates, in the order of
    the plant's q."""
    joints = [plant.get_joint(j) for j in plant.GetJointIndices()]
    moving = [j for j in joints if j.num_positions() > 0]
    return [j.name() for j in sorted(moving, key=lambda j: j.position_start())]


def check_joint_names(plant, description: RobotDescription) -> None:
    """Raises RobotModelError when `description.joints` or its fixed joints name a joint the
    model does not have (or a joint twice); the message lists the model's joints."""
    known = movable_joint_names(plant)
    listed = f"the model's joints: {', '.join(known)}"
    unknown = [n for n in description.joints if n not in known]
    if unknown:
        raise RobotModelError(
            f"{option_name('joints')} names {unknown} that robot model {description.label} "
            f"does not have; {listed}")
    repeated = sorted({n for n in description.joints if description.joints.count(n) > 1})
    if repeated:
        raise RobotModelError(f"{option_name('joints')} names {repeated} more than once")
    fixed = [name for name, _ in description.fixed_joints]
    unknown = [n for n in fixed if n not in known]
    if unknown:
        raise RobotModelError(
            f"{option_name('fixed_joints')} names {unknown} that robot model "
            f"{description.label} does not have; {listed}")
    both = [n for n in fixed if n in description.joints]
    if both:
        raise RobotModelError(
            f"{both}: both a log's joint ({option_name('joints')}) and fixed "
            f"({option_name('fixed_joints')}); keep one")


def joint_count_message(plant, n_data: int, label: str) -> str:
    """What to say when the rows hold `n_data` joints and the model has others: the model's
    joint names, and the options that name the log's joints and fix the others."""
    known = movable_joint_names(plant)
    return (f"the data has {n_data} joints; the robot model has {len(known)} "
            f"({', '.join(known)}; {label}): name the log's joints in the order of its position "
            f"columns with {option_name('joints')} NAME,NAME,... and fix the others with "
            f"{option_name('fixed_joints')} NAME=VALUE,... (default 0)")


def joint_names(spec) -> tuple[str, ...]:
    """Joint names from ``"joint_s,joint_l"`` or a sequence, blanks dropped; () for None."""
    if spec is None:
        return ()
    if isinstance(spec, str):
        spec = spec.split(",")
    return tuple(str(j).strip() for j in spec if str(j).strip())


def fixed_joint_values(spec) -> tuple[tuple[str, float], ...]:
    """Fixed joint positions as ``((name, value), …)`` from a mapping, a sequence of pairs,
    ``"torso=0.2,finger_l=0.01"`` or the path of a YAML file holding a mapping name → value
    (rad for revolute joints, m for prismatic). Raises RobotModelError naming a bad entry."""
    if spec is None or spec == "":
        return ()
    if isinstance(spec, str):
        spec = _fixed_joints_text(spec)
    items = spec.items() if hasattr(spec, "items") else spec
    out = []
    for entry in items:
        try:
            name, value = entry
            value = float(value)
        except (TypeError, ValueError):
            raise RobotModelError(f"fixed joints: {entry!r} is not NAME=VALUE (a number: rad "
                                  "for revolute, m for prismatic)") from None
        if not np.isfinite(value):
            raise RobotModelError(f"fixed joints: {name}={value} is not a finite number")
        out.append((str(name), value))
    return tuple(out)


def joint_mapping_file(path) -> tuple[tuple[str, ...], tuple[tuple[str, float], ...]]:
    """(joints, fixed joints) from a YAML file holding ``joints: [NAME, …]`` (the log's
    joints, in the order of its position columns) and optionally ``fixed_joints: {NAME:
    VALUE, …}`` (rad, or m for prismatic joints). Raises RobotModelError naming what is wrong."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as e:
        raise RobotModelError(f"{option_name('joints')} {path}: cannot read it as YAML: "
                              f"{e}") from None
    joints = data.get("joints") if isinstance(data, dict) else None
    if not (isinstance(joints, list) and joints and all(isinstance(j, str) for j in joints)):
        raise RobotModelError(f"{option_name('joints')} {path}: must hold 'joints: [NAME, "
                              "...]' (the log's "
                              "joints, in the order of its position columns) and optionally "
                              "'fixed_joints: {NAME: VALUE}'")
    unknown = sorted(set(data) - {"joints", "fixed_joints"})
    if unknown:
        raise RobotModelError(f"{option_name('joints')} {path}: unknown keys {unknown}; it "
                              "holds joints and fixed_joints")
    return tuple(joints), fixed_joint_values(data.get("fixed_joints") or {})


def _fixed_joints_text(text: str):
    """``"a=1,b=2"`` → pairs; a YAML file's mapping → its items."""
    if "=" not in text and Path(text).is_file():
        try:
            data = yaml.safe_load(Path(text).read_text())
        except yaml.YAMLError as e:
            raise RobotModelError(f"fixed joints: {text} is not YAML: {e}") from None
        if not isinstance(data, dict):
            raise RobotModelError(f"fixed joints: {text} must hold a mapping joint name → "
                                  "value (rad or m)")
        return data
    pairs = [p.strip() for p in text.split(",") if p.strip()]
    bad = [p for p in pairs if p.count("=") != 1]
    if bad:
        raise RobotModelError(f"fixed joints: {bad[0]!r} is not NAME=VALUE (or a YAML file "
                              "holding a mapping)")
    return [tuple(s.strip() for s in p.split("=")) for p in pairs]
