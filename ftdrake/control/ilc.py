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


