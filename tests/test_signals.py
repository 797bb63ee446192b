"""The loop's q̈ estimate (shared by the compensator, JointStateGravity and training) against
its closed form."""

import numpy as np

from ftdrake.signals import acceleration_filter_gain, causal_acceleration


def test_a_velocity_ramp_gives_the_first_order_step_response():
    """v_k = a·k·T: every backward difference is a, so the filtered estimate is the step
    response of a first-order low-pass, a·(1 − (1 − α)^k), and 0 at k = 0."""
    period, cutoff, a = 0.001, 25.0, np.array([2.0, -0.5, 3.0])
    k = np.arange(400)[:, None]
    alpha = acceleration_filter_gain(cutoff, period)
    got = causal_acceleration(a * k * period, period, cutoff)
    np.testing.assert_allclose(got, a * (1 - (1 - alpha) ** k), rtol=1e-9, atol=1e-12)
    # One column works as a 1-D signal too.
    np.testing.assert_array_equal(causal_acceleration(a[0] * k[:, 0] * period, period, cutoff),
                                  got[:, 0])
