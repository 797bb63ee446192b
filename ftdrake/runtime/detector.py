"""ContactDetector: contact from the external wrench, with hysteresis and debouncing.

Two tests (``DetectorConfig.test``): ``"norm"`` compares ‖F‖ and ‖T‖ with fixed thresholds;
``"chi2"`` whitens the 6-D wrench by the compensator's predictive std and compares
Σ (wᵢ/σᵢ)² with the χ²₆ quantile of the false-positive budget (:func:`chi2_threshold`), so
the budget holds wherever the arm is and the detectable force rises only where the model is
unsure. ``"auto"`` (the default) is resolved per model by the chain
(:meth:`DetectorConfig.for_model`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem
from scipy.stats import chi2

from ..config import DetectorConfig
from ..errors import ConfigError

#: Degrees of freedom of the χ² test: the six wrench axes.
CHI2_DOF = 6
#: The ``payload_state`` of a recognised payload change
#: (:data:`ftdrake.runtime.payload_change.PAYLOAD_STATES`): no contact while it holds.
PAYLOAD_DECIDED = 2.0


def chi2_threshold(config: DetectorConfig, period: float) -> float:
    """The χ² test's threshold on Σ (wᵢ/σᵢ)²: ``config.chi2_on``, or (0) the χ²₆ quantile
    at 1 − p, p = false_positives_per_hour · period / 3600 the per-sample false-positive
    probability (`period` in s). Debouncing is not counted as a further reduction."""
    if config.chi2_on > 0:
        return float(config.chi2_on)
    p = config.false_positives_per_hour * float(period) / 3600.0
    return float(chi2.isf(p, CHI2_DOF))


class ContactDetector(LeafSystem):
    """Detects contact from the external wrench, with hysteresis and debouncing.

    Input ports:
      wrench_contact (6): ``[Fx Fy Fz Tx Ty Tz]`` N, N·m (e.g. CompensatorSystem's output).
      wrench_std (6; required by ``test: "chi2"``, else optional): the compensator's
        predictive std, N, N·m; the χ² test whitens by it, the norm test raises its
        thresholds by ``std_gain · ‖std‖`` when connected.
      wrench_std_tracker (6, optional): the bias tracker's predictive std of what it
        subtracted (``OnlineBiasTracker.wrench_std``), N, N·m; added to wrench_std in
        quadrature when connected (independent errors).
      payload_state (1, optional): the payload-change monitor's decision
        (:class:`~ftdrake.runtime.payload_change.PayloadChangeMonitor`, a state output: the
        previous sample's). While it is 2 (a payload change recognised, the tracker taking the
        new payload over) the detector reports no contact and its counter restarts: a decided
        payload change is not a contact. Unconnected: no effect.
    Output ports (updated every `period` s):
      contact (1): 1.0 while in contact.
      contact_force (1): ‖F‖ of the external wrench in N while in contact, else 0.
    State: contact flag, contact force, consecutive-sample counter. Disarmed (no contact)
    for the first ``arm_after_s`` seconds.

    `config.test` "auto" is resolved for the model by the chain
    (:meth:`DetectorConfig.for_model`); built alone it is the norm test, unless `chi2_on` is
    given (then the model decides, and it is an error).
    """

    def __init__(self, config: DetectorConfig, period: float):
        super().__init__()
        self.config = config.validate().without_model()
        self.period = float(period)
        self._wrench_port = self.DeclareVectorInputPort("wrench_contact", 6)
        self._std_port = self.DeclareVectorInputPort("wrench_std", 6)
        self._tracker_std_port = self.DeclareVectorInputPort("wrench_std_tracker", 6)
        self._payload_state_port = self.DeclareVectorInputPort("payload_state", 1)
        self._flag = self.DeclareDiscreteState(1)
        self._force = self.DeclareDiscreteState(1)
        self._counter = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("contact", self._flag)
        self.DeclareStateOutputPort("contact_force", self._force)
        # The thresholds are read once, here: changing `config` later has no effect.
        c = self.config
        self._chi2 = c.test == "chi2"
        if self._chi2:
            self.chi2_on = chi2_threshold(c, self.period)
            self._constants = np.array([self.chi2_on, c.release_ratio, c.debounce_on,
                                        c.debounce_off])
        else:
            self._constants = np.array([c.force_on, c.torque_on, c.release_ratio,
                                        c.debounce_on, c.debounce_off, c.std_gain])
        self._arm_after_s, self._uses_std = c.arm_after_s, c.std_gain > 0 or self._chi2
        self._no_std = np.zeros(6)
        self._std = np.zeros(6)

    def get_input_port_wrench_contact(self):
        return self.GetInputPort("wrench_contact")

    def get_input_port_wrench_std(self):
        return self.GetInputPort("wrench_std")

    def get_input_port_wrench_std_tracker(self):
        return self.GetInputPort("wrench_std_tracker")

    def get_input_port_payload_state(self):
        return self.GetInputPort("payload_state")

    def get_output_port_contact(self):
        return self.GetOutputPort("contact")

    def get_output_port_contact_force(self):
        return self.GetOutputPort("contact_force")

    def _update(self, context, state):
        # Runs at the sensor rate: few Python calls, the logic compiled (_detect).
        if context.get_time() < self._arm_after_s:
            return  # not armed yet
        std = (self._std_port.Eval(context)
               if self._uses_std and self._std_port.HasValue(context) else None)
        tracker_std = (self._tracker_std_port.Eval(context)
                       if std is not None and self._tracker_std_port.HasValue(context) else None)
        payload_state = (self._payload_state_port.Eval(context)[0]
                         if self._payload_state_port.HasValue(context) else 0.0)
        self.detect(self._wrench_port.Eval(context), std, tracker_std,
                    state.get_mutable_value(self._flag), state.get_mutable_value(self._counter),
                    state.get_mutable_value(self._force), payload_state)

    def detect(self, w, std, tracker_std, flag, counter, force, payload_state=0.0) -> None:
        """One armed sample on plain arrays (what ``_update`` does with the context's): the
        contact wrench `w`, the compensator's `std` and the tracker's `tracker_std` (None
        where the input is not connected or not used), the state (flag, counter, force)
        updated in place; `payload_state` the monitor's decision (0 where unconnected).
        :class:`~ftdrake.runtime.step.ChainStep` calls it too."""
        if payload_state == PAYLOAD_DECIDED:
            flag[0], counter[0], force[0] = 0.0, 0.0, 0.0
            return
        if std is None:
            std = self._no_std
        elif tracker_std is not None:
            std = _in_quadrature(std, tracker_std, self._std)
        if self._chi2:
            if std is self._no_std:
                raise ConfigError("detector.test 'chi2' whitens by the model's std: connect "
                                  "the detector's wrench_std input (CompensationChain does)")
            detect_chi2(w, std, self._constants, flag, counter, force)
            return
        _detect(w, std, self._constants, flag, counter, force)

    @property
    def arm_after_s(self) -> float:
        """s: the detector changes nothing before this time (its context's, or the step's)."""
        return self._arm_after_s

    @property
    def uses_std(self) -> bool:
        """Whether the test reads the std inputs (the χ² test, or the norm test's std_gain)."""
        return self._uses_std


@numba.njit(cache=True)
def _in_quadrature(a, b, out):
    """out = √(a² + b²) per entry (a NaN in either stays NaN: the test then skips the sample)."""
    for i in range(6):
        out[i] = math.sqrt(a[i] * a[i] + b[i] * b[i])
    return out


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


@numba.njit(cache=True)
def chi2_statistic(w, std) -> float:
    """Σ (wᵢ/σᵢ)² over the six axes; NaN when a σᵢ is not positive and finite."""
    total = 0.0
    for i in range(6):
        if not (std[i] > 0.0 and np.isfinite(std[i])):
            return np.nan
        z = w[i] / std[i]
        total += z * z
    return total


@numba.njit(cache=True)
def detect_chi2(w, std, constants, flag, counter, force_out):
    """One χ²-test sample: hysteresis + debounce on Σ (wᵢ/σᵢ)²; updates the state in place.

    `constants` = [threshold, release_ratio, debounce_on, debounce_off]; contact switches on
    above the threshold and off below release_ratio² × it (the ratio is one of norms, as in
    the norm test). A NaN/inf wrench or a std that is not positive changes nothing.
    """
    for value in w:
        if not np.isfinite(value):
            return
    statistic = chi2_statistic(w, std)
    if np.isnan(statistic):
        return
    threshold, release, n_on, n_off = constants
    in_contact, count = flag[0] > 0.5, counter[0]
    if in_contact:
        count = count + 1 if statistic < release * release * threshold else 0.0
        if count >= n_off:
            in_contact, count = False, 0.0
    else:
        count = count + 1 if statistic > threshold else 0.0
        if count >= n_on:
            in_contact, count = True, 0.0
    flag[0] = 1.0 if in_contact else 0.0
    counter[0] = count
    force_out[0] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) if in_contact else 0.0
