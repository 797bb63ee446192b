"""Time-indexed ILC: the zero-phase Q-filter, the update law and the torque table system."""

import numpy as np
import pytest

from ftdrake.control import ilc_update, q_filter
from ftdrake.systems.time_indexed_feedforward import TimeIndexedFeedforward

DT = 1e-3


def test_q_filter_is_zero_phase_low_pass():
    t = np.arange(0.0, 4.0, DT)
    slow, fast = np.sin(2 * np.pi * 0.5 * t), np.sin(2 * np.pi * 100.0 * t)
    u = np.column_stack([slow + fast, 2 * slow])
    out = q_filter(u, DT, cutoff_hz=5.0)
    inner = slice(500, -500)  # away from the ends' padding
    # 0.5 Hz passes unchanged and without lag (a causal filter would lag it); 100 Hz is gone
    # (2nd order forwards and backwards: (5/100)^4 ≈ 6e-6).
    np.testing.assert_allclose(out[inner, 0], slow[inner], atol=1e-3)
    np.testing.assert_allclose(out[inner, 1], 2 * slow[inner], atol=1e-3)
    with pytest.raises(ValueError, match="cut-off"):
        q_filter(u, DT, cutoff_hz=600.0)


def test_update_is_q_of_u_plus_gain_times_learning_signal():
    rng = np.random.default_rng(0)
    u, fb = rng.normal(size=(2000, 3)), rng.normal(size=(2000, 3))
    np.testing.assert_allclose(ilc_update(u, fb, DT, gain=0.5, cutoff_hz=10.0),
                               q_filter(u + 0.5 * fb, DT, 10.0), atol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        ilc_update(u, fb[:-1], DT)


def test_table_system_adds_u_at_the_nearest_sample_and_zero_after():
    u = np.arange(12.0).reshape(4, 3)
    dut = TimeIndexedFeedforward(u, DT)
    context = dut.CreateDefaultContext()
    control = np.array([1.0, -1.0, 0.5])
    dut.get_input_port_control().FixValue(context, control)
    for t, row in ((0.0, 0), (0.0014, 1), (0.0026, 3)):
        context.SetTime(t)
        np.testing.assert_allclose(dut.get_output_port_control().Eval(context), control + u[row])
        np.testing.assert_allclose(dut.get_output_port_status().Eval(context),
                                   np.concatenate([u[row], np.zeros(3), np.ones(3)]))
    context.SetTime(0.01)
    np.testing.assert_allclose(dut.get_output_port_correction().Eval(context), np.zeros(3))
