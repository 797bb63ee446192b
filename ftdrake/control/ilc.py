"""Classic iterative learning control (ILC), the baseline the seed paper compares with.

Time-indexed, at the torque level (the paper's Fig. 3 and Eq. 1)::

    u_{k+1}(t) = Q[ u_k(t) + γ · τ_fb,k(t) ],    τ_fb = M̂(q) (kp e + kd ė)

The learning filter is ``L = γ · C``: the feedback controller C (the same computed-torque
PD law the loop runs) scaled by a learning gain γ, so L·e is the torque the feedback
supplied; with ``P`` the closed loop's response from feedforward torque to tracking error,
``Q (I − L P)`` is a contraction for γ ≤ 1 at the low frequencies Q passes (Eq. 1,
ρ(Q(I − LP)) < 1). ``Q`` is a zero-phase low-pass (a Butterworth filter run forwards and
backwards, possible because a whole iteration's signal is known): it stops learning above
its cut-off, where the loop's response is least known and noise would accumulate.

``u`` is indexed by time alone. Run on another trajectory it is replayed at the same times,
which is why it does not transfer (the learned feedforward in
:mod:`ftdrake.systems.learned_feedforward` is indexed by the desired state instead).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem
from scipy.signal import butter, sosfiltfilt


def q_filter(u: np.ndarray, dt: float, cutoff_hz: float, order: int = 2) -> np.ndarray:
    """Zero-phase Butterworth low-pass of `u` (N, n) sampled every `dt` s, along time."""
    u = np.asarray(u, dtype=float)
    nyquist = 0.5 / dt
    if not 0 < cutoff_hz < nyquist:
        raise ValueError(f"Q-filter cut-off must be in (0, {nyquist:g}) Hz; got {cutoff_hz}")
    sos = butter(order, cutoff_hz / nyquist, output="sos")
    padlen = min(3 * (2 * len(sos) + 1), len(u) - 1)
    return sosfiltfilt(sos, u, axis=0, padlen=padlen)


def ilc_update(u: np.ndarray, feedback: np.ndarray, dt: float, *, gain: float = 1.0,
               cutoff_hz: float = 5.0) -> np.ndarray:
    """``Q(u + gain · feedback)``: the next iteration's feedforward (N, n), N·m."""
    u, feedback = np.asarray(u, dtype=float), np.asarray(feedback, dtype=float)
    if u.shape != feedback.shape:
        raise ValueError(f"u {u.shape} and feedback {feedback.shape} differ in shape")
    if not gain > 0:
        raise ValueError(f"learning gain must be > 0; got {gain}")
    return q_filter(u + gain * feedback, dt, cutoff_hz)


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
