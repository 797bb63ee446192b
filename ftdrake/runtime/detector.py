"""ContactDetector: contact from the external wrench, with hysteresis and debouncing."""

from __future__ import annotations

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem

from ..config import DetectorConfig


class ContactDetector(LeafSystem):
    """Detects contact from the external wrench, with hysteresis and debouncing.

    Input ports:
      wrench_contact (6): ``[Fx Fy Fz Tx Ty Tz]`` N, N·m (e.g. CompensatorSystem's output).
      wrench_std (6, optional): the compensator's predictive std; raises the thresholds by
        ``std_gain · ‖std‖`` when connected.
    Output ports (updated every `period` s):
      contact (1): 1.0 while in contact.
      contact_force (1): ‖F‖ of the external wrench in N while in contact, else 0.
    State: contact flag, contact force, consecutive-sample counter. Disarmed (no contact)
    for the first ``arm_after_s`` seconds.
    """

    def __init__(self, config: DetectorConfig, period: float):
        super().__init__()
        self.config = config.validate()  # built on its own too, from a DetectorConfig alone
        self.period = float(period)
        self._wrench_port = self.DeclareVectorInputPort("wrench_contact", 6)
        self._std_port = self.DeclareVectorInputPort("wrench_std", 6)
        self._flag = self.DeclareDiscreteState(1)
        self._force = self.DeclareDiscreteState(1)
        self._counter = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("contact", self._flag)
        self.DeclareStateOutputPort("contact_force", self._force)
        # The thresholds are read once, here: changing `config` later has no effect.
        c = self.config
        self._constants = np.array([c.force_on, c.torque_on, c.release_ratio, c.debounce_on,
                                    c.debounce_off, c.std_gain])
        self._arm_after_s, self._uses_std = c.arm_after_s, c.std_gain > 0
        self._no_std = np.zeros(6)

    def get_input_port_wrench_contact(self):
        return self.GetInputPort("wrench_contact")

    def get_input_port_wrench_std(self):
        return self.GetInputPort("wrench_std")

    def get_output_port_contact(self):
        return self.GetOutputPort("contact")

    def get_output_port_contact_force(self):
        return self.GetOutputPort("contact_force")

    def _update(self, context, state):
        # Runs at the sensor rate: few Python calls, the logic compiled (_detect).
        if context.get_time() < self._arm_after_s:
            return  # not armed yet
        w = self._wrench_port.Eval(context)
        std = (self._std_port.Eval(context)
               if self._uses_std and self._std_port.HasValue(context) else self._no_std)
        _detect(w, std, self._constants, state.get_mutable_value(self._flag),
                state.get_mutable_value(self._counter), state.get_mutable_value(self._force))


@numba.njit(cache=True)
def _detect(w, std, constants, flag, counter, force_out):
    """One detector sample: hysteresis + debounce on ‖F‖ and ‖T‖; updates the state in place.

    `constants` = [force_on, torque_on, release_ratio, debounce_on, debounce_off, std_gain].
    A NaN/inf wrench changes nothing (it is not evidence either way).
    """
    for value in w:
        if not np.isfinite(value):
            return
    force_on, torque_on, release, n_on, n_off, gain = constants
    force = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    torque = math.sqrt(w[3] * w[3] + w[4] * w[4] + w[5] * w[5])
    if gain > 0:
        force_on += gain * math.sqrt(std[0] * std[0] + std[1] * std[1] + std[2] * std[2])
        torque_on += gain * math.sqrt(std[3] * std[3] + std[4] * std[4] + std[5] * std[5])
    in_contact, count = flag[0] > 0.5, counter[0]
    if in_contact:
        quiet = force < release * force_on and torque < release * torque_on
        count = count + 1 if quiet else 0.0
        if count >= n_off:
            in_contact, count = False, 0.0
    else:
        loud = force > force_on or torque > torque_on
        count = count + 1 if loud else 0.0
        if count >= n_on:
            in_contact, count = True, 0.0
    flag[0] = 1.0 if in_contact else 0.0
    counter[0] = count
    force_out[0] = force if in_contact else 0.0
