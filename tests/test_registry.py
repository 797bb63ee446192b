"""The compensator registry: adding a compensator is one module and one registry line.

A toy compensator defined here is registered with one entry and then works everywhere the
registry feeds: tuning presets, model files, the loop (CompensatorSystem) and ONNX refusal.
"""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from ftdrake import CompensatorSystem, load_model, save_model
from ftdrake.compensation import registry
from ftdrake.compensation.base import Compensator
from ftdrake.compensation.registry import CompensatorEntry
from ftdrake.compensation.tuning import param_grid

N = 2  # joints


class MeanCompensator(Compensator):
    """Predicts the training mean plus `gain` × the first joint angle on every output."""

    def __init__(self, features="q", gain=0.0):
        super().__init__(features=features)
        self.gain = gain

    def _fit(self, Z, Y):
        del Z  # Compensator._fit's signature; the mean ignores the inputs
        self.mean_ = Y.mean(axis=0)

    def _predict(self, Z):
        return self.mean_ + self.gain * Z[:, :1]


@pytest.fixture
def registered(monkeypatch):
    entry = CompensatorEntry("mean", MeanCompensator, "training mean", {"gain": 0.5},
                             {"quick": [{"gain": [0.0, 1.0]}]})
    monkeypatch.setitem(registry.REGISTRY, "mean", entry)
    return entry


def data():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (60, 3 * N))
    return X, rng.normal(size=(60, 6)) + 3.0


def test_every_shipped_compensator_is_registered_once_with_a_distinct_class():
    classes = [e.cls for e in registry.REGISTRY.values()]
    assert registry.names() == ["rf", "svr", "gpr", "physics", "hybrid", "arm"]
    assert len(set(classes)) == len(classes)
    for e in registry.REGISTRY.values():
        assert registry.entry_for(e.cls) is e and registry.entry(e.name) is e


def test_unknown_names_list_the_registered_ones():
    with pytest.raises(ValueError, match=r"unknown compensator 'forest'; expected one of \['rf'"):
        registry.entry("forest")


def test_one_entry_makes_a_new_compensator_buildable_tunable_and_loadable(registered, tmp_path):
    model = registered.build()
    assert model.gain == 0.5
    assert param_grid("quick", model) == [{"gain": [0.0, 1.0]}]
    X, Y = data()
    model.fit(X, Y)
    with pytest.raises(ValueError, match="not a registered compensator"):
        registry.entry_for(object())
    loaded = load_model(save_model(model, tmp_path / "m.ftdm", target_names=list("abcdef"),
                                   target_units=["N"] * 6))
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))


def test_unregistered_compensators_cannot_be_saved(tmp_path):
    X, Y = data()
    with pytest.raises(ValueError, match="not a registered compensator"):
        save_model(MeanCompensator().fit(X, Y), tmp_path / "m.ftdm",
                   target_names=list("abcdef"), target_units=["N"] * 6)


def test_a_new_compensator_runs_in_the_loop_through_its_row_predictor(registered):
    X, Y = data()
    model = registered.build().fit(X, Y)
    assert model.compiled_predictor() is None  # no compiled form: the generic row path
    with pytest.raises(TypeError, match="MeanCompensator has no ONNX export"):
        model.onnx_parts()
    builder = DiagramBuilder()
    q = np.array([0.3, -0.2])
    wrench = np.arange(6.0)
    dut = builder.AddSystem(CompensatorSystem(model, 0.01, n_joints=N))
    builder.Connect(builder.AddSystem(ConstantVectorSource(wrench)).get_output_port(),
                    dut.get_input_port_wrench_measured())
    builder.Connect(builder.AddSystem(ConstantVectorSource(np.r_[q, 0, 0])).get_output_port(),
                    dut.get_input_port_joint_state())
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.05)
    context = dut.GetMyContextFromRoot(simulator.get_context())
    expected = model.mean_ + 0.5 * q[0]  # independent of predict: the toy's own formula
    np.testing.assert_allclose(dut.get_output_port_wrench_internal().Eval(context), expected,
                               rtol=1e-12)
    np.testing.assert_allclose(dut.get_output_port_wrench_compensated().Eval(context),
                               wrench - expected, rtol=1e-12)
