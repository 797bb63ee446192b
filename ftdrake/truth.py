"""Ground truth from the plant: the contact wrench on the tool, seen at the sensor."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import LeafSystem, ValueProducer


class ContactTruth(LeafSystem):
    """True contact between the tool and the environment, from the plant's ContactResults.

    Input ports:
      contact_results (abstract ContactResults): the plant's contact results port.
      body_poses (abstract, list of RigidTransform): the plant's body poses port (X_WB).
    Output ports:
      wrench_external (6): ``[Fx Fy Fz Tx Ty Tz]`` N, N·m: the sum of contact forces the
        environment applies to the tool, about the sensor origin So, expressed in S. This is
        what the sensor reads on top of the internal wrench.
      contact (1): 1.0 while any tool body touches any environment body, else 0.0.

    Point contact only (the plant ftdrake builds uses ContactModel.kPoint). Like the plant's sampled ports, this reads
    no contact before the first step.
    """

    def __init__(self, plant, sensor_frame, tool_bodies, environment_bodies):
        super().__init__()
        self._tool = {int(b) for b in tool_bodies}
        self._env = {int(b) for b in environment_bodies}
        self._S_body = int(sensor_frame.body().index())
        self._X_BS = sensor_frame.GetFixedPoseInBodyFrame()
        self.DeclareAbstractInputPort("contact_results", AbstractValue.Make(ContactResults()))
        self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies())
        )
        self._cache = self.DeclareCacheEntry(
            "wrench_and_flag",
            ValueProducer(allocate=lambda: AbstractValue.Make(np.zeros(7)), calc=self._calc),
            prerequisites_of_calc={self.all_input_ports_ticket()},
        ).cache_index()
        self.DeclareVectorOutputPort(
            "wrench_external", 6, lambda c, o: o.SetFromVector(self._eval(c)[:6]),
            prerequisites_of_calc={self.all_input_ports_ticket()},
        )
        self.DeclareVectorOutputPort(
            "contact", 1, lambda c, o: o.SetFromVector(self._eval(c)[6:]),
            prerequisites_of_calc={self.all_input_ports_ticket()},
        )

    def _eval(self, context):
        return self.get_cache_entry(self._cache).Eval(context)

    def _calc(self, context, value):
        results = self.get_input_port(0).Eval(context)
        contacts = list(self._contacts_on_tool(results))
        if not contacts:  # the common case; skip evaluating every body's pose
            value.set_value(np.zeros(7))
            return
        X_WS = self.get_input_port(1).Eval(context)[self._S_body] @ self._X_BS
        f_W, tau_So_W, touching = np.zeros(3), np.zeros(3), False
        for f_on_tool_W, p_WP in contacts:
            touching = True
            f_W += f_on_tool_W
            tau_So_W += np.cross(p_WP - X_WS.translation(), f_on_tool_W)
        R_SW = X_WS.rotation().inverse()
        value.set_value(
            np.concatenate([R_SW @ f_W, R_SW @ tau_So_W, [1.0 if touching else 0.0]])
        )

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
