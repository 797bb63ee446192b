"""Ground truth from the plant: the contact wrench on the tool, seen at the sensor."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactModel, ContactResults
from pydrake.systems.framework import LeafSystem


class ContactTruth(LeafSystem):
    """True contact between the tool and the environment, from the plant's ContactResults.

    Input ports:
      contact_results (abstract ContactResults): the plant's contact results port.
      body_poses (abstract, list of RigidTransform): the plant's body poses port (X_WB).
    Output ports (sampled every `period` s, like the sensor):
      wrench_contact_true (6): ``[Fx Fy Fz Tx Ty Tz]`` N, N·m: the sum of contact forces the
        environment applies to the tool, about the sensor origin So, expressed in S. This is
        what the sensor reads on top of the internal wrench.
      contact_true (1): 1.0 while any tool body touches any environment body, else 0.0.

    Point contact only (the plant ftdrake builds uses ContactModel.kPoint). Like the plant's
    sampled ports, this reads no contact before the first step.
    """

    def __init__(self, plant, sensor_frame, tool_bodies, environment_bodies, period: float):
        super().__init__()
        self._tool = {int(b) for b in tool_bodies}
        self._env = {int(b) for b in environment_bodies}
        self._S_body = int(sensor_frame.body().index())
        self._X_BS = sensor_frame.GetFixedPoseInBodyFrame()
        # With point contact only, a hydroelastic contact cannot occur and is not checked for.
        self._may_be_hydroelastic = plant.get_contact_model() != ContactModel.kPoint
        self._results = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults())
        )
        self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies())
        )
        # Sampled like the sensor; outputs are state ports, so reading them costs no Python.
        self._wrench = self.DeclareDiscreteState(6)
        self._contact = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._sample)
        self.DeclareStateOutputPort("wrench_contact_true", self._wrench)
        self.DeclareStateOutputPort("contact_true", self._contact)

    def get_input_port_contact_results(self):
        return self.GetInputPort("contact_results")

    def get_input_port_body_poses(self):
        return self.GetInputPort("body_poses")

    def get_output_port_wrench_contact_true(self):
        return self.GetOutputPort("wrench_contact_true")

    def get_output_port_contact_true(self):
        return self.GetOutputPort("contact_true")

    def _sample(self, context, discrete_state):
        results = self._results.Eval(context)
        if not results.num_point_pair_contacts() and not (
            self._may_be_hydroelastic and results.num_hydroelastic_contacts()
        ):
            # The common case, every step of free motion: nothing touches. The update starts
            # from the held state, so only leaving contact needs a write.
            contact = discrete_state.get_mutable_vector(self._contact)
            if contact.GetAtIndex(0):
                contact.SetAtIndex(0, 0.0)
                discrete_state.get_mutable_vector(self._wrench).SetZero()
            return
        contacts = list(self._contacts_on_tool(results))
        wrench = np.zeros(6)
        if contacts:  # skip evaluating every body's pose in the common, contact-free case
            X_WS = self.get_input_port(1).Eval(context)[self._S_body] @ self._X_BS
            R_SW = X_WS.rotation().inverse()
            for f_on_tool_W, p_WP in contacts:
                wrench[:3] += R_SW @ f_on_tool_W
                wrench[3:] += R_SW @ np.cross(p_WP - X_WS.translation(), f_on_tool_W)
        discrete_state.get_mutable_vector(self._wrench).SetFromVector(wrench)
        discrete_state.get_mutable_vector(self._contact).SetFromVector([float(bool(contacts))])

    def _contacts_on_tool(self, results):
        """Yields (force on the tool in W, application point in W) for tool–environment pairs."""
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            sign = self._side(int(info.bodyA_index()), int(info.bodyB_index()))
            if sign:
                # contact_force() is the force on body B.
                yield sign * info.contact_force(), info.contact_point()
        if results.num_hydroelastic_contacts():
            raise NotImplementedError(
                "ContactTruth handles point contact only (ftdrake's plant uses ContactModel.kPoint)"
            )

    def _side(self, body_a: int, body_b: int) -> float:
        """+1 if B is the tool and A the environment, -1 if the reverse, 0 otherwise."""
        if body_b in self._tool and body_a in self._env:
            return 1.0
        if body_a in self._tool and body_b in self._env:
            return -1.0
        return 0.0
