"""OnlineBiasTracker: the sensor's bias (and optionally a grasped payload), estimated while the
tool is free, so the detector judges the contact wrench alone::

    compensator.wrench_compensated ──▶ tracker ──▶ detector.wrench_contact
    compensator.out_of_domain, fault ──▶ tracker ◀── detector.contact

Wired by :class:`~ftdrake.runtime.chain.CompensationChain`. The detector's ``contact`` is a
state output, so the tracker reads the previous sample's decision: no algebraic loop.

**What it estimates** (one sample, sensor frame S, ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m)::

    wrench_compensated = b + K·[F_P; T_P] + contact wrench + noise
    F_P = Δm·g_S − ([α]× + [ω]×[ω]×) Δ(m·c)
    T_P = Δ(m·c) × g_S − (L(α) + [ω]× L(ω)) ΔI_So

K (``payload_map``, identity by default) is how a wrench at the sensor shows in the
compensated wrench: the compensator's reading matrix seen from S (its identified cross-talk,
1–2 % per entry on a real sensor, acts on a grasped payload's wrench as on the tool's).
θ = [b (6); Δm; Δ(m·c) (3); ΔI_So (6)]: the bias left after the compensator, and with
``track_payload`` a rigid payload picked up after training (mass kg, first moment about So
kg·m, inertia about So kg·m² as ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``; L(x) maps them to I·x);
g_S = g − a_So (``gravity_S``), ω, α of S (``motion_S``), all in S, as the physics payload
compensator's regressor (:mod:`ftdrake.compensation.compiled.payload`). Without
``motion_S`` only the gravity part is fitted and ΔI_So stays at its prior (0). Without
``track_payload`` only b (6 parameters).

**How.** Recursive least squares in information form with stabilised exponential forgetting
(memory τ = ``time_constant_s``, λ = exp(−period/τ)), in coordinates scaled by the prior
stds (``bias_prior_std``, ``payload_prior_std``) and the sensor's noise σ::

    R ← λ·R + (1 − λ)·I + ΦᵀΦ,      θ ← θ + R⁻¹·Φᵀ·(y − Φθ)

The *published* θ (what is subtracted and output) follows the estimate at most
``rate_bound_sigmas``·drift_std/√τ per second per axis (the payload's bound scaled to the
same force and torque rates), except in the settle windows below.

**When it updates.** Only while ``contact``, ``out_of_domain`` and ``fault`` are < 0.5 and
the inputs are finite (a NaN flag counts as set); otherwise the estimator's state is held
and the outputs are computed from the held estimate. One exception: in the payload's hold
(below) ``out_of_domain`` does not hold it, since a held sample re-initialises the payload
from itself alone and a grasp's jolt takes q̈ out of the domain for a few ms. A non-finite
wrench, g_S or motion holds every output.

**Signals.** ``tared`` (re-tare) and ``payload_changed`` (grasp or release) cannot be told
from contact by the wrench, so they are inputs:

* ``payload_changed``, and a ``tared`` at the run's start (or with ``tare_jump_window_s``
  0): for the signal's samples and ``hold_samples`` − 1 after, the block's information is
  reset to the prior before the update (the payload from the gravity part of that sample
  alone, its motion terms counted as noise at their prior's spread); then the published
  values follow the estimate without the rate bound for ``tare_settle_s`` (bias) or
  ``payload_settle_s`` (bias and payload) of used samples. Within those windows contact
  does not freeze the estimator (out_of_domain and fault do): keep the tool free after a
  tare or a grasp.
* a later ``tared``: estimated as a jump of the bias, the mean level over
  ``tare_jump_window_s`` after the hold less the mean corrected wrench before the signal
  (leaving out its last ``tare_guard_s``); the estimator keeps its information.

**How sure it is.** ``wrench_std`` is the predictive std of what it subtracts, Φ·θ, from
the estimate's covariance (S·R⁻¹·S in parameter units). It is small once the estimator has
seen τ seconds of motion; after a grasp it starts from the payload's prior (the motion terms'
part stays large until the arm has accelerated and turned with the new load), so a detector
that adds it to the compensator's std (the chain's does) cannot take the payload still being
identified for contact.

**State** (discrete): θ, the published θ, R (n × n, scaled), four counters (tare hold, tare
settle, payload hold, payload settle), the jump's state (the "before" mean, the pulse's bias,
the sum after it, its phase, a ring of the last ``tare_guard_s`` of corrected wrenches), and
the outputs (state outputs).

The derivation, the guards' reasoning and their measured figures are in the documentation
(user guide, "The bias tracker").
"""

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..config import BiasTrackerConfig, SensorConfig, SensorStreamConfig
from ..conventions import STANDARD_GRAVITY
from .bias_estimator import N_PAYLOAD, jump_state_size, steady_information, track_sample

__all__ = ["BiasTrackerConfig", "OnlineBiasTracker"]

#: rad/s²: the scale of |α| + |ω|² the inertia's rate bound is set for (brisk free motion).
ANGULAR_SCALE = 10.0


class OnlineBiasTracker(LeafSystem):
    """Tracks the bias (and optionally a payload) of the external wrench while not in contact.

    Input ports:
      wrench_compensated (6): measured − predicted internal wrench (CompensatorSystem), N, N·m, S.
      contact (1): the detector's flag (its state output: the previous sample's decision).
      out_of_domain (1, optional): the compensator's flag; unconnected = 0.
      fault (1, optional): the compensator's flag; unconnected = 0.
      tared (1, optional): > 0.5 (a pulse or a short level) when the sensor was re-tared.
      gravity_S (3, with ``track_payload``): the apparent gravity at So, g − a_So, in S, m/s²
        (≈ R_SW·[0, 0, −9.81] at rest; SensorGravity, JointStateGravity).
      motion_S (6, optional, with ``track_payload``): [ω_S; α_S], the angular velocity (rad/s)
        and acceleration (rad/s²) of S, in S (SensorGravity, JointStateGravity); unconnected
        = 0: the gravity part only, ΔI_So held at its prior. The stations connect it only
        with ``bias_tracker.track_payload_motion``.
      payload_changed (1, optional, with ``track_payload``): > 0.5 when a payload was grasped
        or released.
      payload_change_detected (1, optional, with ``track_payload``): the same from
        :class:`~ftdrake.runtime.payload_change.PayloadChangeMonitor` (a change nobody
        signalled); either input > 0.5 counts.
    Output ports (updated every `period` s):
      wrench_contact (6): input − bias − K·[F_P; T_P] (the payload's wrench as the model
        reads it, module docstring), N, N·m, S.
      bias (6): the published bias estimate, N, N·m, S.
      payload (4, with ``track_payload``): [Δm (kg), Δ(m·c) about So in S (kg·m)].
      payload_inertia (6, with ``track_payload``): ΔI_So [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
        (kg·m², about So, in S).
      tracking (1): 1.0 on samples that updated the estimator.
      wrench_std (6): the predictive std of bias + K·[F_P; T_P] from the estimate's
        covariance (module docstring, "How sure it is"), N, N·m, S.

    `sensor` (the chain's SensorStreamConfig, or a simulated SensorConfig) gives the noise σ
    per axis (the rows' weights) and the drift (the rate bound);
    `period` defaults to the sensor's sample period. `payload_map` (6 × 6, default identity):
    how a wrench acting at the sensor (in S, about So) shows in ``wrench_compensated``; the
    chain passes its model's (``payload_reading_map()``, the identified cross-talk seen from
    S), so a grasped payload is read through the same sensor matrix as the tool. See the
    module docstring for what is estimated, when it freezes, the rate bound and what tared /
    payload_changed do; the compiled estimator is :mod:`ftdrake.runtime.bias_estimator`.
    """

    def __init__(self, config: BiasTrackerConfig, sensor: SensorStreamConfig | SensorConfig,
                 period: float | None = None, payload_map=None):
        super().__init__()
        self.config = config.validate()  # built on its own too, from its config alone
        spec = sensor.spec()
        self.period = float(1.0 / spec.rate_hz if period is None else period)
        if not (self.period > 0 and math.isfinite(self.period)):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        c = self.config
        self.track_payload = bool(c.track_payload)
        self.n = N_PAYLOAD if self.track_payload else 6
        self.payload_map = self._checked_payload_map(payload_map)
        # Noise σ weights the rows; floored so an ideal sensor (σ = 0) stays well posed.
        self.noise_std = np.maximum(np.asarray(spec.noise_std, dtype=float),
                                    np.maximum(np.asarray(spec.resolution, float), 1e-6))
        self.lam = math.exp(-self.period / c.time_constant_s)
        self.rate_bound = self._rate_bound(sensor)
        self.prior_std = np.asarray(list(c.bias_prior_std) + c.payload_prior())[:self.n]
        hold = int(c.hold_samples)
        tare_settle = max(hold, round(c.tare_settle_s / self.period))
        payload_settle = max(hold, round(c.payload_settle_s / self.period))
        window = round(c.tare_jump_window_s / self.period)
        self.guard = max(1, round(c.tare_guard_s / self.period))
        self._constants = np.array([self.lam, hold, tare_settle, payload_settle, window,
                                    self.guard])
        self._steps = self.rate_bound * self.period
        self._declare_state(hold, tare_settle, payload_settle)
        self._declare_ports()

    @staticmethod
    def _checked_payload_map(payload_map) -> np.ndarray:
        if payload_map is None:
            return np.eye(6)
        K = np.asarray(payload_map, dtype=float)
        if K.shape != (6, 6) or not np.all(np.isfinite(K)):
            raise ValueError(f"payload_map must be a finite 6 × 6 matrix (the model's map from "
                             f"a wrench in S to the compensated wrench), got shape {K.shape}")
        return K

    def _rate_bound(self, sensor: SensorStreamConfig | SensorConfig) -> np.ndarray:
        """ḃ_max per parameter (N/s, N·m/s for the bias) from the sensor's drift; the
        payload's so that Δṁ·g ≤ min ḃ_F, Δ(m·c)˙·g ≤ min ḃ_T, ΔI˙·ANGULAR_SCALE ≤ min ḃ_T."""
        c = self.config
        k = c.rate_bound_sigmas
        bias_rate = k * np.asarray(sensor.drift, float) / math.sqrt(c.time_constant_s)
        if math.isinf(k):
            bias_rate = np.full(6, np.inf)
        return np.concatenate(
            [bias_rate, [bias_rate[:3].min() / STANDARD_GRAVITY],
             np.full(3, bias_rate[3:].min() / STANDARD_GRAVITY),
             np.full(6, bias_rate[3:].min() / ANGULAR_SCALE)])[:self.n]

    def _declare_state(self, hold: int, tare_settle: int, payload_settle: int) -> None:
        """Estimator state: θ (n), published θ (n), R (n²), counters [tare hold, tare settle,
        payload hold, payload settle] (counted in used samples), the jump's state; then the
        outputs. A run starts as after a tare (and a grasp, with payload tracking)."""
        c, n = self.config, self.n
        theta = np.zeros(n)
        theta[:6] = c.initial_bias
        counters = [hold, tare_settle] + ([hold, payload_settle] if self.track_payload
                                          else [0, 0])
        x0 = np.concatenate([theta, theta, np.eye(n).ravel(), counters,
                             np.zeros(jump_state_size(self.guard))])
        self._x = self.DeclareDiscreteState(x0)
        self._corrected = self.DeclareDiscreteState(6)
        self._bias = self.DeclareDiscreteState(np.asarray(c.initial_bias, float))
        self._payload = self.DeclareDiscreteState(4) if self.track_payload else None
        self._inertia = self.DeclareDiscreteState(6) if self.track_payload else None
        self._tracking = self.DeclareDiscreteState(1)
        self._std = self.DeclareDiscreteState(6)
        self._flags = np.zeros(5)
        self._no_gravity = np.zeros(3)
        self._no_motion = np.zeros(6)
        self._no_payload = np.zeros(n)

    def _declare_ports(self) -> None:
        self._wrench_port = self.DeclareVectorInputPort("wrench_compensated", 6)
        self._contact_port = self.DeclareVectorInputPort("contact", 1)
        self._ood_port = self.DeclareVectorInputPort("out_of_domain", 1)
        self._fault_port = self.DeclareVectorInputPort("fault", 1)
        self._tared_port = self.DeclareVectorInputPort("tared", 1)
        if self.track_payload:
            self._gravity_port = self.DeclareVectorInputPort("gravity_S", 3)
            self._motion_port = self.DeclareVectorInputPort("motion_S", 6)
            self._changed_port = self.DeclareVectorInputPort("payload_changed", 1)
            self._detected_port = self.DeclareVectorInputPort("payload_change_detected", 1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("wrench_contact", self._corrected)
        self.DeclareStateOutputPort("bias", self._bias)
        if self.track_payload:
            self.DeclareStateOutputPort("payload", self._payload)
            self.DeclareStateOutputPort("payload_inertia", self._inertia)
        self.DeclareStateOutputPort("tracking", self._tracking)
        self.DeclareStateOutputPort("wrench_std", self._std)

    # -- ports ---------------------------------------------------------------------------------
    def get_input_port_wrench_compensated(self):
        return self.GetInputPort("wrench_compensated")

    def get_input_port_contact(self):
        return self.GetInputPort("contact")

    def get_input_port_out_of_domain(self):
        return self.GetInputPort("out_of_domain")

    def get_input_port_fault(self):
        return self.GetInputPort("fault")

    def get_input_port_tared(self):
        return self.GetInputPort("tared")

    def get_input_port_gravity_S(self):
        return self.GetInputPort("gravity_S")

    def get_input_port_motion_S(self):
        return self.GetInputPort("motion_S")

    def get_input_port_payload_changed(self):
        return self.GetInputPort("payload_changed")

    def get_input_port_payload_change_detected(self):
        return self.GetInputPort("payload_change_detected")

    def get_output_port_wrench_contact(self):
        return self.GetOutputPort("wrench_contact")

    def get_output_port_bias(self):
        return self.GetOutputPort("bias")

    def get_output_port_payload(self):
        return self.GetOutputPort("payload")

    def get_output_port_payload_inertia(self):
        return self.GetOutputPort("payload_inertia")

    def get_output_port_tracking(self):
        return self.GetOutputPort("tracking")

    def get_output_port_wrench_std(self):
        return self.GetOutputPort("wrench_std")

    # -- state -----------------------------------------------------------------------------------
    def set_estimate(self, context, bias, payload=None, *, settled: bool = True) -> None:
        """Starts the estimator from a known bias (and payload) in `context`.

        `payload`: [Δm, Δ(m·c) (3)] (the inertia then starts at 0) or all 10 parameters
        [Δm, Δ(m·c) (3), ΔI_So (6)].

        ``settled=True`` gives it the information of τ seconds of free motion (isotropic
        orientations for the payload), as if it had been running for a long time: no settle
        window, the rate bound applies at once. ``settled=False`` starts as after a tare.
        """
        n = self.n
        theta = np.zeros(n)
        theta[:6] = np.asarray(bias, dtype=float)
        if self.track_payload and payload is not None:
            payload = np.asarray(payload, dtype=float).ravel()
            if len(payload) not in (4, 10):
                raise ValueError(f"payload: 4 ([Δm, Δ(m·c)]) or 10 entries (with ΔI_So), got "
                                 f"{len(payload)}")
            theta[6:6 + len(payload)] = payload
        if settled:
            info = steady_information(self.noise_std, self.prior_std, self.lam, n,
                                      self.payload_map)
            counters = np.zeros(4)
        else:
            info = np.eye(n)
            hold, tare_settle, payload_settle = self._constants[1:4]
            counters = np.array([hold, tare_settle] + ([hold, payload_settle]
                                                       if self.track_payload else [0, 0]))
        x = np.concatenate([theta, theta, info.ravel(), counters,
                            np.zeros(jump_state_size(self.guard))])
        state = context.get_mutable_discrete_state()
        state.set_value(self._x, x)
        state.set_value(self._bias, theta[:6])
        if self.track_payload:
            state.set_value(self._payload, theta[6:10])
            state.set_value(self._inertia, theta[10:])

    def estimator_state(self, context) -> np.ndarray:
        """A copy of the estimator's state (θ, published θ, R, counters) in `context`."""
        return context.get_discrete_state(self._x).get_value().copy()

    def _update(self, context, state):
        # Runs at the sensor rate: few Python calls, the work compiled (track_sample).
        flags = self._flags
        flags[0] = self._contact_port.Eval(context)[0]
        flags[1] = self._ood_port.Eval(context)[0] if self._ood_port.HasValue(context) else 0.0
        flags[2] = (self._fault_port.Eval(context)[0]
                    if self._fault_port.HasValue(context) else 0.0)
        flags[3] = (self._tared_port.Eval(context)[0]
                    if self._tared_port.HasValue(context) else 0.0)
        if self.track_payload:
            gravity = self._gravity_port.Eval(context)
            motion = (self._motion_port.Eval(context) if self._motion_port.HasValue(context)
                      else self._no_motion)
            flags[4] = (self._changed_port.Eval(context)[0]
                        if self._changed_port.HasValue(context) else 0.0)
            if self._detected_port.HasValue(context):  # either announces the change
                flags[4] = max(flags[4], self._detected_port.Eval(context)[0])
            payload = state.get_mutable_value(self._payload)
            inertia = state.get_mutable_value(self._inertia)
        else:
            gravity, motion = self._no_gravity, self._no_motion
            payload = inertia = self._no_payload
        self.track(self._wrench_port.Eval(context), gravity, motion, flags,
                   state.get_mutable_value(self._x), state.get_mutable_value(self._corrected),
                   state.get_mutable_value(self._bias), payload, inertia,
                   state.get_mutable_value(self._tracking), state.get_mutable_value(self._std))

    def track(self, y, gravity, motion, flags, x, corrected, bias, payload, inertia, tracking,
              std) -> None:
        """One sample on plain arrays (what ``_update`` does with the context's): the inputs
        `y` (6), `gravity` (3), `motion` (6) and `flags` [contact, out_of_domain, fault,
        tared, payload_changed], the state updated in place (``payload``/``inertia``: any
        scratch arrays of n entries without ``track_payload``); see
        :func:`~ftdrake.runtime.bias_estimator.track_sample`.
        :class:`~ftdrake.runtime.step.ChainStep` calls it too."""
        track_sample(y, gravity, motion, flags, self.n, self.payload_map, x, self._constants,
                     self._steps, self.noise_std, self.prior_std, corrected, bias, payload,
                     inertia, tracking, std)
