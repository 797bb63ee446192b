"""The loop's q̈ estimate (shared by the compensator, JointStateGravity and training) against
closed forms."""

import numpy as np

from ftdrake.signals import (
    DEFAULT_ACCELERATION_CUTOFF_HZ,
    acceleration_filter_gains,
    causal_acceleration,
)


def test_a_velocity_ramp_gives_the_trackers_step_response():
    """v_k = a·k·T: every backward difference is a, so from k = 1 on the estimate is the g–h
    tracker's response to a step of a from 0: q̈_1 = g·a, j_1 = h·a/T, and each later sample
    p = q̈ + T·j, q̈ ← p + g (a − p), j ← j + h (a − p) / T. It settles on a, 0 at k = 0."""
    period, cutoff, a = 0.001, 12.0, np.array([2.0, -0.5, 3.0])
    k = np.arange(400)[:, None]
    g, h = acceleration_filter_gains(cutoff, period)
    expected, qdd, jerk = np.zeros((400, 3)), np.zeros(3), np.zeros(3)
    for i in range(1, 400):
        p = qdd + period * jerk
        qdd, jerk = p + g * (a - p), jerk + h * (a - p) / period
        expected[i] = qdd
    got = causal_acceleration(a * k * period, period, cutoff)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got[-1], a, rtol=1e-6)
    # One column works as a 1-D signal too.
    np.testing.assert_array_equal(causal_acceleration(a[0] * k[:, 0] * period, period, cutoff),
                                  got[:, 0])


def test_a_q_double_dot_ramp_is_followed_without_lag():
    """q̈ = c·t (constant jerk c): after the tracker settles its estimate equals the backward
    difference's own c·(t − T/2) — no lag, where a first-order low-pass at 25 Hz lags by
    1/(2π·25) s, 6.4 ms (c·6.4 ms of error)."""
    period, c = 0.001, 5.0
    t = np.arange(2000) * period
    got = causal_acceleration(0.5 * c * t ** 2, period, DEFAULT_ACCELERATION_CUTOFF_HZ)
    np.testing.assert_allclose(got[1000:], c * (t[1000:] - period / 2), atol=1e-9)


def test_the_tracker_passes_no_more_white_noise_than_the_filter_it_replaced():
    """At the default cut-off and 1 kHz, white noise on q̇ comes out of the estimate with a
    std no larger than the first-order low-pass at 25 Hz (its step: q̈ ← q̈ + α (d − q̈))."""
    period = 0.001
    noise = np.random.default_rng(0).normal(0.0, 1e-3, 40000)
    tracked = causal_acceleration(noise, period, DEFAULT_ACCELERATION_CUTOFF_HZ)[2000:].std()
    alpha, low_passed, out = 1 - np.exp(-2 * np.pi * 25.0 * period), 0.0, []
    for d in np.diff(noise) / period:
        low_passed += alpha * (d - low_passed)
        out.append(low_passed)
    assert tracked <= np.std(out[2000:])
