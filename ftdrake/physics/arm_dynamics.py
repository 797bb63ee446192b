"""Joint torques of a whole arm, linear in its inertial parameters: the rigid-body regressor.

For an arm of rigid bodies the inverse dynamics ``τ = M(q) q̈ + C(q, q̇) q̇ − τ_g(q)`` is linear
in each moving body B's 10 inertial parameters

    φ_B = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]

(mass, first moment ``h = m·c`` and inertia about the body origin Bo, all expressed in B; the
layout of :mod:`ftdrake.compensation.identification.consistent`), so ``τ = Y(q, q̇, q̈)·φ`` with φ
all bodies' parameters stacked. The regressor is built by Newton–Euler, body by body:

* the wrench B needs to move as it does under gravity g, about Bo in B,
  ``f = m (a − g) + ([α]× + [ω]×[ω]×) h``,  ``n = I α + ω × I ω + h × (a − g)``
  (ω, α, a: B's angular velocity and acceleration and Bo's acceleration, from Drake's
  kinematics with the given q̈; no forces, no mass matrix);
* joint j supplies the sum of these over the bodies outboard of it, projected on its axis:
  ``τ_j = â_j · Σ_B (n_B + (p_Bo − p_Jo) × f_B)`` for a revolute joint (Jo on its axis),
  ``τ_j = â_j · Σ_B f_B`` for a prismatic one (world frame, N·m or N).

It is independent of Drake's inverse dynamics, which the tests check it against (to 1e-9 on
random states: ``Y·φ_model = plant.CalcInverseDynamics``). Units: SI throughout; q in rad (m for
prismatic joints), torques in N·m (N). Bodies welded to the world carry no parameters; bodies
welded to a moving body join its group (a rigid group has one set of 10 parameters).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import MultibodyForces, PrismaticJoint, RevoluteJoint

from ..conventions import GRAVITY_W
from ..errors import RobotModelError
from .rigid_body import inertia_map, skew
from .robot import add_robot_model, floating_base_hint, model_label

#: Per-body inertial parameter names (suffixed by the body's name in the stacked vector).
INERTIAL_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
INERTIAL_UNITS = ("kg", "kg*m", "kg*m", "kg*m") + ("kg*m^2",) * 6


@dc.dataclass(frozen=True)
class ArmModel:
    """An arm's model: a URDF/SDF file, a ``package://`` URL of one, or model-directives text
    (starting with ``directives:``), and how it is mounted.

    base_frame: a frame welded to the world (None: the model welds itself, as a URDF with a
    ``world`` link does). package_xmls: extra package.xml files for its ``package://`` URLs.
    """

    model: str
    base_frame: str | None = None
    package_xmls: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        """A short name for messages (directives text is not one)."""
        return model_label(self.model)

    def build_plant(self) -> MultibodyPlant:
        """A finalized plant of the arm; RobotModelError names what is wrong."""
        plant = MultibodyPlant(0.0)
        add_robot_model(plant, self.model, self.package_xmls)
        if self.base_frame:
            try:
                base = plant.GetFrameByName(self.base_frame)
            except RuntimeError:
                raise RobotModelError(f"robot model {self.label} has no base frame named "
                                      f"{self.base_frame!r}") from None
            plant.WeldFrames(plant.world_frame(), base)
        plant.Finalize()
        return plant


class ArmDynamics:
    """The joint-torque regressor of one arm (see the module docstring).

    Attributes: ``plant``, ``joints`` and ``joint_names`` (the plant's velocity order, which is
    τ's), ``bodies`` (each joint's child body: φ stacks the parameters of its rigid group, in
    that order), ``groups`` (the body indices of each group), ``gravity``.
    """

    def __init__(self, plant: MultibodyPlant, gravity=GRAVITY_W):
        if plant.num_positions() != plant.num_velocities():
            raise RobotModelError(
                f"the arm has {plant.num_positions()} positions but {plant.num_velocities()} "
                f"velocities ({floating_base_hint(plant)}): joint-torque models need one "
                "coordinate per joint")
        self.plant = plant
        self.context = plant.CreateDefaultContext()
        self.gravity = np.asarray(gravity, dtype=float)
        self.n = plant.num_velocities()
        self.joints = [_dof_joint(plant, i) for i in range(self.n)]
        # One rigid group per joint: its child body and every body welded to it (a massless
        # tool0 frame, a flange, a tool) move as one, so they share one set of parameters,
        # about the child body's origin.
        self.bodies = [joint.child_body() for joint in self.joints]
        self.groups = [[b.index() for b in plant.GetBodiesWeldedTo(body)]
                       for body in self.bodies]
        self.joint_names = [j.name() for j in self.joints]
        column = {int(b.index()): k for k, b in enumerate(self.bodies)}
        if len(column) != len(self.bodies):
            raise RobotModelError("two joints move the same body: not an arm of rigid links")
        # outboard[j, k]: body k moves with joint j (τ_j carries its wrench).
        self.outboard = np.zeros((self.n, len(self.bodies)), dtype=bool)
        for j, joint in enumerate(self.joints):
            for b in plant.GetBodiesKinematicallyAffectedBy([joint.index()]):
                if int(b) in column:
                    self.outboard[j, column[int(b)]] = True
        self.prismatic = np.array([isinstance(j, PrismaticJoint) for j in self.joints])

    @property
    def num_parameters(self) -> int:
        return 10 * len(self.bodies)

    def parameter_names(self) -> list[str]:
        return [f"{name}_{b.name()}" for b in self.bodies for name in INERTIAL_NAMES]

    def model_parameters(self) -> np.ndarray:
        """φ of the model file (each group's mass, centre of mass and inertia)."""
        phi = []
        for body, group in zip(self.bodies, self.groups, strict=True):
            M = self.plant.CalcSpatialInertia(self.context, body.body_frame(), group)
            m, c = M.get_mass(), M.get_com()
            inertia = M.CalcRotationalInertia().CopyToFullMatrix3()
            phi.append([m, *(m * c), inertia[0, 0], inertia[0, 1], inertia[0, 2],
                        inertia[1, 1], inertia[1, 2], inertia[2, 2]])
        return np.asarray(phi, dtype=float).reshape(-1)

    def regressor(self, q, v, vdot) -> np.ndarray:
        """Y of shape (N, n, 10·bodies) with ``τ = Y·φ`` (rows of q, q̇, q̈ in the plant's order)."""
        q, v, vdot = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, v, vdot))
        for name, arr in (("q", q), ("qd", v), ("qdd", vdot)):
            if arr.shape[1] != self.n:
                raise ValueError(f"{name} has {arr.shape[1]} columns; the arm has {self.n} "
                                 f"joints ({', '.join(self.joint_names)})")
        N, nb = len(q), len(self.bodies)
        R = np.empty((N, nb, 3, 3))
        p = np.empty((N, nb, 3))
        w = np.empty((N, nb, 3))
        alpha = np.empty((N, nb, 3))
        a = np.empty((N, nb, 3))
        axis = np.empty((N, self.n, 3))
        origin = np.empty((N, self.n, 3))
        plant, ctx = self.plant, self.context
        for k in range(N):
            plant.SetPositions(ctx, q[k])
            plant.SetVelocities(ctx, v[k])
            accelerations = plant.CalcSpatialAccelerationsFromVdot(ctx, vdot[k])
            for i, body in enumerate(self.bodies):
                X = plant.EvalBodyPoseInWorld(ctx, body)
                V = plant.EvalBodySpatialVelocityInWorld(ctx, body)
                A = accelerations[int(body.index())]
                R[k, i], p[k, i] = X.rotation().matrix(), X.translation()
                w[k, i], alpha[k, i] = V.rotational(), A.rotational()
                a[k, i] = A.translational()
            for j, joint in enumerate(self.joints):
                X_WM = joint.frame_on_child().CalcPoseInWorld(ctx)
                axis[k, j] = X_WM.rotation().matrix() @ _joint_axis(joint)
                origin[k, j] = X_WM.translation()
        return self._assemble(R, p, w, alpha, a - self.gravity, axis, origin)

    def _assemble(self, R, p, w_W, alpha_W, d_W, axis, origin):
        """Y from body poses, motion (world frame) and joint axes/origins (see module doc)."""
        RT = np.swapaxes(R, -1, -2)
        w, al, d = (np.einsum("nbij,nbj->nbi", RT, x) for x in (w_W, alpha_W, d_W))
        Yb = body_wrench_regressor(w, al, d)  # (N, nb, 6, 10), in B about Bo
        f = np.einsum("nbij,nbjk->nbik", R, Yb[:, :, :3])  # in W
        moment = np.einsum("nbij,nbjk->nbik", R, Yb[:, :, 3:])
        N, nb = R.shape[:2]
        Y = np.zeros((N, self.n, nb, 10))
        for j in range(self.n):
            bodies = self.outboard[j]
            if self.prismatic[j]:
                per_body = f[:, bodies]
            else:
                lever = p[:, bodies] - origin[:, j][:, None, :]
                per_body = moment[:, bodies] + np.cross(
                    lever[..., None, :], np.swapaxes(f[:, bodies], -1, -2)).swapaxes(-1, -2)
            Y[:, j, bodies] = np.einsum("ni,nbik->nbk", axis[:, j], per_body)
        return Y.reshape(N, self.n, nb * 10)

    def inverse_dynamics(self, q, v, vdot) -> np.ndarray:
        """Drake's ``CalcInverseDynamics`` with gravity (the plant's force elements) as the only
        applied force, row by row (N, n): the independent computation the regressor is checked
        against. The plant's gravity must be ``self.gravity`` (Drake's default is)."""
        q, v, vdot = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, v, vdot))
        out = np.empty((len(q), self.n))
        forces = MultibodyForces(self.plant)
        for k in range(len(q)):
            self.plant.SetPositions(self.context, q[k])
            self.plant.SetVelocities(self.context, v[k])
            # Gravity is a force element: Drake's inverse dynamics adds only the forces given.
            self.plant.CalcForceElementsContribution(self.context, forces)
            out[k] = self.plant.CalcInverseDynamics(self.context, vdot[k], forces)
        return out


def body_wrench_regressor(w, alpha, d) -> np.ndarray:
    """(…, 6, 10): the wrench ``[f; n]`` about Bo a body needs, linear in φ (all in B);
    ``d = a − g`` is Bo's acceleration minus gravity."""
    shape = w.shape[:-1]
    Y = np.zeros((*shape, 6, 10))
    Y[..., :3, 0] = d
    Y[..., :3, 1:4] = skew(alpha) + skew(w) @ skew(w)
    Y[..., 3:, 1:4] = -skew(d)  # h × d = −d × h
    Y[..., 3:, 4:10] = inertia_map(alpha) + skew(w) @ inertia_map(w)
    return Y


def _dof_joint(plant, v_index):
    """The one-dof joint whose velocity is v[v_index]; RobotModelError for other kinds."""
    for i in plant.GetJointIndices():
        joint = plant.get_joint(i)
        if joint.num_velocities() and joint.velocity_start() <= v_index < (
                joint.velocity_start() + joint.num_velocities()):
            if not isinstance(joint, RevoluteJoint | PrismaticJoint):
                raise RobotModelError(
                    f"joint {joint.name()!r} is a {joint.type_name()} joint; joint-torque "
                    "models take revolute and prismatic joints")
            return joint
    raise RobotModelError(f"no joint owns velocity {v_index}")


def _joint_axis(joint) -> np.ndarray:
    """The joint's unit axis in its child frame M (= in F for these joint types)."""
    if isinstance(joint, RevoluteJoint):
        return np.asarray(joint.revolute_axis(), dtype=float)
    return np.asarray(joint.translation_axis(), dtype=float)
