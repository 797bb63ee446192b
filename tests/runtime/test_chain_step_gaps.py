"""ChainStep across a gap of samples (lost or dropped at a live station): ``bridge_gap``
starts the q̈ estimate after the gap from q̈ taken as linear across it, and ``hold`` keeps
the tracker from learning and the detector released (a station's settle window)."""

import numpy as np
import pytest

from ftdrake import ChainConfig, CompensationChain
from ftdrake.runtime.step import ChainStep
from ftdrake.signals import causal_acceleration
from tests.helpers import chain_forest

N = 7
PERIOD = 1e-3
A0 = np.linspace(-0.5, 0.5, N)  # rad/s², q̈ at t = 0
JERK = np.linspace(0.8, -0.4, N)  # rad/s³: q̈ linear in time


def state(t):
    """[q; q̇] (rad, rad/s) of the motion with q̈ = A0 + JERK·t from rest at q = 0.3."""
    v = A0 * t + 0.5 * JERK * t**2
    q = 0.3 + 0.5 * A0 * t**2 + JERK * t**3 / 6
    return np.concatenate([q, v])


def acceleration_estimate(step):
    """The compensator's q̈ estimate (its estimator's state: q̇ before, q̈, jerk, primed)."""
    return step._comp_state[0][N:2 * N]


@pytest.fixture
def step():
    chain = ChainConfig()
    return ChainStep(CompensationChain(chain_forest(False), chain, n_joints=N))


def test_the_estimate_after_a_gap_is_the_acceleration_there(step):
    """Before the gap the estimate follows the ramp of q̈ (as causal_acceleration, computed
    apart, does); after a 60 ms gap, bridged, it is q̈ at the first sample after it (half a
    period before, as without a gap) — where
    the estimate without the bridge reads q̇'s jump as one period's acceleration."""
    times = np.arange(400) * PERIOD
    for t in times:
        step.update(t, np.zeros(6), state(t))
    v = np.array([state(t)[N:] for t in times])
    cutoff = step.chain.config.compensator.acceleration_cutoff_hz
    reference = causal_acceleration(v, PERIOD, cutoff)[-1]
    np.testing.assert_allclose(acceleration_estimate(step), reference, rtol=0, atol=1e-12)
    # Converged: q̈ half a period before the sample (the backward difference's).
    np.testing.assert_allclose(reference, A0 + JERK * (times[-1] - PERIOD / 2), atol=1e-9)
    after = times[-1] + 0.06
    step.bridge_gap(0.06)
    step.update(after, np.zeros(6), state(after))
    np.testing.assert_allclose(acceleration_estimate(step), A0 + JERK * (after - PERIOD / 2),
                               atol=1e-9)
    unbridged = causal_acceleration(np.vstack([v, state(after)[N:]]), PERIOD, cutoff)[-1]
    assert np.abs(unbridged - (A0 + JERK * after)).max() > 1.0  # what the bridge avoids


def test_gaps_that_recur_leave_the_estimate_on_the_acceleration(step):
    """Three of every 16 samples missing, each gap bridged: the estimate settles onto q̈ (the
    ramp, within 1e-5 rad/s² from 1 s on) as without gaps. A bridge that carried the gap's
    own jerk into the filter amplified the error before each gap and diverged."""
    errors = []
    for k in range(2000):
        if k % 16 >= 13:
            continue
        t = k * PERIOD
        if k % 16 == 0 and k > 0:
            step.bridge_gap(4 * PERIOD)
        step.update(t, np.zeros(6), state(t))
        if k >= 1000:
            errors.append(acceleration_estimate(step) - (A0 + JERK * (t - PERIOD / 2)))
    assert np.abs(errors).max() < 1e-5, np.abs(errors).max()


def test_hold_learns_nothing_and_judges_nothing(step):
    """A 20 N reading while held: no contact, no contact force, the tracker's bias and
    state unchanged; once released, the same reading is a contact."""
    x = state(0.0)
    for k in range(100):
        step.update(k * PERIOD, np.zeros(6), x)
    bias = step.outputs["bias"].copy()
    tracker = [a.copy() for a in step._tracker_state]
    pressed = np.array([0.0, 0.0, 20.0, 0.0, 0.0, 0.0])
    for k in range(100, 150):
        out = step.update(k * PERIOD, pressed, x, hold=True)
        assert out["contact"][0] == 0.0 and out["contact_force"][0] == 0.0
    np.testing.assert_array_equal(step.outputs["bias"], bias)
    np.testing.assert_array_equal(step._tracker_state[0], tracker[0])
    for k in range(150, 150 + step.chain.config.detector.debounce_on + 1):
        out = step.update(k * PERIOD, pressed, x)
    assert out["contact"][0] == 1.0 and out["contact_force"][0] > 15.0


def test_after_a_restart_the_estimate_starts_afresh(step):
    """restart_acceleration (a live station's streams whose clock restarted): the next
    update starts the q̈ estimate as the first update of a new step does (q̈ = 0 there), not
    from the jump of q̇ between the old stream and the new; a pending bridge is dropped."""
    wrench = np.zeros(6)
    for k in range(200):
        step.update(k * PERIOD, wrench, state(k * PERIOD))
    assert np.abs(acceleration_estimate(step)).max() > 0.1
    step.bridge_gap(0.5)
    step.restart_acceleration()
    fresh = ChainStep(CompensationChain(chain_forest(False), ChainConfig(), n_joints=N))
    again = state(0.05)  # the stream from another time: q̇ jumps
    step.update(200 * PERIOD, wrench, again)
    fresh.update(0.0, wrench, again)
    np.testing.assert_array_equal(step._comp_state[0], fresh._comp_state[0])
    assert not acceleration_estimate(step).any()
