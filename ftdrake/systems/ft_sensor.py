"""Force/torque sensors as Drake systems.

Convention (used everywhere in ftdrake; tested in tests/systems/test_sensor_physics.py):

* A wrench is ``[Fx, Fy, Fz, Tx, Ty, Tz]`` in N and N·m (force first, as ROS WrenchStamped and
  the study). Drake's ``SpatialForce`` is ``[torque; force]``; the conversion happens in
  :func:`wrench_from_spatial_force` / :func:`spatial_force_from_wrench` (and, compiled for the
  1 kHz loop, in ``_negated_wrench``, tested equal to them).
* The sensor reports the load that the **tool side applies to the sensor** (ATI's convention),
  about the origin So of the sensor frame S, expressed in S. S is the sensor weld joint's child
  frame ``Jc``; the tool is the weld's child side.
* Drake's reaction-forces port gives ``F_CJc_Jc``: the force the joint applies to the child body C
  at Jc, expressed in Jc. By Newton's third law the tool applies ``-F_CJc_Jc`` to the sensor, so
  the sensor reads ``wrench = -F_CJc_Jc`` (same point, same frame).
* Consequence, at rest: the reading is the tool's weight ``m·g`` expressed in S (pointing down in
  the world) and the torque ``p_SoScm × m·g`` about So.
"""

from __future__ import annotations

import numba
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.tree import WeldJoint
from pydrake.systems.framework import BasicVector, LeafSystem


def wrench_from_spatial_force(F: SpatialForce) -> np.ndarray:
    """Drake ``[τ; f]`` → ftdrake ``[Fx, Fy, Fz, Tx, Ty, Tz]``."""
    return np.concatenate([F.translational(), F.rotational()])


def spatial_force_from_wrench(w) -> SpatialForce:
    """ftdrake ``[Fx, Fy, Fz, Tx, Ty, Tz]`` → Drake ``SpatialForce(τ, f)``."""
    w = np.asarray(w, dtype=float)
    return SpatialForce(tau=w[3:], f=w[:3])


class ForceTorqueSensor(LeafSystem):
    """Ideal 6-axis F/T sensor at a weld joint of any MultibodyPlant.

    Input ports:
      reaction_forces (abstract, list of SpatialForce): connect the plant's
        ``get_reaction_forces_output_port()``.
    Output ports:
      wrench (6): ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m: the load the child (tool) side applies to
        the sensor, about the weld's child-frame origin So, expressed in that frame S.

    With a discrete plant, the reaction port is sampled: it reads all zeros until the plant has
    taken its first step, so this sensor reads zero at t = 0.
    """

    def __init__(self, plant, joint):
        super().__init__()
        if not isinstance(joint, WeldJoint):
            raise TypeError(
                f"ForceTorqueSensor needs a weld joint; {joint.name()!r} is a "
                f"{joint.type_name()} joint"
            )
        if plant.get_joint(joint.index()).name() != joint.name():
            raise ValueError(f"joint {joint.name()!r} does not belong to this plant")
        self._joint_index = int(joint.index())
        self._num_joints = plant.num_joints()
        self._reaction_forces = self.DeclareAbstractInputPort(
            "reaction_forces", AbstractValue.Make([SpatialForce()] * self._num_joints)
        )
        self.DeclareVectorOutputPort(
            "wrench", 6, self._calc_wrench,
            prerequisites_of_calc={self.input_port_ticket(self._reaction_forces.get_index())},
        )

    def get_input_port_reaction_forces(self):
        return self.GetInputPort("reaction_forces")

    def get_output_port_wrench(self):
        return self.GetOutputPort("wrench")

    def _calc_wrench(self, context, output: BasicVector):
        # Runs every plant step, so it makes as few Python calls as it can.
        forces = self._reaction_forces.Eval(context)
        if len(forces) != self._num_joints:
            raise ValueError(
                f"reaction_forces has {len(forces)} entries; the plant has {self._num_joints} "
                "joints (is the port connected to the right plant?)"
            )
        _negated_wrench(forces[self._joint_index].get_coeffs(), output.get_mutable_value())


@numba.njit(cache=True)
def _negated_wrench(tau_f, out):
    """``out = -[f; τ]`` from Drake's spatial-force coefficients ``[τ; f]``."""
    for i in range(3):
        out[i] = -tau_f[3 + i]
        out[3 + i] = -tau_f[i]
