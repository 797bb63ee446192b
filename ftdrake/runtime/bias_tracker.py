"""OnlineBiasTracker: the sensor's bias (and optionally a grasped payload) by recursive least
squares with forgetting, frozen during contact. Sits between CompensatorSystem and
ContactDetector::

    compensator.wrench_compensated ──▶ tracker ──▶ detector.wrench_contact
    compensator.out_of_domain, fault ──▶ tracker ◀── detector.contact

Wired by :class:`~ftdrake.runtime.chain.CompensationChain`. The detector's ``contact`` is a
state output (updated at the same sample times), so the tracker reads the flag computed from
the previous sample: there is no algebraic loop and no
direct-feedthrough path through the pair.

The model (one sample, sensor frame S, ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m)::

    w_ext = b + [F_P; T_P] + contact wrench + noise
    F_P = Δm·g_S − ([α]× + [ω]×[ω]×) Δ(m·c)
    T_P = Δ(m·c) × g_S − (L(α) + [ω]× L(ω)) ΔI_So

b is the bias left after the compensator (tare error, drift); [F_P; T_P] is the Newton–Euler
wrench (about So) of a rigid payload picked up after the compensator was trained: Δm (kg),
Δ(m·c) (kg·m, the first moment about So in S) and ΔI_So (kg·m², its inertia about So in S,
``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``; L(x) maps them to I·x). g_S = g − a_So is the apparent
gravity at So (``gravity_S``), ω and α the angular velocity and acceleration of S
(``motion_S``), all in S: the convention (and the compiled regressor row) of the physics
payload compensator (:mod:`ftdrake.compensation.physics`), i.e. the reading of a sensor
carrying the payload. Without ``motion_S`` (ω = α = 0) the model is the gravity part alone,
[Δm·g_S; Δ(m·c) × g_S], and ΔI_So stays at its prior (0). Neglected: nothing of a rigid
payload — what remains is the error of g_S, ω, α themselves (on hardware α comes from a
filtered q̈ estimate, see JointStateGravity). Without ``track_payload`` only b is estimated
(6 parameters, identity regressor: one exponentially weighted mean per axis).

Estimation. θ = [b (6); Δm; Δ(m·c) (3); ΔI_So (6)] (16 parameters) by RLS in information form with
*stabilised* exponential forgetting (Kulhavý): per used sample, in coordinates where each parameter
is divided by its prior std (`bias_prior_std`, `payload_prior_std`) and each wrench row by the
sensor's noise σ,

    R ← λ·R + (1 − λ)·I + ΦᵀΦ,      θ ← θ + R⁻¹·Φᵀ·(y − Φθ),      λ = exp(−period/τ).

The memory is ~τ (`time_constant_s`, 20 s by default): in steady state the bias follows a small
step as 1 − exp(−t/τ) exactly (the gain is 1 − λ up to (1 − λ)·σ²/prior², ~1e-10 here). The
(1 − λ)·I term is the small prior that keeps the problem well posed: information that is not
renewed decays to the prior, not to zero, so R stays invertible (no covariance wind-up) and
a direction the data do not see stays where it is. Per sample this is one 16 × 16 update and
Cholesky solve, compiled (a few µs).

Payload identifiability. With one orientation of g_S the bias and the payload's gravity wrench
are confounded: the force only gives b_F + Δm·g_S, and the torque only gives the part of Δ(m·c)
perpendicular to g_S. The estimator then keeps the split at its previous (or prior) value, and
the corrected wrench is still right *in that pose*. Δm, all of Δ(m·c) and b separate once g_S
has taken at least two non-parallel directions (three for a well-conditioned CoM) within the
memory — rotate the tool after a grasp. If the bias is already known (the usual case: the
tracker was running before the grasp), one pose gives Δm and the CoM perpendicular to g_S at
once; only the CoM along g_S needs a rotation. ΔI_So is seen only through α and ω (its torque
is ~|ΔI|·(|α| + |ω|²): 0.0074 kg·m² at 5 rad/s² is 37 mN·m, 30 σ of the ATI Gamma's torque
noise), and all six entries need α in several directions; at rest they keep their value.

When it updates. Only while ``contact`` < 0.5, ``out_of_domain`` < 0.5 and ``fault`` < 0.5 and
the inputs are finite (a NaN counts as "set" for the flags). Otherwise the estimator's state is
held exactly; the corrected wrench is still computed every sample from the held estimate (the
detector needs it). A non-finite wrench or g_S holds every output at its last value.

The slow-push problem: a push that grows slowly must not be taken for bias. Three guards:

1. **Freeze.** The estimator stops the sample after the detector reports contact.
2. **Long memory.** Until detection, the estimator absorbs a ramp r·t only through its
   slow gain: r·t²/(2τ). A 5 N push ramped over 5 s (r = 1 N/s) crosses a 0.5 N threshold
   after 0.5 s; by then the estimate has absorbed 1 N/s · (0.5 s)² / 40 s = 6.25 mN, 1.25 % of
   what the push has reached (0.125 % of the 5 N).
3. **Rate bound.** The bias that is *published* (subtracted, and output on ``bias``) moves
   towards the estimate no faster than |ḃ_i| ≤ k·drift_std_i/√τ (k = `rate_bound_sigmas`,
   3 by default; drift_std from the sensor config, a random walk in N/√s): over the memory τ
   a real drift moves σ_d·√τ, an average rate σ_d/√τ, and exceeds k times that with
   probability ~0.3 % (k = 3). For the default ATI Gamma this is 1.34 mN/s (Fx, Fy), 2.0 mN/s
   (Fz), 34 µN·m/s (T). In the example the published bias moves at most 1.34 mN/s · 0.5 s =
   0.67 mN (1 mN along z) before detection: 0.13–0.2 % of the threshold, so detection is
   delayed by < 1 ms. (Measured with the ContactDetector in the loop and the sensor's noise:
   detected 0.52 s after the push began, published bias moved 0.68 mN, estimate 6.8 mN.)
   Any push growing faster than ḃ_max is detected; only a load that stays below the
   threshold for a long time (0.4 N for 300 s) or grows no faster than a real drift can be
   absorbed — from the wrench alone it cannot be told from drift. The published payload
   is bounded likewise (|Δṁ|·9.81 ≤ min ḃ_F, |Δ(m·c)˙|·9.81 ≤ min ḃ_T, |ΔI˙|·10 rad/s² ≤
   min ḃ_T, 10 rad/s² a brisk |α| + |ω|²: `ANGULAR_SCALE`) so a payload change does not move
   the corrected wrench faster than the bias bound either.

Re-tare and grasp. A re-tare (the driver's ``tared`` pulse or level) makes the bias jump; a grasp
(``payload_changed``) adds a weight. The wrench alone cannot tell either from contact, so both must
be signalled. A re-tare with history is estimated as a jump (below); at the run's start (and
with ``tare_jump_window_s`` 0), and for a grasp: while the signal is high and for
``hold_samples`` − 1 samples after it (default 3 in
all: the compensator lags the sensor by one sample, so the driver's pulse may come one sample before
the new reading), the block's information is reset to the prior before the update (contact is
ignored on those samples; out_of_domain and fault still stop it). A held sample re-initialises the
payload from its gravity part alone (ω = α = 0 in that update): one sample determines Δm and Δ(m·c)
⊥ g_S but not ten parameters, and fitted to single samples the motion terms took up the
compensator's error in the grasp's transient (measured in the loop, 0.5 kg grasp: 170 σ on Ty while
the estimate was frozen by out_of_domain, against 53 σ with the gravity-only hold). The first sample
then re-initialises the block (gain ≈ 1), the following ones average (gain 1/n until the memory
reaches τ), and the published values follow the estimate without the rate bound for `tare_settle_s`
(bias) or `payload_settle_s` (bias and payload, which are coupled) of used samples. Within those
windows the estimator keeps updating even while the detector reports contact (only out_of_domain and
fault stop it): right after a tare or a grasp the corrected wrench is not yet trustworthy, and an
estimate frozen by the first contact it causes would never recover (measured: a grasp in motion
otherwise stayed in false contact to the end of the run). The price is that a real contact within
the window is absorbed like the tare: tare and grasp are moments to keep the tool free. What the
detector sees: with the pulse aligned with the new reading, the corrected wrench is back at the
noise level on the first tared sample (the re-initialisation takes that sample as the bias: the
output reads ≈ 0 on it); a step that comes d samples before the pulse shows in full for those d
samples (no contact with d < ``debounce_on``; otherwise a short contact that releases after
``debounce_off`` quiet samples). During a settle window a push starting right then is absorbed
faster (the estimator's memory is the time since the signal); the start of a run is treated as both
signals.

A re-tare as a jump (``tare_jump_window_s``, 50 ms by default; not at the run's start, where
there is no history). The estimator keeps a mean of the corrected wrench over the last
``tare_jump_window_s`` of used, contact-free samples, leaving out the last ``tare_guard_s``
(10 ms: a pulse that comes a few samples after the new reading does not reach it). At the
signal that mean is the "before" level, ≈ the compensator's error there. The hold samples then
re-initialise from themselves (the output reads the "before" level), and the next
``tare_jump_window_s`` of in-domain samples are averaged: the bias's jump is that average
less the pulse's published bias and the "before" level, and θ's bias moves by it with R kept
— the estimator's memory survives the tare. Because the compensator's error just before and
just after the tare is nearly the same (the arm moves little in 60 ms), it cancels instead of
being taken as bias, as the reset-and-average above does with the error of its settle window
(which the rate bound then sheds only slowly). The price is noise: the jump is known to
σ·√(1/50 + 1/99) ≈ 0.17 σ per axis, not 0.02 σ; the estimator's long memory then refines it.
(tests/test_bias_tracker.py: with a 3–4 σ slowly varying model error, within 2σ at once and
≤ 0.86 σ after, against 1.7 s and 1.3 σ with the reset.)

State: the estimate θ, the published θ, R (information, scaled), 4 counters (holds, settle
windows), the jump's state (a ring of the last `tare_guard_s` of corrected wrenches, the
"before" mean, the pulse's bias, the sum after it, its phase); the outputs are state outputs.
"""

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem

from ..compensation.compiled.payload import regressor_row
from ..config import BiasTrackerConfig, SensorConfig
from ..conventions import STANDARD_GRAVITY

__all__ = ["BiasTrackerConfig", "OnlineBiasTracker"]

#: rad/s²: the scale of |α| + |ω|² the inertia's rate bound is set for (brisk free motion; at
#: the sensor the default scenario's fourier trajectory has 4.6 at its 99th percentile, 6.5 max).
ANGULAR_SCALE = 10.0
#: Parameters with payload tracking: b (6), Δm, Δ(m·c) (3), ΔI_So (6).
N_PAYLOAD = 16


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
        with ``bias_tracker.track_payload_motion`` (off by default: in the loop a grasp
        changes the motion, and fitted in the settle window the motion terms took up the
        compensator's error there — tests/test_tracker_in_loop.py read contact 27 % of the
        time after a grasp with them, < 10 % without).
      payload_changed (1, optional, with ``track_payload``): > 0.5 when a payload was grasped
        or released.
    Output ports (updated every `period` s):
      wrench_contact (6): input − bias − [F_P; T_P] (the payload's wrench, module
        docstring), N, N·m, S.
      bias (6): the published bias estimate, N, N·m, S.
      payload (4, with ``track_payload``): [Δm (kg), Δ(m·c) about So in S (kg·m)].
      payload_inertia (6, with ``track_payload``): ΔI_So [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
        (kg·m², about So, in S).
      tracking (1): 1.0 on samples that updated the estimator.

    `sensor` gives the noise σ per axis (the rows' weights) and the drift (the rate bound);
    `period` defaults to the sensor's sample period. See the module docstring for the
    estimator, the freeze, the rate bound and what tared / payload_changed do.
    """

    def __init__(self, config: BiasTrackerConfig, sensor: SensorConfig,
                 period: float | None = None):
        super().__init__()
        self.config = config.validate()
        spec = sensor.spec()
        self.period = float(1.0 / spec.rate_hz if period is None else period)
        if not (self.period > 0 and math.isfinite(self.period)):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        c = self.config
        self.track_payload = bool(c.track_payload)
        n = self.n = N_PAYLOAD if self.track_payload else 6
        # Noise σ weights the rows; floored so an ideal sensor (σ = 0) stays well posed.
        self.noise_std = np.maximum(np.asarray(spec.noise_std, dtype=float),
                                    np.maximum(np.asarray(spec.resolution, float), 1e-6))
        self.lam = math.exp(-self.period / c.time_constant_s)
        k = c.rate_bound_sigmas
        bias_rate = k * np.asarray(sensor.drift_std, float) / math.sqrt(c.time_constant_s)
        if math.isinf(k):
            bias_rate = np.full(6, np.inf)
        # ḃ_max (N/s, N·m/s) and the payload's: Δṁ·g ≤ min ḃ_F, Δ(m·c)˙·g ≤ min ḃ_T,
        # ΔI˙·ANGULAR_SCALE ≤ min ḃ_T.
        self.rate_bound = np.concatenate(
            [bias_rate, [bias_rate[:3].min() / STANDARD_GRAVITY],
             np.full(3, bias_rate[3:].min() / STANDARD_GRAVITY),
             np.full(6, bias_rate[3:].min() / ANGULAR_SCALE)])[:n]
        self.prior_std = np.asarray(list(c.bias_prior_std) + c.payload_prior())[:n]
        hold = int(c.hold_samples)
        tare_settle = max(hold, round(c.tare_settle_s / self.period))
        payload_settle = max(hold, round(c.payload_settle_s / self.period))
        window = round(c.tare_jump_window_s / self.period)
        self.guard = max(1, round(c.tare_guard_s / self.period))
        self._constants = np.array([self.lam, hold, tare_settle, payload_settle, window,
                                    self.guard])
        self._steps = self.rate_bound * self.period

        # Estimator state: θ (n), published θ (n), R (n²), counters [tare hold, tare settle,
        # payload hold, payload settle] (counted in used samples). A run starts as after a
        # tare (and a grasp, with payload tracking): nothing is known yet.
        theta = np.zeros(n)
        theta[:6] = c.initial_bias
        counters = [hold, tare_settle] + ([hold, payload_settle] if self.track_payload
                                          else [0, 0])
        x0 = np.concatenate([theta, theta, np.eye(n).ravel(), counters,
                             np.zeros(_jump_state_size(self.guard))])
        self._x = self.DeclareDiscreteState(x0)
        self._corrected = self.DeclareDiscreteState(6)
        self._bias = self.DeclareDiscreteState(np.asarray(c.initial_bias, float))
        self._payload = self.DeclareDiscreteState(4) if self.track_payload else None
        self._inertia = self.DeclareDiscreteState(6) if self.track_payload else None
        self._tracking = self.DeclareDiscreteState(1)

        self._wrench_port = self.DeclareVectorInputPort("wrench_compensated", 6)
        self._contact_port = self.DeclareVectorInputPort("contact", 1)
        self._ood_port = self.DeclareVectorInputPort("out_of_domain", 1)
        self._fault_port = self.DeclareVectorInputPort("fault", 1)
        self._tared_port = self.DeclareVectorInputPort("tared", 1)
        if self.track_payload:
            self._gravity_port = self.DeclareVectorInputPort("gravity_S", 3)
            self._motion_port = self.DeclareVectorInputPort("motion_S", 6)
            self._changed_port = self.DeclareVectorInputPort("payload_changed", 1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("wrench_contact", self._corrected)
        self.DeclareStateOutputPort("bias", self._bias)
        if self.track_payload:
            self.DeclareStateOutputPort("payload", self._payload)
            self.DeclareStateOutputPort("payload_inertia", self._inertia)
        self.DeclareStateOutputPort("tracking", self._tracking)
        self._flags = np.zeros(5)
        self._no_gravity = np.zeros(3)
        self._no_motion = np.zeros(6)
        self._no_payload = np.zeros(n)

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
            info = _steady_information(self.noise_std, self.prior_std, self.lam, n)
            counters = np.zeros(4)
        else:
            info = np.eye(n)
            hold, tare_settle, payload_settle = self._constants[1:]
            counters = np.array([hold, tare_settle] + ([hold, payload_settle]
                                                       if self.track_payload else [0, 0]))
        x = np.concatenate([theta, theta, info.ravel(), counters,
                            np.zeros(_jump_state_size(self.guard))])
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
        # Runs at the sensor rate: few Python calls, the work compiled (_track).
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
            payload = state.get_mutable_value(self._payload)
            inertia = state.get_mutable_value(self._inertia)
        else:
            gravity, motion = self._no_gravity, self._no_motion
            payload = inertia = self._no_payload
        _track(self._wrench_port.Eval(context), gravity, motion, flags, self.n,
               state.get_mutable_value(self._x), self._constants, self._steps,
               self.noise_std, self.prior_std, state.get_mutable_value(self._corrected),
               state.get_mutable_value(self._bias), payload, inertia,
               state.get_mutable_value(self._tracking))


@numba.njit(cache=True)
def _regressor(g, motion, n, out):
    """Φ (6 × n), rows F then T, columns θ = [b (6); Δm; Δ(m·c) (3); ΔI_So (6)]: b plus the
    Newton–Euler wrench of the payload (module docstring) for g = g − a_So and motion =
    [ω; α], all in S. The payload's columns are the physics compensator's regressor row
    (:func:`~ftdrake.compensation.compiled.payload.regressor_row`, d = a − g = −g), whose
    parameter order is [m, m·c, I_So, b]."""
    out[:, :] = 0.0
    for i in range(6):
        out[i, i] = 1.0
    if n == N_PAYLOAD:
        A = np.zeros((6, 16))
        d = np.empty(3)
        w = np.zeros(6)  # [ω; α]; an empty `motion`: at rest (the gravity part)
        for i in range(3):
            d[i] = -g[i]
        for i in range(len(motion)):
            w[i] = motion[i]
        regressor_row(w[:3], w[3:], d, A)
        for i in range(6):
            for j in range(10):
                out[i, 6 + j] = A[i, j]


@numba.njit(cache=True)
def _reset_block(R, n, lo, hi):
    """Information of parameters lo..hi-1 back to the prior (scaled: 1 on the diagonal)."""
    for i in range(lo, hi):
        for j in range(n):
            R[i, j] = 0.0
            R[j, i] = 0.0
        R[i, i] = 1.0


@numba.njit(cache=True)
def _track(y, g, motion, flags, n, x, constants, steps, sigma, prior, corrected, bias, payload,
           inertia, tracking):
    """One sample of the tracker; updates the state arrays in place (see the module doc).

    `g` (3) = g − a_So and `motion` (6) = [ω, α], in S; `x` = [θ (n), published θ (n), R (n²), tare
    hold, tare settle, payload hold, payload settle]; `constants` = [λ, hold samples, tare settle
    samples, payload settle samples]; `steps` = the rate bound × period per parameter; `flags` =
    [contact, out_of_domain, fault, tared, payload_changed].
    """
    theta = x[:n]
    published = x[n:2 * n]
    R = x[2 * n:2 * n + n * n].reshape((n, n))
    k = 2 * n + n * n  # counters
    lam, hold, tare_settle, payload_settle = constants[0], constants[1], constants[2], constants[3]
    window, guard = int(constants[4]), int(constants[5])
    jump = x[k + 4:]  # the tare-as-a-jump state (_jump_state_size)
    if flags[3] > 0.5 and not _start_jump(jump, published, hold, window):
        x[k], x[k + 1] = hold, max(x[k + 1], tare_settle)
    if flags[3] <= 0.5:
        jump[_LEVEL_JUMPED] = 0.0  # the level (if any) is over
    jump[_SIGNAL] = flags[3]
    if n == N_PAYLOAD and flags[4] > 0.5:
        x[k + 2], x[k + 3] = hold, payload_settle
    for v in y:
        if not np.isfinite(v):
            return  # hold every output; not evidence of anything
    for v in g:
        if not np.isfinite(v):
            return
    for v in motion:
        if not np.isfinite(v):
            return
    phi = np.empty((6, n))
    _regressor(g, motion, n, phi)
    if jump[_PHASE] > 0:
        _jump_step(y, phi, flags, n, theta, published, jump, window, corrected, bias, payload,
                   inertia, tracking)
        return
    # Hold and settle windows (after tared / payload_changed) update through contact: a
    # re-initialised estimate that froze at the first false contact would never recover.
    holding = x[k] > 0 or x[k + 2] > 0 or x[k + 1] > 0 or x[k + 3] > 0
    free = flags[0] < 0.5
    update = flags[1] < 0.5 and flags[2] < 0.5 and (holding or free)
    if update:
        if x[k] > 0:
            _reset_block(R, n, 0, 6)
            x[k] -= 1
        fit = phi
        if x[k + 2] > 0:
            _reset_block(R, n, 6, n)
            x[k + 2] -= 1
            # A held sample re-initialises the payload from itself alone: the gravity part
            # (Δm, Δ(m·c) ⊥ g_S), which one sample determines; the motion terms need a
            # spread of motion (the settle window's), and fitted to one sample they take up
            # the compensator's error in the grasp's transient.
            fit = np.empty((6, n))
            _regressor(g, motion[:0], n, fit)
        # Scaled, whitened regressor Φ' = Σ⁻¹ Φ S and innovation e' = Σ⁻¹ (y − Φθ).
        scaled = np.empty((6, n))
        e = np.empty(6)
        for i in range(6):
            acc = y[i]
            for j in range(n):
                acc -= fit[i, j] * theta[j]
                scaled[i, j] = fit[i, j] * prior[j] / sigma[i]
            e[i] = acc / sigma[i]
        rhs = np.zeros(n)
        for a in range(n):
            for b in range(n):
                acc = 0.0
                for i in range(6):
                    acc += scaled[i, a] * scaled[i, b]
                R[a, b] = lam * R[a, b] + acc + ((1.0 - lam) if a == b else 0.0)
            for i in range(6):
                rhs[a] += scaled[i, a] * e[i]
        if _cholesky_solve(R, rhs, n):
            for j in range(n):
                theta[j] += prior[j] * rhs[j]
        # Publish: free in a settle window, else at most `steps` per sample.
        payload_window = x[k + 3] > 0
        bias_window = x[k + 1] > 0 or payload_window
        for j in range(n):
            unbounded = bias_window if j < 6 else payload_window
            delta = theta[j] - published[j]
            if not unbounded:
                delta = min(max(delta, -steps[j]), steps[j])
            published[j] += delta
        if x[k + 1] > 0:
            x[k + 1] -= 1
        if payload_window:
            x[k + 3] -= 1
    _publish(y, phi, n, published, corrected, bias, payload, inertia)
    if update and free and x[k] <= 0 and x[k + 1] <= 0:
        _remember(jump, corrected, window, guard)
    tracking[0] = 1.0 if update else 0.0


@numba.njit(cache=True)
def _publish(y, phi, n, published, corrected, bias, payload, inertia):
    """The outputs from the published θ: the corrected wrench y − Φ·θ, the bias, the payload."""
    for i in range(6):
        acc = y[i]
        for j in range(n):
            acc -= phi[i, j] * published[j]
        corrected[i] = acc
    for i in range(6):
        bias[i] = published[i]
    if n == N_PAYLOAD:
        for j in range(4):
            payload[j] = published[6 + j]
        for j in range(6):
            inertia[j] = published[10 + j]


# -- a re-tare as a jump ---------------------------------------------------------------------
# The jump's state (after the four counters), fixed fields first, then the ring of the last
# `guard` corrected wrenches (6·guard).
_BEFORE, _B0, _AFTER = 0, 6, 12  # 6 each: the "before" mean, the pulse's bias, the sum after
_AFTER_N, _PHASE = 18, 19  # samples summed after; samples left (hold + window)
_SIGNAL, _LEVEL_JUMPED = 20, 21  # the last sample's signal; whether this level started a jump
_MEAN, _MEAN_N = 22, 28  # the running mean of the corrected wrench (6), its count
_RING_N, _RING_POS, _RING = 29, 30, 31  # ring entries filled, next slot, the ring


def _jump_state_size(guard: int) -> int:
    return _RING + 6 * guard


@numba.njit(cache=True)
def _remember(jump, corrected, window, guard):
    """Keeps the corrected wrench of a used, contact-free sample: into the ring; the one
    leaving it (`guard` samples old) into the running mean (a mean until `window` samples,
    then an exponential one of that length)."""
    if window <= 0:
        return
    ring = jump[_RING:_RING + 6 * guard].reshape((guard, 6))
    pos = int(jump[_RING_POS])
    if jump[_RING_N] >= guard:
        jump[_MEAN_N] += 1.0
        w = 1.0 / min(jump[_MEAN_N], window)
        for i in range(6):
            jump[_MEAN + i] += (ring[pos, i] - jump[_MEAN + i]) * w
    else:
        jump[_RING_N] += 1.0
    for i in range(6):
        ring[pos, i] = corrected[i]
    jump[_RING_POS] = (pos + 1) % guard


@numba.njit(cache=True)
def _start_jump(jump, published, hold, window):
    """At a tared sample: starts the jump estimate at the signal's rising edge (a level's
    later samples change nothing: the jump is measured right after the edge, where the
    compensator's error is nearest the "before" level's). False when there is no history to
    compare with (the run's start, `window` 0): then the block resets."""
    if window <= 0:
        return False
    if jump[_SIGNAL] > 0.5 and (jump[_PHASE] > 0 or jump[_LEVEL_JUMPED] > 0.5):
        return True  # the same level, estimated (or being estimated) as a jump
    if jump[_PHASE] <= 0 and jump[_MEAN_N] < window:
        return False
    if jump[_PHASE] <= 0:  # a new jump; during one, a second pulse only restarts the hold
        for i in range(6):
            jump[_BEFORE + i] = jump[_MEAN + i]  # the mean corrected wrench before it
            jump[_B0 + i] = published[i]
        jump[_RING_N] = 0.0  # the ring refills after the jump
    jump[_AFTER:_PHASE] = 0.0
    jump[_PHASE] = hold + window
    jump[_LEVEL_JUMPED] = 1.0
    return True


@numba.njit(cache=True)
def _jump_step(y, phi, flags, n, theta, published, jump, window, corrected, bias, payload,
               inertia, tracking):
    """One sample of a re-tare estimated as a jump of the bias (module docstring): the hold
    samples re-initialise from themselves, the next `window` ones average; at the end θ's bias
    moves by the jump and its information is kept. The estimator does not update meanwhile."""
    before, b0, after = jump[_BEFORE:_B0], jump[_B0:_AFTER], jump[_AFTER:_AFTER_N]
    usable = flags[1] < 0.5 and flags[2] < 0.5
    if usable:
        level = np.empty(6)  # the reading less the published payload's wrench
        for i in range(6):
            acc = y[i]
            for j in range(6, n):
                acc -= phi[i, j] * published[j]
            level[i] = acc
        if jump[_PHASE] > window:  # hold: this sample alone
            for i in range(6):
                published[i] = level[i] - before[i]
        else:
            jump[_AFTER_N] += 1.0
            for i in range(6):
                after[i] += level[i]
                published[i] = after[i] / jump[_AFTER_N] - before[i]
        jump[_PHASE] -= 1.0
        if jump[_PHASE] <= 0:
            for i in range(6):
                theta[i] += published[i] - b0[i]
    _publish(y, phi, n, published, corrected, bias, payload, inertia)
    tracking[0] = 0.0


@numba.njit(cache=True)
def _cholesky_solve(R, rhs, n):
    """Solves R·z = rhs in place (rhs ← z) by Cholesky; False (rhs untouched) if not SPD."""
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            acc = R[i, j]
            for m in range(j):
                acc -= L[i, m] * L[j, m]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    z = np.empty(n)
    for i in range(n):
        acc = rhs[i]
        for m in range(i):
            acc -= L[i, m] * z[m]
        z[i] = acc / L[i, i]
    for i in range(n - 1, -1, -1):
        acc = z[i]
        for m in range(i + 1, n):
            acc -= L[m, i] * rhs[m]
        rhs[i] = acc / L[i, i]
    return True


def _steady_information(sigma, prior, lam, n):
    """R (scaled) after a long run of free motion: E[Φ'ᵀΦ']/(1 − λ) + I, the expectation over
    the six axis directions of g (exact isotropic second moments), at rest: the inertia's
    information stays at its prior (motion is not assumed)."""
    phi = np.empty((6, n))
    info = np.zeros((n, n))
    directions = STANDARD_GRAVITY * np.vstack([np.eye(3), -np.eye(3)])
    for g in directions:
        _regressor(g, np.zeros(6), n, phi)
        scaled = phi * prior[None, :] / sigma[:, None]
        info += scaled.T @ scaled / len(directions)
    return info / (1.0 - lam) + np.eye(n)
