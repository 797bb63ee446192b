"""PayloadChangeMonitor: a payload change nobody signalled, told from a contact by gravity.

A rigid payload picked up (or let go) after the tracker settled adds to the contact wrench,
in the sensor frame S (``[Fx Fy Fz Tx Ty Tz]``, N, N·m)::

    F = Δm·g_S,      T = Δ(m·c) × g_S = −[g_S]× Δ(m·c)          (g_S = g − a_So, in S)

— the gravity part of the bias tracker's payload model. As the arm rotates, g_S turns in S
and the payload's wrench turns with it. A press against the environment does not follow
g_S: its force is fixed by the surface (a wall's normal in the world) or by the tool (a wrench
constant in S). So while the detector reports contact the monitor keeps the contact wrench y
and g_S over the last ``window_s`` seconds and compares, in the sensor's noise units (each
axis divided by its σ), three sums of squares:

* SST — the window's own (the contact wrench it has to explain);
* SSE_payload — what the best θ = [Δm, Δ(m·c)] (least squares) leaves;
* SSE_constant — what a wrench constant in S (the window's mean) leaves.

It reports a payload change when the gravity directions span ``min_rotation_deg`` (without
rotation a weight and a steady press look alike), SSE_payload ≤ ``max_unexplained``·SST and
SSE_payload ≤ ``max_ratio_to_constant``·SSE_constant. The ``payload_change`` output then
stays high for ``signal_s``; the chain feeds it to the tracker's ``payload_change_detected``
input, which re-identifies the payload as after a signalled grasp. The window is cleared when
the contact ends and after a decision (then nothing is collected for ``refractory_s``).

**The decision** (``payload_state``, :data:`PAYLOAD_STATES`), at every sample:

* 0 ``none``: the detector reports no contact (and no payload change is being taken over);
* 1 ``undecided``: contact, but the window's gravity directions span less than
  ``min_rotation_deg`` — without rotation a weight and a press look alike, so the change is
  neither called a payload nor a contact;
* 2 ``payload``: a payload change was recognised; held while ``payload_change`` is high and
  for ``refractory_s`` (the tracker re-identifies the payload meanwhile; the chain's detector
  reads this state and does not report the change as contact);
* 3 ``contact``: the window has turned enough and the payload model does not explain it. It
  is judged again at every sample with the window as it slides (a later window a weight
  explains still becomes 2), and ends with the contact.

**What it cannot tell apart.** A force that is constant in the *world* and parallel to
gravity (pushing straight down on the tool) is, to the gravity part, a weight at its point of
application: only its lack of inertia differs, which shows at accelerations comparable to g.
Such a push is reported as a payload change (a press straight up as one let go).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..config import PayloadChangeConfig, SensorConfig, SensorStreamConfig
from .detector import PAYLOAD_DECIDED

__all__ = ["PAYLOAD_STATES", "PayloadChangeMonitor", "payload_change_statistics"]

#: ``payload_state`` values (module docstring, "The decision").
PAYLOAD_STATES = {"none": 0.0, "undecided": 1.0, "payload": PAYLOAD_DECIDED, "contact": 3.0}
_NONE, _UNDECIDED, _PAYLOAD, _CONTACT = PAYLOAD_STATES.values()

#: Entries per window sample: the contact wrench (6) and g_S (3).
_SAMPLE = 9


def payload_regressor(gravity_S: np.ndarray) -> np.ndarray:
    """(N × 6 × 4): the gravity part of the payload's wrench, linear in [Δm, Δ(m·c)], for
    N apparent gravities g_S (N × 3, m/s²): F = Δm·g_S, T = Δ(m·c) × g_S."""
    g = np.asarray(gravity_S, dtype=float)
    A = np.zeros((len(g), 6, 4))
    A[:, :3, 0] = g
    gx, gy, gz = g[:, 0], g[:, 1], g[:, 2]
    # h × g = −[g]× h, with [g]× the cross-product matrix of g.
    A[:, 3, 2], A[:, 3, 3] = gz, -gy
    A[:, 4, 1], A[:, 4, 3] = -gz, gx
    A[:, 5, 1], A[:, 5, 2] = gy, -gx
    return A


def payload_change_statistics(wrench, gravity_S, noise_std) -> dict:
    """The monitor's decision statistics over a window (module docstring).

    `wrench` (N × 6, N, N·m, S), `gravity_S` (N × 3, m/s², S), `noise_std` (6): the axes'
    weights. Returns ``sst``, ``sse_payload``, ``sse_constant`` (dimensionless, in σ² units),
    ``rotation_deg`` (the largest angle between the first row's g_S and any other row's) and
    ``theta`` ([Δm kg, Δ(m·c) kg·m in S], the least-squares payload)."""
    y = np.asarray(wrench, dtype=float) / noise_std
    g = np.asarray(gravity_S, dtype=float)
    A = payload_regressor(g) / np.asarray(noise_std, dtype=float)[None, :, None]
    theta, *_ = np.linalg.lstsq(A.reshape(-1, 4), y.ravel(), rcond=None)
    sse_payload = float(np.sum((y - A @ theta) ** 2))
    sse_constant = float(np.sum((y - y.mean(axis=0)) ** 2))
    unit = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    cos = np.clip(unit @ unit[0], -1.0, 1.0)
    return {"sst": float(np.sum(y**2)), "sse_payload": sse_payload,
            "sse_constant": sse_constant, "rotation_deg": math.degrees(np.arccos(cos.min())),
            "theta": theta}


def is_payload_change(stats: dict, config: PayloadChangeConfig) -> bool:
    """The decision rule of the module docstring on :func:`payload_change_statistics`."""
    return (stats["rotation_deg"] >= config.min_rotation_deg
            and stats["sse_payload"] <= config.max_unexplained * stats["sst"]
            and stats["sse_payload"] <= config.max_ratio_to_constant * stats["sse_constant"])


class PayloadChangeMonitor(LeafSystem):
    """Reports a payload change that nobody signalled (module docstring: the test and its
    limits).

    Input ports:
      wrench_contact (6): the tracker's contact wrench (input − bias − the payload it knows),
        N, N·m, in S.
      gravity_S (3): the apparent gravity at So, g − a_So, in S, m/s² (the tracker's).
      contact (1): the detector's flag (a state output: the previous sample's decision).
    Output ports (updated every ``config.sample_period_s``):
      payload_change (1): 1.0 for ``signal_s`` after a payload change was recognised.
      payload_change_estimate (4): the last recognised change's [Δm (kg), Δ(m·c) (kg·m, about
        So, in S)] relative to what the tracker knew; 0 before any.
      payload_state (1): the decision, 0 none / 1 undecided / 2 payload change / 3 contact
        (module docstring, "The decision"; :data:`PAYLOAD_STATES`).
    State: the window (samples × [wrench (6), g_S (3)]), its fill count and write index, the
    refractory and signal timers (periods), the outputs.
    """

    def __init__(self, config: PayloadChangeConfig, sensor: SensorStreamConfig | SensorConfig):
        super().__init__()
        self.config = config.validate()
        self.period = float(config.sample_period_s)
        self.capacity = max(5, round(config.window_s / self.period))
        spec = sensor.spec()
        # Floored so an ideal sensor (σ = 0) keeps finite weights (as the tracker's).
        self.noise_std = np.maximum(np.asarray(spec.noise_std, dtype=float), 1e-6)
        self._refractory = round(config.refractory_s / self.period)
        self._signal = max(1, round(config.signal_s / self.period))
        self._wrench_port = self.DeclareVectorInputPort("wrench_contact", 6)
        self._gravity_port = self.DeclareVectorInputPort("gravity_S", 3)
        self._contact_port = self.DeclareVectorInputPort("contact", 1)
        # [window (capacity × 9), count, next index, refractory left, signal left]
        self._window = self.DeclareDiscreteState(self.capacity * _SAMPLE + 4)
        self._flag = self.DeclareDiscreteState(1)
        self._estimate = self.DeclareDiscreteState(4)
        self._state = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("payload_change", self._flag)
        self.DeclareStateOutputPort("payload_change_estimate", self._estimate)
        self.DeclareStateOutputPort("payload_state", self._state)

    def get_input_port_wrench_contact(self):
        return self.GetInputPort("wrench_contact")

    def get_input_port_gravity_S(self):
        return self.GetInputPort("gravity_S")

    def get_input_port_contact(self):
        return self.GetInputPort("contact")

    def get_output_port_payload_change(self):
        return self.GetOutputPort("payload_change")

    def get_output_port_payload_change_estimate(self):
        return self.GetOutputPort("payload_change_estimate")

    def get_output_port_payload_state(self):
        return self.GetOutputPort("payload_state")

    def _update(self, context, state):
        self.monitor(self._wrench_port.Eval(context), self._gravity_port.Eval(context),
                     self._contact_port.Eval(context)[0], state.get_mutable_value(self._window),
                     state.get_mutable_value(self._flag), state.get_mutable_value(self._estimate),
                     state.get_mutable_value(self._state))

    def monitor(self, wrench, gravity, contact, x, flag, estimate, payload_state) -> None:
        """One sample on plain arrays (what ``_update`` does with the context's): the inputs
        `wrench` (6), `gravity` (3) and `contact` (the flag's value), the state (window with
        its counters, ``payload_change``, ``payload_change_estimate``, ``payload_state``)
        updated in place. :class:`~ftdrake.runtime.step.ChainStep` calls it too."""
        n = self.capacity * _SAMPLE
        count, index, refractory, signal = (int(v) for v in x[n:])
        signal = max(0, signal - 1)
        flag[0] = 1.0 if signal > 0 else 0.0
        in_contact = contact >= 0.5
        finite = np.all(np.isfinite(wrench)) and np.all(np.isfinite(gravity))
        if refractory > 0 or not in_contact:
            # Waiting after a decision, or the contact ended: start the window afresh.
            taking_over = refractory > 0 or signal > 0
            payload_state[0] = _PAYLOAD if taking_over else _NONE
            x[n:] = (0, 0, max(0, refractory - 1), signal)
            return
        if finite:  # a non-finite sample is not evidence; the window keeps what it has
            x[index * _SAMPLE:(index + 1) * _SAMPLE] = np.concatenate([wrench, gravity])
            index, count = (index + 1) % self.capacity, min(count + 1, self.capacity)
        decision = (self._decide(x[:count * _SAMPLE].reshape(count, _SAMPLE), estimate)
                    if count >= 5 else _UNDECIDED)
        if decision == _PAYLOAD:
            count, index, refractory, signal = 0, 0, self._refractory, self._signal
            flag[0] = 1.0
        payload_state[0] = decision
        x[n:] = (count, index, refractory, signal)

    def _decide(self, samples: np.ndarray, estimate) -> float:
        """The window's decision (a :data:`PAYLOAD_STATES` value); `estimate` set for a
        payload."""
        stats = payload_change_statistics(samples[:, :6], samples[:, 6:], self.noise_std)
        if stats["rotation_deg"] < self.config.min_rotation_deg:
            return _UNDECIDED
        if not is_payload_change(stats, self.config):
            return _CONTACT
        estimate[:] = stats["theta"]
        return _PAYLOAD
