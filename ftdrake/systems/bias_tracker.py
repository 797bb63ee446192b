"""OnlineBiasTracker: the sensor's bias (and optionally a grasped payload) by recursive least
squares with forgetting, frozen during contact. Sits between CompensatorSystem and
ContactDetector::

    compensator.wrench_external ──▶ tracker ──▶ detector.wrench_external
    compensator.out_of_domain, fault ──▶ tracker ◀── detector.contact

Wiring (names of the ports)::

    tracker = builder.AddSystem(OnlineBiasTracker(BiasTrackerConfig(), scenario.sensor))
    builder.Connect(comp.get_output_port_wrench_external(),
                    tracker.get_input_port_wrench_external())
    builder.Connect(comp.get_output_port_out_of_domain(), tracker.get_input_port_out_of_domain())
    builder.Connect(comp.get_output_port_fault(), tracker.get_input_port_fault())
    builder.Connect(tracker.get_output_port_wrench_external(), det.get_input_port_wrench_external())
    builder.Connect(det.get_output_port_contact(), tracker.get_input_port_contact())

The detector's ``contact`` is a state output (updated at the same sample times), so the tracker
reads the flag computed from the previous sample: there is no algebraic loop and no
direct-feedthrough path through the pair.

The model (one sample, sensor frame S, ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m)::

    w_ext = b + [Δm·g_S ; Δ(m·c) × g_S] + contact wrench + noise

b is the bias left after the compensator (tare error, drift); Δm (kg) and Δ(m·c) (kg·m, CoM
about So in S) are a payload picked up after the compensator was trained. Without ``gravity_S``
only b is estimated (6 parameters, identity regressor: one exponentially weighted mean per
axis).

Estimation. θ = [b (6); Δm; Δ(m·c) (3)] by RLS in information form with *stabilised*
exponential forgetting (Kulhavý): per used sample, in coordinates where each parameter is
divided by its prior std (`bias_prior_std`, `payload_prior_std`) and each wrench row by the
sensor's noise σ,

    R ← λ·R + (1 − λ)·I + ΦᵀΦ,      θ ← θ + R⁻¹·Φᵀ·(y − Φθ),      λ = exp(−period/τ).

The memory is ~τ (`time_constant_s`, 20 s by default): in steady state the bias follows a small
step as 1 − exp(−t/τ) exactly (the gain is 1 − λ up to (1 − λ)·σ²/prior², ~1e-10 here). The
(1 − λ)·I term is the small prior that keeps the problem well posed: information that is not
renewed decays to the prior, not to zero, so R stays invertible (no covariance wind-up) and
a direction the data do not see stays where it is.

Payload identifiability. With one orientation of g_S the bias and the payload's gravity wrench
are confounded: the force only gives b_F + Δm·g_S, and the torque only gives the part of Δ(m·c)
perpendicular to g_S. The estimator then keeps the split at its previous (or prior) value, and
the corrected wrench is still right *in that pose*. Δm, all of Δ(m·c) and b separate once g_S
has taken at least two non-parallel directions (three for a well-conditioned CoM) within the
memory — rotate the tool after a grasp. If the bias is already known (the usual case: the
tracker was running before the grasp), one pose gives Δm and the CoM perpendicular to g_S at
once; only the CoM along g_S needs a rotation.

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
   is bounded likewise (|Δṁ|·9.81 ≤ min ḃ_F, |Δ(m·c)˙|·9.81 ≤ min ḃ_T) so a payload change never
   moves the corrected wrench faster than the bias bound either.

Re-tare and grasp. A re-tare (the driver's ``tared`` pulse or level) makes the bias jump; a
grasp (``payload_changed``) adds a weight. The wrench alone cannot tell either from contact, so
both must be signalled: while the signal is high and for ``hold_samples`` − 1 samples after it
(default 3 in all: the compensator lags the sensor by one sample, so the driver's pulse may
come one sample before the new reading), the block's information is reset to the prior before
the update (contact is ignored on those samples; out_of_domain and fault still stop it). The
first sample then re-initialises the block (gain ≈ 1), the following ones average (gain 1/n
until the memory reaches τ), and the published values follow the estimate without the rate
bound for `tare_settle_s` (bias) or `payload_settle_s` (bias and payload, which are coupled) of
used samples. Within those windows the estimator keeps updating even while the detector reports
contact (only out_of_domain and fault stop it): right after a tare or a grasp the corrected
wrench is not yet trustworthy, and an estimate frozen by the first contact it causes would
never recover (measured: a grasp in motion otherwise stayed in false contact to the end of the
run). The price is that a real contact within the window is absorbed like the tare: tare and
grasp are moments to keep the tool free. What the detector sees: with the pulse aligned with
the new reading, the corrected wrench is back at the noise level on the first tared sample (the
re-initialisation takes that sample as the bias: the output reads ≈ 0 on it); a step that comes
d samples before the pulse shows in full for those d samples (no contact with d <
``debounce_on``; otherwise a short contact that releases after ``debounce_off`` quiet samples).
During a settle window a push starting right then is absorbed faster (the estimator's memory is
the time since the signal); the start of a run is treated as both signals.

State: the estimate θ, the published θ, R (information, scaled), 4 counters (holds, settle
windows); the four outputs are state outputs.
"""

import math

import numba
import numpy as np
from pydrake.systems.framework import LeafSystem

from ..config import BiasTrackerConfig, SensorConfig

__all__ = ["BiasTrackerConfig", "OnlineBiasTracker"]

STANDARD_GRAVITY = 9.80665


class OnlineBiasTracker(LeafSystem):
    """Tracks the bias (and optionally a payload) of the external wrench while not in contact.

    Input ports:
      wrench_external (6): measured − predicted internal wrench (CompensatorSystem), N, N·m, S.
      contact (1): the detector's flag (its state output: the previous sample's decision).
      out_of_domain (1, optional): the compensator's flag; unconnected = 0.
      fault (1, optional): the compensator's flag; unconnected = 0.
      tared (1, optional): > 0.5 (a pulse or a short level) when the sensor was re-tared.
      gravity_S (3, with ``track_payload``): gravity expressed in S, m/s² (≈ R_SW·[0, 0, −9.81]).
      payload_changed (1, optional, with ``track_payload``): > 0.5 when a payload was grasped
        or released.
    Output ports (updated every `period` s):
      wrench_external (6): input − bias − [Δm·g_S; Δ(m·c) × g_S], N, N·m, S.
      bias (6): the published bias estimate, N, N·m, S.
      payload (4, with ``track_payload``): [Δm (kg), Δ(m·c) in S (kg·m)].
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
        n = self.n = 10 if self.track_payload else 6
        # Noise σ weights the rows; floored so an ideal sensor (σ = 0) stays well posed.
        self.noise_std = np.maximum(np.asarray(spec.noise_std, dtype=float),
                                    np.maximum(np.asarray(spec.resolution, float), 1e-6))
        self.lam = math.exp(-self.period / c.time_constant_s)
        k = c.rate_bound_sigmas
        bias_rate = k * np.asarray(sensor.drift_std, float) / math.sqrt(c.time_constant_s)
        if math.isinf(k):
            bias_rate = np.full(6, np.inf)
        # ḃ_max (N/s, N·m/s) and the payload's: Δṁ·g ≤ min ḃ_F, Δ(m·c)˙·g ≤ min ḃ_T.
        self.rate_bound = np.concatenate(
            [bias_rate, [bias_rate[:3].min() / STANDARD_GRAVITY],
             np.full(3, bias_rate[3:].min() / STANDARD_GRAVITY)])[:n]
        self.prior_std = np.asarray(list(c.bias_prior_std) + list(c.payload_prior_std))[:n]
        hold = int(c.hold_samples)
        tare_settle = max(hold, round(c.tare_settle_s / self.period))
        payload_settle = max(hold, round(c.payload_settle_s / self.period))
        self._constants = np.array([self.lam, hold, tare_settle, payload_settle])
        self._steps = self.rate_bound * self.period

        # Estimator state: θ (n), published θ (n), R (n²), counters [tare hold, tare settle,
        # payload hold, payload settle] (counted in used samples). A run starts as after a
        # tare (and a grasp, with payload tracking): nothing is known yet.
        theta = np.zeros(n)
        theta[:6] = c.initial_bias
        counters = [hold, tare_settle] + ([hold, payload_settle] if self.track_payload
                                          else [0, 0])
        x0 = np.concatenate([theta, theta, np.eye(n).ravel(), counters])
        self._x = self.DeclareDiscreteState(x0)
        self._corrected = self.DeclareDiscreteState(6)
        self._bias = self.DeclareDiscreteState(np.asarray(c.initial_bias, float))
        self._payload = self.DeclareDiscreteState(4) if self.track_payload else None
        self._tracking = self.DeclareDiscreteState(1)

        self._wrench_port = self.DeclareVectorInputPort("wrench_external", 6)
        self._contact_port = self.DeclareVectorInputPort("contact", 1)
        self._ood_port = self.DeclareVectorInputPort("out_of_domain", 1)
        self._fault_port = self.DeclareVectorInputPort("fault", 1)
        self._tared_port = self.DeclareVectorInputPort("tared", 1)
        if self.track_payload:
            self._gravity_port = self.DeclareVectorInputPort("gravity_S", 3)
            self._changed_port = self.DeclareVectorInputPort("payload_changed", 1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("wrench_external", self._corrected)
        self.DeclareStateOutputPort("bias", self._bias)
        if self.track_payload:
            self.DeclareStateOutputPort("payload", self._payload)
        self.DeclareStateOutputPort("tracking", self._tracking)
        self._flags = np.zeros(5)
        self._no_gravity = np.zeros(3)
        self._no_payload = np.zeros(4)

    # -- ports ---------------------------------------------------------------------------------
    def get_input_port_wrench_external(self):
        return self.GetInputPort("wrench_external")

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

    def get_input_port_payload_changed(self):
        return self.GetInputPort("payload_changed")

    def get_output_port_wrench_external(self):
        return self.GetOutputPort("wrench_external")

    def get_output_port_bias(self):
        return self.GetOutputPort("bias")

    def get_output_port_payload(self):
        return self.GetOutputPort("payload")

    def get_output_port_tracking(self):
        return self.GetOutputPort("tracking")

    # -- state -----------------------------------------------------------------------------------
    def set_estimate(self, context, bias, payload=None, *, settled: bool = True) -> None:
        """Starts the estimator from a known bias (and payload) in `context`.

        ``settled=True`` gives it the information of τ seconds of free motion (isotropic
        orientations for the payload), as if it had been running for a long time: no settle
        window, the rate bound applies at once. ``settled=False`` starts as after a tare.
        """
        n = self.n
        theta = np.zeros(n)
        theta[:6] = np.asarray(bias, dtype=float)
        if self.track_payload and payload is not None:
            theta[6:] = np.asarray(payload, dtype=float)
        if settled:
            info = _steady_information(self.noise_std, self.prior_std, self.lam, n)
            counters = np.zeros(4)
        else:
            info = np.eye(n)
            hold, tare_settle, payload_settle = self._constants[1:]
            counters = np.array([hold, tare_settle] + ([hold, payload_settle]
                                                       if self.track_payload else [0, 0]))
        x = np.concatenate([theta, theta, info.ravel(), counters])
        state = context.get_mutable_discrete_state()
        state.set_value(self._x, x)
        state.set_value(self._bias, theta[:6])
        if self.track_payload:
            state.set_value(self._payload, theta[6:])

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
            flags[4] = (self._changed_port.Eval(context)[0]
                        if self._changed_port.HasValue(context) else 0.0)
            payload = state.get_mutable_value(self._payload)
        else:
            gravity, payload = self._no_gravity, self._no_payload
        _track(self._wrench_port.Eval(context), gravity, flags, self.n,
               state.get_mutable_value(self._x), self._constants, self._steps,
               self.noise_std, self.prior_std, state.get_mutable_value(self._corrected),
               state.get_mutable_value(self._bias), payload,
               state.get_mutable_value(self._tracking))


@numba.njit(cache=True)
def _regressor(g, n, out):
    """Φ (6 × n): w = b + [Δm·g; Δ(m·c) × g]. Rows F then T."""
    out[:, :] = 0.0
    for i in range(6):
        out[i, i] = 1.0
    if n == 10:
        for i in range(3):
            out[i, 6] = g[i]
        # (m·c) × g = −[g]× (m·c)
        out[3, 8], out[3, 9] = g[2], -g[1]
        out[4, 7], out[4, 9] = -g[2], g[0]
        out[5, 7], out[5, 8] = g[1], -g[0]


@numba.njit(cache=True)
def _reset_block(R, n, lo, hi):
    """Information of parameters lo..hi-1 back to the prior (scaled: 1 on the diagonal)."""
    for i in range(lo, hi):
        for j in range(n):
            R[i, j] = 0.0
            R[j, i] = 0.0
        R[i, i] = 1.0


@numba.njit(cache=True)
def _track(y, g, flags, n, x, constants, steps, sigma, prior, corrected, bias, payload,
           tracking):
    """One sample of the tracker; updates the state arrays in place (see the module doc).

    `x` = [θ (n), published θ (n), R (n²), tare hold, tare settle, payload hold, payload
    settle]; `constants` = [λ, hold samples, tare settle samples, payload settle samples];
    `steps` = the rate bound × period per parameter; `flags` = [contact, out_of_domain,
    fault, tared, payload_changed].
    """
    theta = x[:n]
    published = x[n:2 * n]
    R = x[2 * n:2 * n + n * n].reshape((n, n))
    k = 2 * n + n * n  # counters
    lam, hold, tare_settle, payload_settle = constants[0], constants[1], constants[2], constants[3]
    if flags[3] > 0.5:
        x[k], x[k + 1] = hold, max(x[k + 1], tare_settle)
    if n == 10 and flags[4] > 0.5:
        x[k + 2], x[k + 3] = hold, payload_settle
    for v in y:
        if not np.isfinite(v):
            return  # hold every output; not evidence of anything
    for v in g:
        if not np.isfinite(v):
            return
    phi = np.empty((6, n))
    _regressor(g, n, phi)
    # Hold and settle windows (after tared / payload_changed) update through contact: a
    # re-initialised estimate that froze at the first false contact would never recover.
    holding = x[k] > 0 or x[k + 2] > 0 or x[k + 1] > 0 or x[k + 3] > 0
    free = flags[0] < 0.5
    update = flags[1] < 0.5 and flags[2] < 0.5 and (holding or free)
    if update:
        if x[k] > 0:
            _reset_block(R, n, 0, 6)
            x[k] -= 1
        if x[k + 2] > 0:
            _reset_block(R, n, 6, n)
            x[k + 2] -= 1
        # Scaled, whitened regressor Φ' = Σ⁻¹ Φ S and innovation e' = Σ⁻¹ (y − Φθ).
        scaled = np.empty((6, n))
        e = np.empty(6)
        for i in range(6):
            acc = y[i]
            for j in range(n):
                acc -= phi[i, j] * theta[j]
                scaled[i, j] = phi[i, j] * prior[j] / sigma[i]
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
            window = bias_window if j < 6 else payload_window
            delta = theta[j] - published[j]
            if not window:
                delta = min(max(delta, -steps[j]), steps[j])
            published[j] += delta
        if x[k + 1] > 0:
            x[k + 1] -= 1
        if payload_window:
            x[k + 3] -= 1
    for i in range(6):
        acc = y[i]
        for j in range(n):
            acc -= phi[i, j] * published[j]
        corrected[i] = acc
    for i in range(6):
        bias[i] = published[i]
    for j in range(6, n):
        payload[j - 6] = published[j]
    tracking[0] = 1.0 if update else 0.0


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
    the six axis directions of g (exact isotropic second moments)."""
    phi = np.empty((6, n))
    info = np.zeros((n, n))
    directions = STANDARD_GRAVITY * np.vstack([np.eye(3), -np.eye(3)])
    for g in directions:
        _regressor(g, n, phi)
        scaled = phi * prior[None, :] / sigma[:, None]
        info += scaled.T @ scaled / len(directions)
    return info / (1.0 - lam) + np.eye(n)
