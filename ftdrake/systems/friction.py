"""JointFriction: viscous + smooth Coulomb friction in the joints, taken off the actuation.

The controller's model of the arm knows no friction (``make_control_plant``), so the torque
this system removes is one of the model errors a learned feedforward has to supply (the other
is the nominal tool's mass and centre of mass, ``ControllerConfig``).

Why a LeafSystem on the actuation and not the plant: Drake's joint damping (SDF
``<damping>``) is viscous only; Coulomb friction needs a nonlinear function of v. The system
is evaluated from the state at the start of each plant step (explicit in time), which is
stable while ``dt · (viscous + coulomb / velocity_scale) < 2 · inertia`` for each joint;
:func:`check_explicit_stability` checks that with a margin and names the joint when not.

Transmission compliance (the paper's motor-side encoder vs link angle) is a separate system,
:mod:`ftdrake.systems.transmission` (``scenario.transmission``, off by default): a motor and a
gearbox spring per joint, the spring integrated implicitly by Drake's solver.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from ..config import FrictionConfig
from ..errors import ConfigError

# dt · slope / inertia must stay below 2 for an explicit step to be stable; keep a margin.
STABILITY_MARGIN = 1.5


class JointFriction(LeafSystem):
    """Subtracts joint friction from the actuation torque.

    ``actuation_out = actuation_in − τ_f(v)``,
    ``τ_f,i = viscous_i · v_i + coulomb_i · tanh(v_i / velocity_scale)``.

    Input ports:
      actuation (n): commanded joint torques (N·m), e.g. the controller's output.
      joint_state (2n): ``[q (rad), v (rad/s)]`` of the arm (a plant's state port).
    Output ports:
      actuation (n): the torque that reaches the joints (N·m): commanded − friction.
      friction (n): τ_f (N·m), the friction torque opposing the motion.
    State: none.
    """

    def __init__(self, config: FrictionConfig, n_joints: int):
        super().__init__()
        config.validate()  # the system is built on its own too, from a FrictionConfig alone
        n = self.n = int(n_joints)
        if len(config.coulomb) != n:
            raise ConfigError(f"friction.coulomb: must have one entry per arm joint ({n}), "
                              f"got {len(config.coulomb)}")
        self.coulomb = np.asarray(config.coulomb, dtype=float)
        self.viscous = np.asarray(config.viscous, dtype=float)
        self.velocity_scale = float(config.velocity_scale)
        self._actuation = self.DeclareVectorInputPort("actuation", n)
        self._state = self.DeclareVectorInputPort("joint_state", 2 * n)
        inputs = {self.input_port_ticket(self._actuation.get_index()),
                  self.input_port_ticket(self._state.get_index())}
        self.DeclareVectorOutputPort("actuation", n, self._calc_actuation,
                                     prerequisites_of_calc=inputs)
        self.DeclareVectorOutputPort(
            "friction", n, self._calc_friction,
            prerequisites_of_calc={self.input_port_ticket(self._state.get_index())})

    def get_input_port_actuation(self):
        return self.GetInputPort("actuation")

    def get_input_port_joint_state(self):
        return self.GetInputPort("joint_state")

    def get_output_port_actuation(self):
        return self.GetOutputPort("actuation")

    def get_output_port_friction(self):
        return self.GetOutputPort("friction")

    def torque(self, v) -> np.ndarray:
        """τ_f (n,) or (N, n) in N·m for joint velocities `v` (rad/s)."""
        v = np.asarray(v, dtype=float)
        return self.viscous * v + self.coulomb * np.tanh(v / self.velocity_scale)

    def slope(self) -> np.ndarray:
        """dτ_f/dv at v = 0 per joint (N·m·s/rad): the stiffest the explicit step sees."""
        return self.viscous + self.coulomb / self.velocity_scale

    def _calc_friction(self, context, output: BasicVector):
        v = self._state.Eval(context)[self.n:]
        output.SetFromVector(self.torque(v))

    def _calc_actuation(self, context, output: BasicVector):
        v = self._state.Eval(context)[self.n:]
        output.SetFromVector(self._actuation.Eval(context) - self.torque(v))


def check_explicit_stability(friction: JointFriction, plant, instance, q, time_step: float,
                             where: str = "scenario.friction") -> None:
    """Raises ConfigError when a joint's friction slope is too stiff for the plant's step.

    The inertia a joint sees is bounded below by the diagonal of the mass matrix at `q`
    (the others held still); `dt · slope / M_ii` must stay below :data:`STABILITY_MARGIN`.
    """
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, instance, np.asarray(q, dtype=float))
    M = plant.CalcMassMatrix(context)
    velocity_start = plant.GetJointIndices(instance)
    joints = [plant.get_joint(j) for j in velocity_start if plant.get_joint(j).num_velocities()]
    slope = friction.slope()
    for i, joint in enumerate(joints):
        inertia = M[joint.velocity_start(), joint.velocity_start()]
        ratio = time_step * slope[i] / inertia
        if ratio > STABILITY_MARGIN:
            raise ConfigError(
                f"{where}: joint {joint.name()} (index {i}): coulomb/velocity_scale + viscous = "
                f"{slope[i]:.3g} N·m·s/rad against an inertia of {inertia:.3g} kg·m² is too "
                f"stiff for a {time_step:g} s step (dt·slope/inertia = {ratio:.2f} > "
                f"{STABILITY_MARGIN}); raise velocity_scale or lower the coefficients")
