"""ContactDetector: contact from the external wrench, with hysteresis and debouncing."""

from __future__ import annotations

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem
from scipy.stats import chi2

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
        self.config = config.validate()
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


def armed(times, arm_after_s: float = DetectorConfig.arm_after_s) -> np.ndarray:
    """The samples the detector judges: run time (s, from each run's start) ≥ `arm_after_s`.

    Thresholds come from these only: before it the detector is not armed, and the controller's
    start-up transient there (|q̈| up to 8 rad/s² in the first milliseconds of a simulated run)
    would otherwise set the largest-residual term of
    :func:`thresholds_for_false_positive_rate`."""
    return np.asarray(times, dtype=float) >= arm_after_s


def thresholds_for_false_positive_rate(residual, *, sample_rate_hz: float,
                                       false_positives_per_hour: float = 1.0,
                                       **overrides) -> DetectorConfig:
    """Detector thresholds for a target false-positive rate, from held-out free motion.

    `residual` (N × 6) is measured − predicted wrench on contact-free data the model was not
    trained on, sampled at `sample_rate_hz`. The thresholds come from a Gaussian model of
    that residual, checked against the data itself:

    * Per axis the residual is taken as zero-mean Gaussian with the held-out RMS s_i as its
      standard deviation (model error plus sensor noise). ‖F‖ is then at most s_max·χ₃
      (χ with 3 degrees of freedom), with s_max the largest force-axis RMS; likewise ‖T‖.
    * A budget of R false positives per hour is a per-sample probability
      p = R / (3600·f_s) for each of force and torque (half each). Debouncing
      (``debounce_on`` consecutive samples) is not counted as a further reduction: at 1 kHz a
      model's error is smooth, so one exceeding sample is usually followed by more.
    * force_on = max(s_max·√(χ²₃ quantile at 1 − p/2), 1.05 × the largest ‖F‖ seen on the
      held-out data); torque_on likewise. The second term keeps heavy tails (where the
      motion leaves the training data) from firing on the very data that set the thresholds.

    The smallest contact force it then detects is about force_on plus the residual at that
    moment; ``ftdrake.sim.evaluation`` measures it. `overrides` set the other fields.
    """
    r = np.asarray(residual, dtype=float)
    if r.ndim != 2 or r.shape[1] != 6 or len(r) < 100:
        raise ValueError(f"residual must be N × 6 with N >= 100; got shape {r.shape}")
    if not np.isfinite(r).all():
        raise ValueError("residual holds NaN or infinity; drop those rows first")
    if not (false_positives_per_hour > 0 and sample_rate_hz > 0):
        raise ValueError("false_positives_per_hour and sample_rate_hz must be positive")
    p = false_positives_per_hour / (3600.0 * sample_rate_hz) / 2.0
    k = float(np.sqrt(chi2.isf(p, 3)))
    rms = np.sqrt(np.mean(r**2, axis=0))
    thresholds = []
    for block in (slice(0, 3), slice(3, 6)):
        gaussian = k * rms[block].max()
        observed = 1.05 * np.linalg.norm(r[:, block], axis=1).max()
        thresholds.append(float(max(gaussian, observed)))
    return DetectorConfig(force_on=thresholds[0], torque_on=thresholds[1],
                          **overrides).validate()
