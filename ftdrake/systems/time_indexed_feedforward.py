"""TimeIndexedFeedforward: the ILC's torque table u(t) added to the controller's output.

The learning law is :mod:`ftdrake.control.ilc`; this is the system that plays its result.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem


class TimeIndexedFeedforward(LeafSystem):
    """Adds a torque table u(t) to the controller's output: the ILC's feedforward.

    ``u`` (N, n) holds the torque at times ``k · dt`` (k = 0 … N−1); between samples the
    nearest one is used, after the table the torque is 0. Same ports as
    ``LearnedFeedforward``, so ``build_station(..., feedforward=...)`` takes either.

    Input ports:
      control (n): the controller's joint torques (N·m).
      desired_state (2n): unused (an ILC is indexed by time only).
      desired_acceleration (n): unused.
    Output ports:
      control (n): control + u(t) (N·m).
      correction (n): u(t) (N·m).
      status (3n): ``[u(t), 0 (no std), 1 (confidence)]``.
    """

    def __init__(self, u: np.ndarray, dt: float):
        super().__init__()
        u = np.asarray(u, dtype=float)
        if u.ndim != 2 or len(u) < 1 or not np.isfinite(u).all():
            raise ValueError(f"u must be a finite (N, n) table; got shape {u.shape}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0 s; got {dt}")
        self.u, self.dt = u, float(dt)
        n = self.n = u.shape[1]
        self._zero = np.zeros(n)
        self._control = self.DeclareVectorInputPort("control", n)
        self.DeclareVectorInputPort("desired_state", 2 * n)
        self.DeclareVectorInputPort("desired_acceleration", n)
        time = {self.time_ticket()}
        self.DeclareVectorOutputPort(
            "control", n, self._calc_control,
            prerequisites_of_calc=time | {self.input_port_ticket(self._control.get_index())})
        self.DeclareVectorOutputPort("correction", n, self._calc_correction,
                                     prerequisites_of_calc=time)
        self.DeclareVectorOutputPort("status", 3 * n, self._calc_status,
                                     prerequisites_of_calc=time)

    def get_input_port_control(self):
        return self.GetInputPort("control")

    def get_input_port_desired_state(self):
        return self.GetInputPort("desired_state")

    def get_input_port_desired_acceleration(self):
        return self.GetInputPort("desired_acceleration")

    def get_output_port_control(self):
        return self.GetOutputPort("control")

    def get_output_port_correction(self):
        return self.GetOutputPort("correction")

    def get_output_port_status(self):
        return self.GetOutputPort("status")

    def at(self, t: float) -> np.ndarray:
        """u at time `t` (n,): the nearest sample, 0 after the table."""
        k = round(t / self.dt)
        return self.u[k] if 0 <= k < len(self.u) else self._zero

    def _calc_control(self, context, output: BasicVector):
        output.SetFromVector(self._control.Eval(context) + self.at(context.get_time()))

    def _calc_correction(self, context, output: BasicVector):
        output.SetFromVector(self.at(context.get_time()))

    def _calc_status(self, context, output: BasicVector):
        output.SetFromVector(np.concatenate([self.at(context.get_time()), self._zero,
                                             np.ones(self.n)]))
