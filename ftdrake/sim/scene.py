"""The MultibodyPlant: arm, F/T sensor weld, tool and environment, all from `models/`.

Nothing is fetched at run time: ``package://ftdrake/...`` resolves to the `models/` folder
shipped with ftdrake (its `package.xml`), and users can add their own package.xml files.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    ContactModel,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import (
    BodyIndex,
    FixedOffsetFrame,
    LinearSpringDamper,
    ModelInstanceIndex,
    SpatialInertia,
    WeldJoint,
)
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource

from ..config import ConfigError, ScenarioConfig, TaskConfig
from ..physics.scenario_robot import add_model, make_parser, sensor_weld
from ..systems.transmission import arm_actuators, configure_plant_transmission
from .cable import add_cable_spring, cable_weight_forces


@dc.dataclass
class Scene:
    """Handles into the plant that the rest of ftdrake needs."""

    plant: MultibodyPlant
    scene_graph: SceneGraph
    arm: ModelInstanceIndex
    tool: ModelInstanceIndex
    environment: ModelInstanceIndex
    sensor_joint: WeldJoint
    tool_bodies: list[BodyIndex]  # every body rigidly attached on the sensor's tool side
    environment_bodies: list[BodyIndex]
    cable: LinearSpringDamper | None  # the cable's spring, None when the cable is disabled
    task: TaskConfig = dc.field(default_factory=TaskConfig)  # names of the task's frames

    @property
    def sensor_frame(self):
        """Frame S: the sensor weld's child frame."""
        return self.sensor_joint.frame_on_child()

    def tool_tip_frame(self):
        """The frame ``task.tool_tip_frame`` of the tool model, on the sensor's tool side."""
        name = self.task.tool_tip_frame
        frame = self._task_frame(name, self.tool, "tool_tip_frame", "tool")
        if frame.body().index() not in self.tool_bodies:
            raise ConfigError(
                f"scenario.task.tool_tip_frame: frame {name!r} is on body "
                f"{frame.body().name()!r}, which is not on the sensor's tool side"
            )
        return frame

    def surface_frame(self, surface: str):
        """The frame of contact surface `surface` (a key of ``task.surfaces``) in the
        environment model; it must be fixed in the world."""
        if surface not in self.task.surfaces:
            raise ConfigError(
                f"scenario.trajectory.contact_target: {surface!r} is not a surface of "
                f"scenario.task.surfaces {sorted(self.task.surfaces)}"
            )
        name = self.task.surfaces[surface]
        frame = self._task_frame(name, self.environment, f"surfaces.{surface}", "environment")
        fixed = {body.index() for body in self.plant.GetBodiesWeldedTo(self.plant.world_body())}
        if frame.body().index() not in fixed:
            raise ConfigError(
                f"scenario.task.surfaces.{surface}: frame {name!r} is on body "
                f"{frame.body().name()!r}, which is not welded to the world"
            )
        return frame

    def _task_frame(self, name: str, instance, field: str, model: str):
        if not self.plant.HasFrameNamed(name, instance):
            raise ConfigError(
                f"scenario.task.{field}: no frame {name!r} in the {model} model "
                f"{self.plant.GetModelInstanceName(instance)!r} (scenario.models.{model})"
            )
        return self.plant.GetFrameByName(name, instance)


def add_scene(builder: DiagramBuilder, config: ScenarioConfig) -> Scene:
    """Adds plant + scene graph for `config` to `builder` and finalizes the plant.

    The scene includes the cable (its spring in the plant, its weight through the plant's
    applied-spatial-force input, which is therefore connected).
    """
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(
            time_step=config.time_step,
            discrete_contact_approximation=config.contact_approximation,
        ),
        builder,
    )
    plant.set_contact_model(ContactModel.kPoint)
    models = config.models
    parser = make_parser(plant, models)
    arm = add_model(parser, models.arm, "arm")
    tool = add_model(parser, models.tool, "tool")
    env = add_model(parser, models.environment, "environment")
    plant.WeldFrames(
        plant.world_frame(),
        _frame(plant, models.arm_base_frame, arm, "arm_base_frame"),
        RigidTransform(np.asarray(models.p_WArmBase, dtype=float)),
    )
    plant.WeldFrames(
        _frame(plant, models.flange_frame, arm, "flange_frame"),
        _frame(plant, models.tool_mount_frame, tool, "tool_mount_frame"),
    )
    joint = sensor_weld(plant, models.sensor_joint, tool)
    cable = (
        add_cable_spring(plant, arm, joint.frame_on_child(), config.cable)
        if config.cable.enabled else None
    )
    if config.transmission.enabled:  # the links' end of the gearbox springs
        configure_plant_transmission(plant, arm, config.transmission)
    plant.Finalize()
    _add_cable_weight(builder, plant, joint.frame_on_child(), config)
    if plant.num_positions(arm) != len(config.home_q):
        raise ConfigError(
            f"scenario.home_q: has {len(config.home_q)} entries but the arm has "
            f"{plant.num_positions(arm)} joints"
        )
    _filter_robot_self_collisions(plant, scene_graph, [arm, tool])
    return Scene(
        plant=plant,
        scene_graph=scene_graph,
        arm=arm,
        tool=tool,
        environment=env,
        sensor_joint=joint,
        tool_bodies=bodies_outboard_of(plant, joint),
        environment_bodies=list(plant.GetBodyIndices(env)),
        cable=cable,
        task=config.task,
    )


def _add_cable_weight(builder, plant, sensor_frame, config):
    """The cable's hanging weight: a constant force on the tool, into the plant's
    applied-spatial-force port (which the scene therefore occupies)."""
    weight = plant.get_applied_spatial_force_input_port().Allocate()  # the port's C++ type
    weight.set_value(cable_weight_forces(sensor_frame, config.cable))
    source = builder.AddNamedSystem("cable_weight", ConstantValueSource(weight))
    builder.Connect(source.get_output_port(), plant.get_applied_spatial_force_input_port())






def bodies_outboard_of(plant: MultibodyPlant, joint) -> list[BodyIndex]:
    """Bodies on the child side of `joint` that are welded to its child (the sensed load)."""
    child = joint.child_body()
    welded = plant.GetBodiesWeldedTo(child)
    # GetBodiesWeldedTo also returns the parent side if it is welded; keep only bodies whose
    # path to the child body does not pass through the sensor joint.
    result, frontier = {child.index()}, [child.index()]
    while frontier:
        current = frontier.pop()
        for j in plant.GetJointIndices():
            other = plant.get_joint(j)
            if other.index() == joint.index() or not isinstance(other, WeldJoint):
                continue
            pair = (other.parent_body().index(), other.child_body().index())
            if current in pair:
                nxt = pair[1] if pair[0] == current else pair[0]
                if nxt not in result and plant.get_body(nxt) in welded:
                    result.add(nxt)
                    frontier.append(nxt)
    return sorted(result, key=int)


def _frame(plant, name, instance, field):
    if not plant.HasFrameNamed(name, instance):
        raise ConfigError(f"scenario.models.{field}: no frame {name!r} in that model")
    return plant.GetFrameByName(name, instance)


def _filter_robot_self_collisions(plant, scene_graph, instances):
    """The robot (arm + sensor + tool) may touch the environment, never itself."""
    geometries = []
    for instance in instances:
        for body_index in plant.GetBodyIndices(instance):
            geometries += plant.GetCollisionGeometriesForBody(plant.get_body(body_index))
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(GeometrySet(geometries))
    )


# ----------------------------------------------------------------------------------------------
# The controller's model: the arm plus a nominal, imperfect estimate of sensor + tool.
# ----------------------------------------------------------------------------------------------
#: The sensor frame S in the controller's plant (:func:`make_control_plant`).
CONTROL_SENSOR_FRAME = "controller_sensor_S"


def make_control_plant(config: ScenarioConfig, scene: Scene) -> MultibodyPlant:
    """A continuous plant of the arm with one rigid body standing in for sensor + tool, and the
    sensor frame S (``CONTROL_SENSOR_FRAME``) on it.

    Its mass is the true load's mass × (1 + tool_mass_error) and its centre of mass is shifted
    by tool_com_error (in S): a real controller never knows its tool exactly.
    """
    plant = MultibodyPlant(0.0)
    parser = make_parser(plant, config.models)
    arm = add_model(parser, config.models.arm, "arm")
    plant.WeldFrames(
        plant.world_frame(),
        plant.GetFrameByName(config.models.arm_base_frame, arm),
        RigidTransform(np.asarray(config.models.p_WArmBase, dtype=float)),
    )
    true_plant = scene.plant
    context = true_plant.CreateDefaultContext()
    flange = true_plant.GetFrameByName(config.models.flange_frame, scene.arm)
    load = [*scene.tool_bodies, scene.sensor_joint.parent_body().index()]
    M_FFo_F = true_plant.CalcSpatialInertia(context, flange, load)
    mass = M_FFo_F.get_mass() * (1.0 + config.controller.tool_mass_error)
    R_FS = scene.sensor_frame.CalcPose(context, flange).rotation()
    p_FoLcm_F = M_FFo_F.get_com() + R_FS @ np.asarray(config.controller.tool_com_error)
    # Keep the true rotational inertia about the centre of mass, moved to the shifted one.
    G_Lcm_F = M_FFo_F.Shift(M_FFo_F.get_com()).get_unit_inertia()
    G_FoNominal_F = G_Lcm_F.ShiftFromCenterOfMass(-p_FoLcm_F)
    nominal = plant.AddRigidBody(
        "nominal_tool", arm, SpatialInertia(mass, p_FoLcm_F, G_FoNominal_F)
    )
    plant.WeldFrames(plant.GetFrameByName(config.models.flange_frame, arm), nominal.body_frame())
    # S itself, for terms expressed at the sensor (PayloadFeedforward); no dynamics.
    plant.AddFrame(FixedOffsetFrame(CONTROL_SENSOR_FRAME, nominal.body_frame(),
                                    scene.sensor_frame.CalcPose(context, flange)))
    t = config.transmission
    if t.enabled and t.controller_knows_rotor_inertia:  # the motors' J_m N² in M̂(q)
        for index, J_m, N in zip(arm_actuators(plant, arm), t.rotor_inertia,
                                 t.gear_ratio, strict=True):
            actuator = plant.get_mutable_joint_actuator(index)
            actuator.set_default_rotor_inertia(J_m)
            actuator.set_default_gear_ratio(N)
    plant.Finalize()
    return plant


__all__ = [
    "CONTROL_SENSOR_FRAME",
    "Scene",
    "add_scene",
    "bodies_outboard_of",
    "make_control_plant",
    "sensor_weld",
]
