"""Derivatives of sampled joint positions and velocities, shared by training and the loop.

Two estimates, the first for offline logs, the second what a controller has at run time:

* :func:`savgol_derivative` – Savitzky–Golay derivative of q, for noisy real logs; non-causal.
* :func:`causal_acceleration` – the estimate ``CompensatorSystem`` makes in the loop: a
  backward difference of q̇ low-passed by a first-order filter. Training on it gives a
  ``q,qd,qdd`` model the same q̈ at run time as in training.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.signal import savgol_filter


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


def acceleration_filter_gain(cutoff_hz: float, period: float) -> float:
    """α of the loop's first-order low-pass at `cutoff_hz` sampled every `period` s."""
    return 1.0 - math.exp(-2 * math.pi * cutoff_hz * period)


def causal_acceleration(qd: np.ndarray, period: float, cutoff_hz: float) -> np.ndarray:
    """q̈ as ``CompensatorSystem`` estimates it, row by row, from q̇ sampled every `period`.

    ``q̈_0 = 0``; ``q̈_k = q̈_{k−1} + α ((q̇_k − q̇_{k−1}) / period − q̈_{k−1})`` with α from
    :func:`acceleration_filter_gain`. It lags the true q̈ by about 1 / (2π·cutoff) s.
    """
    qd = np.asarray(qd, dtype=float)
    rows = np.ascontiguousarray(qd.reshape(len(qd), -1))
    out = np.zeros_like(rows)
    _causal_acceleration_rows(rows, acceleration_filter_gain(cutoff_hz, period), float(period),
                              out)
    return out.reshape(qd.shape)


@numba.njit(cache=True)
def causal_acceleration_step(v, estimator, alpha, period, vdot):
    """One sample of :func:`causal_acceleration` in place, for loops at the sensor rate.

    `estimator` (2n + 1) holds the previous v, the previous estimate and a primed flag (0
    before the first sample, which gives v̇ = 0); `vdot` (n) receives the new estimate.
    """
    n = len(v)
    primed = estimator[2 * n] != 0.0
    for i in range(n):
        if primed:
            vdot[i] = estimator[n + i] + alpha * ((v[i] - estimator[i]) / period
                                                  - estimator[n + i])
        else:
            vdot[i] = 0.0
        estimator[i], estimator[n + i] = v[i], vdot[i]
    estimator[2 * n] = 1.0


@numba.njit(cache=True)
def _causal_acceleration_rows(qd, alpha, period, out):
    estimator = np.zeros(2 * qd.shape[1] + 1)
    for k in range(qd.shape[0]):
        causal_acceleration_step(qd[k], estimator, alpha, period, out[k])
