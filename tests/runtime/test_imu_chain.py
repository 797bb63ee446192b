"""The runtime chain with a model that takes an IMU at the sensor.

In the simulation's loop the chain's internal wrench equals the model's offline prediction on
the log's rows, sample for sample (the log's IMU columns are what the chain read, α derived
as the chain derives it); the per-sample step equals the diagram, and a missing IMU sample
(NaN) is a fault that holds the last good outputs; a station without an IMU refuses the model.
"""

import dataclasses as dc
import warnings

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from ftdrake import CompensationChain
from ftdrake import conventions as col
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.compensation.estimators.motion_std import MotionStdCompensator
from ftdrake.config import ScenarioConfig
from ftdrake.data.dataset import imu_layout
from ftdrake.errors import ConfigError
from ftdrake.runtime.step import ChainStep
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station


def _config(duration):
    config = ScenarioConfig()
    config.cable.enabled = False
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = duration
    config.imu = dc.replace(config.imu, enabled=True)
    return config


@pytest.fixture(scope="module")
def trained():
    config = _config(0.8)
    log = simulate(build_station(config), progress=False).log
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ImuPayloadCompensator().fit(imu_layout(log),
                                            log[col.wrench_columns(col.MEASURED)].to_numpy())
    return config, model, log


def test_the_chain_in_the_loop_equals_the_offline_prediction(trained):
    config, model, _ = trained
    log = simulate(build_station(config, model), progress=False).log
    in_loop = log[col.wrench_columns("wrench_internal")].to_numpy()
    np.testing.assert_allclose(in_loop, model.predict(imu_layout(log)), rtol=0, atol=1e-9)
    assert np.ptp(in_loop[:, 0]) > 0.01  # it moved: the comparison is not of constants


def test_a_station_without_an_imu_refuses_the_model(trained):
    config, model, _ = trained
    with pytest.raises(ConfigError, match=r"scenario\.imu\.enabled"):
        build_station(dc.replace(config, imu=dc.replace(config.imu, enabled=False)), model)


def run_both(chain, inputs: dict, period: float):
    """The chain's outputs per sample (K × size per name) from the diagram, its inputs fixed
    and advanced one update per sample, and from a ChainStep of the same chain."""
    simulator = Simulator(chain)
    context = simulator.get_mutable_context()
    chain.initialize(context)
    simulator.Initialize()
    step = ChainStep(chain, context)
    fixed = {chain.get_input_port(i).get_name(): chain.get_input_port(i)
             for i in range(chain.num_input_ports())}
    fixed = {name: port.FixValue(context, np.atleast_1d(inputs[name][0]))
             for name, port in fixed.items()}
    names = [chain.get_output_port(i).get_name() for i in range(chain.num_output_ports())]
    diagram, stepped = {name: [] for name in names}, {name: [] for name in names}
    for k in range(len(inputs["wrench_measured"])):
        for name, value in fixed.items():
            value.GetMutableData().get_mutable_value().SetFromVector(
                np.atleast_1d(inputs[name][k]))
        simulator.AdvanceTo((k + 0.5) * period)
        out = step.update(k * period, inputs["wrench_measured"][k], inputs["joint_state"][k],
                          tared=inputs["tared"][k], imu=inputs["imu"][k])
        for name in names:
            diagram[name].append(np.array(chain.GetOutputPort(name).Eval(context)))
            stepped[name].append(out[name].copy())
    return ({n: np.array(v) for n, v in diagram.items()},
            {n: np.array(v) for n, v in stepped.items()})


def assert_equal_outputs(diagram, stepped):
    assert sorted(stepped) == sorted(diagram)
    for name in diagram:
        np.testing.assert_allclose(stepped[name], diagram[name], rtol=0, atol=1e-12,
                                   err_msg=name)


def _inputs(log, nan_rows=()):
    n = 7
    q = log[col.joint_columns(col.Q, n)].to_numpy()
    v = log[col.joint_columns(col.QD_EST, n)].to_numpy()
    imu = log[[*col.imu_columns(col.IMU_ACC), *col.imu_columns(col.IMU_GYRO)]].to_numpy().copy()
    imu[list(nan_rows)] = np.nan
    k = len(log)
    return {"wrench_measured": log[col.wrench_columns(col.MEASURED)].to_numpy(),
            "joint_state": np.hstack([q, v]), "imu": imu, "tared": np.zeros(k)}


@pytest.mark.parametrize("wrapped", [False, True])
def test_the_step_equals_the_diagram_and_a_missing_imu_is_a_fault(trained, wrapped):
    config, model, log = trained
    if wrapped:
        X = imu_layout(log)
        model = MotionStdCompensator(ImuPayloadCompensator()).fit(
            X, log[col.wrench_columns(col.MEASURED)].to_numpy())
    chain = CompensationChain(model, config.chain_config(), n_joints=7)
    assert chain.needs_imu and chain.HasInputPort("imu")
    rows = log.iloc[:300]
    diagram, stepped = run_both(chain, _inputs(rows, nan_rows=(150, 151)), chain.period)
    assert_equal_outputs(diagram, stepped)
    fault = diagram["fault"][:, 0]
    assert fault[150] == 1.0 and fault[151] == 1.0 and fault[149] == 0.0 and fault[152] == 0.0
    internal = diagram["wrench_internal"]
    np.testing.assert_array_equal(internal[151], internal[149])  # held, not a stale value
    assert not np.array_equal(internal[152], internal[149])


def test_replay_feeds_the_imu_from_the_log_and_names_missing_columns(trained):
    from ftdrake.errors import LogError
    from ftdrake.offline.replay import replay

    _, model, log = trained
    result = replay(model, log)
    in_chain = result[col.wrench_columns("wrench_internal")].to_numpy()
    np.testing.assert_allclose(in_chain, model.predict(imu_layout(log)), rtol=0, atol=1e-9)
    with pytest.raises(LogError, match=r"imu_gyro_x.*scenario\.imu\.enabled"):
        replay(model, log.drop(columns=["imu_gyro_x"]))
