"""The compiled paths' chain update (:func:`ftdrake.hardware.fast.chain.chain_update`)
against ChainStep.update, bit for bit: the forest and the physics model, the bias tracker on
and off, over free motion, a press and a NaN reading."""

import numpy as np
import pytest

from ftdrake import ChainConfig
from ftdrake.hardware.fast.chain import chain_update, step_arguments
from ftdrake.runtime.chain import CompensationChain
from ftdrake.runtime.step import ChainStep
from tests.helpers import fused_forest, fused_physics


@pytest.mark.parametrize(("make", "tracker"), [(fused_forest, True), (fused_physics, True),
                                               (fused_physics, False)],
                         ids=["forest", "physics", "physics, tracker off"])
def test_the_compiled_chain_update_equals_the_chain_step(make, tracker):
    """Bit for bit, over free motion, a press and a NaN reading (faults included)."""
    model = make()
    n = model.n_joints_
    chain = ChainConfig()
    chain.bias_tracker.enabled = tracker

    def step():
        return ChainStep(CompensationChain(model, chain, n_joints=n, gravity="joint_state"))

    reference, dut = step(), step()
    arguments = step_arguments(dut)
    rng = np.random.default_rng(3)
    contacts = 0
    for k in range(600):
        t = k * dut.period
        x = np.r_[0.5 * np.sin(t * (1 + np.arange(n))), 0.5 * np.cos(t * (1 + np.arange(n)))]
        w = rng.normal(size=6) * 0.05 + (30.0 if 300 <= k < 400 else 0.0)
        if k == 1100:
            w[1] = np.nan
        expected = reference.update(t, w, x)
        dut._wrench[:], dut._joint_state[:] = w, x
        chain_update(t, dut._wrench, dut._joint_state, *arguments)
        for name, value in expected.items():
            np.testing.assert_array_equal(dut.outputs[name], value, err_msg=f"{name} at {k}")
        contacts += expected["contact"][0] > 0.5
    assert contacts > 50


