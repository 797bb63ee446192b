"""Derivatives of sampled joint positions and velocities, shared by training and the loop.

Two estimates, the first for offline logs, the second what a controller has at run time:

* :func:`savgol_derivative` – Savitzky–Golay derivative of q, for noisy real logs; non-causal.
* :func:`causal_acceleration` – the estimate ``CompensatorSystem`` makes in the loop: a
  backward difference of q̇ tracked by a critically damped g–h filter. Training on it gives a
  ``q,qd,qdd`` model the same q̈ at run time as in training.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.signal import savgol_filter

# The loop's default q̈ cut-off: defined with the shared constants, so that the config reads
# it without this module's numba and scipy; imported from here by the loop and the readers.
from .conventions import DEFAULT_ACCELERATION_CUTOFF_HZ  # noqa: F401


def savgol_derivative(
    x: np.ndarray, dt: float, deriv: int, window_s: float = 0.1, polyorder: int = 4
) -> np.ndarray:
    """Savitzky–Golay derivative of uniformly sampled rows of `x` (along axis 0).

    Args:
      x: (N, ...) samples, e.g. joint positions in rad.
      dt: sample period in s (a log's median period).
      deriv: 1 for d/dt (rad/s), 2 for d²/dt² (rad/s²).
      window_s: fit window in s, rounded to an odd number of samples (at least
        ``polyorder + 1``, at most N). The default 0.1 s is 13 samples at 125 Hz and 101 at
        1 kHz; with `polyorder` 4 it passes motion up to 5 Hz with < 1.2 % loss in the first
        and < 0.7 % in the second derivative, is -3 dB at 12–14 Hz and passes < 14 % of
        anything above 30 Hz (sensor noise). Shorten it for faster motion.
      polyorder: degree of the local polynomial fit.

    Raises ValueError when there are too few samples for the fit.
    """
    n_rows = len(x)
    window = 2 * round(window_s / dt / 2) + 1
    window = max(window, polyorder + 1 + polyorder % 2)  # odd and > polyorder
    window = min(window, n_rows if n_rows % 2 else n_rows - 1)
    if window <= polyorder:
        raise ValueError(
            f"{n_rows} samples are too few for a Savitzky–Golay fit of order {polyorder}"
        )
    return savgol_filter(x, window, polyorder, deriv=deriv, delta=dt, axis=0)


def acceleration_filter_gains(cutoff_hz: float, period: float) -> tuple[float, float]:
    """(g, h) of the loop's q̈ tracker at `cutoff_hz`, sampled every `period` s: the
    critically damped (fading-memory) g–h filter, g = 1 − θ², h = (1 − θ)² with
    θ = exp(−2π · cutoff · period)."""
    theta = math.exp(-2 * math.pi * cutoff_hz * period)
    return 1.0 - theta * theta, (1.0 - theta) ** 2


def causal_acceleration(qd: np.ndarray, period: float, cutoff_hz: float) -> np.ndarray:
    """q̈ as ``CompensatorSystem`` estimates it, row by row, from q̇ sampled every `period`.

    A g–h tracker (:func:`acceleration_filter_gains`) of the backward difference
    ``d_k = (q̇_k − q̇_{k−1}) / period`` with a jerk state j: ``p = q̈_{k−1} + period·j``,
    ``q̈_k = p + g (d_k − p)``, ``j ← j + h (d_k − p) / period``; ``q̈_0 = 0``, j starts at 0.
    It follows a q̈ that changes at a constant rate without lag, where a first-order low-pass
    lags by 1 / (2π·cutoff) s.
    """
    qd = np.asarray(qd, dtype=float)
    rows = np.ascontiguousarray(qd.reshape(len(qd), -1))
    out = np.zeros_like(rows)
    g, h = acceleration_filter_gains(cutoff_hz, period)
    _causal_acceleration_rows(rows, g, h, float(period), out)
    return out.reshape(qd.shape)


def estimator_size(n: int) -> int:
    """3n + 1: the previous q̇ (n), the q̈ estimate (n), the jerk (n), the primed flag."""
    return 3 * n + 1


@numba.njit(cache=True)
def causal_acceleration_step(v, estimator, g, h, period, vdot):
    """One sample of :func:`causal_acceleration` in place, for loops at the sensor rate.

    `estimator` (3n + 1) holds the previous v, the previous estimate, the jerk and a primed
    flag (0 before the first sample, which gives v̇ = 0); `vdot` (n) receives the new
    estimate.
    """
    n = len(v)
    primed = estimator[3 * n] != 0.0
    for i in range(n):
        if primed:
            predicted = estimator[n + i] + period * estimator[2 * n + i]
            innovation = (v[i] - estimator[i]) / period - predicted
            vdot[i] = predicted + g * innovation
            estimator[2 * n + i] += h * innovation / period
        else:
            vdot[i] = 0.0
            estimator[2 * n + i] = 0.0
        estimator[i], estimator[n + i] = v[i], vdot[i]
    estimator[3 * n] = 1.0


@numba.njit(cache=True)
def hold_acceleration(v, vdot, estimator):
    """Puts :func:`causal_acceleration_step`'s `estimator` at a measured q̇ `v` and q̈ `vdot`
    (a robot that reports q̈): the next step starts from them, with no jerk."""
    n = len(v)
    for i in range(n):
        estimator[i], estimator[n + i], estimator[2 * n + i] = v[i], vdot[i], 0.0
    estimator[3 * n] = 1.0


@numba.njit(cache=True)
def _causal_acceleration_rows(qd, g, h, period, out):
    estimator = np.zeros(3 * qd.shape[1] + 1)
    for k in range(qd.shape[0]):
        causal_acceleration_step(qd[k], estimator, g, h, period, out[k])
