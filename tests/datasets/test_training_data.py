"""load_training_data: one loader for train, evaluate, study and demo.

It must give a `collect` dataset's X and Y exactly as the dataset helpers do, and its causal q̈
option must be the estimate CompensatorSystem makes in the loop.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import ScenarioConfig
from ftdrake.conventions import wrench_columns
from ftdrake.data.dataset import joint_state_layout, save_dataset, wrench_targets
from ftdrake.data.logs import LogError, option_spelling
from ftdrake.data.training import ReadOptions, load_training_data
from ftdrake.errors import ConfigError
from ftdrake.runtime.compensator import CompensatorSystem
from ftdrake.signals import DEFAULT_ACCELERATION_CUTOFF_HZ, causal_acceleration

RATE_HZ = 125.0
DT = 1 / RATE_HZ
N_JOINTS = 3


def sine_log(n_rows: int = 400) -> pd.DataFrame:
    """Joint j follows sin(ω_j t + 0.3) rad with noise, q̇ logged (rad/s); a wrench target."""
    rng = np.random.default_rng(0)
    t = np.arange(n_rows) * DT
    omega = 2 * np.pi * np.array([0.5, 1.0, 2.0])
    phase = omega * t[:, None] + 0.3
    q = np.sin(phase)
    qd = omega * np.cos(phase) + rng.normal(0, 0.01, q.shape)  # a noisy velocity sensor
    frame = {"t": t}
    frame |= {f"q_{j}": q[:, j] for j in range(N_JOINTS)}
    frame |= {f"qd_{j}": qd[:, j] for j in range(N_JOINTS)}
    frame |= {name: np.cos(t) * k for k, name in enumerate(wrench_columns("meas"))}
    return pd.DataFrame(frame)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two 1 s Fourier runs at 100 Hz, from a scenario whose loop filters q̈ at 17 Hz."""
    from ftdrake.sim.collection import collect

    config = ScenarioConfig()
    config.sensor.preset = "robotiq_ft300"  # 100 Hz: a small frame
    config.chain.compensator = dc.replace(config.chain.compensator, acceleration_cutoff_hz=17.0)
    frame = collect(config, 2, kind="fourier", duration=1.0, n_jobs=1, progress=False)
    path = tmp_path_factory.mktemp("dataset") / "d.parquet"
    save_dataset(frame, path)
    return path, frame


@pytest.mark.parametrize("source", ["est", "plant"])
def test_a_dataset_reads_as_the_dataset_helpers_give_it(dataset, source):
    path, frame = dataset
    dut = load_training_data(path, ReadOptions.dataset(source))
    np.testing.assert_array_equal(dut.X, joint_state_layout(frame, source))
    np.testing.assert_array_equal(dut.Y, wrench_targets(frame))
    np.testing.assert_array_equal(dut.groups, frame["trajectory"].to_numpy())
    assert dut.target_names == wrench_columns("meas") and dut.n_joints == 7
    assert dut.derived == [] and dut.warnings == []
    assert dut.scenario_yaml and "2 trajectories" in dut.source


def test_the_causal_estimate_takes_the_scenarios_cutoff(dataset):
    """No cut-off given: a dataset's own scenario's compensator.acceleration_cutoff_hz."""
    path, frame = dataset
    options = ReadOptions(positions=r"re:q_\d+", velocities=r"re:qd_\d+",
                          qdd_estimate="causal")
    dut = load_training_data(path, options)
    assert dut.options.acceleration_cutoff_hz == 17.0
    assert dut.derivation == {"qdd": {"method": "causal", "cutoff_hz": 17.0,
                                      "signal": "causal_acceleration of qd"}}
    for i in (0, 1):
        run = frame[frame["trajectory"] == i]
        period = float(np.median(np.diff(run["t"])))
        expected = causal_acceleration(run.filter(regex=r"^qd_\d+$").to_numpy(), period, 17.0)
        np.testing.assert_allclose(dut.X[dut.groups == i, 14:], expected, rtol=0, atol=1e-12)


def test_causal_option_equals_signals_causal_acceleration(tmp_path):
    log = sine_log()
    log.to_csv(tmp_path / "log.csv", index=False)
    qd = log.filter(regex=r"^qd_").to_numpy()
    for cutoff in (10.0, None):  # None, and no scenario in the file: the config's default
        options = ReadOptions(velocities="qd_*", qdd_estimate="causal",
                              acceleration_cutoff_hz=cutoff)
        dut = load_training_data(tmp_path / "log.csv", options)
        expected = causal_acceleration(qd, DT, cutoff or DEFAULT_ACCELERATION_CUTOFF_HZ)
        np.testing.assert_allclose(dut.X[:, 2 * N_JOINTS:], expected, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(dut.X[:, N_JOINTS:2 * N_JOINTS], qd)
    # The default stays the study's Savitzky–Golay q̈, which differs.
    savgol = load_training_data(tmp_path / "log.csv", ReadOptions(velocities="qd_*"))
    assert np.abs(savgol.X[:, 2 * N_JOINTS:] - expected).max() > 0.1
    assert savgol.derivation["qdd"]["method"] == "savitzky_golay"


class _RowRecorder:
    """A fitted-compensator stand-in for CompensatorSystem: records each row it is given. It
    declares the whole loop contract (ftdrake.compensation.contract.LoopModel)."""

    features = "q,qd,qdd"
    n_joints_ = N_JOINTS
    n_outputs_ = 6
    provides_std = std_includes_noise = temperature_in_ = False
    wrench_delay_s_ = 0.0
    input_min_ = input_max_ = None

    def __init__(self):
        self.rows = []

    def predict(self, X):
        return np.zeros((len(X), 6))

    def predict_std(self, X):
        return np.zeros((len(X), 6))

    def fused_loop_update(self):
        return None

    def reading_to_model_frame(self):
        return None

    def payload_reading_map(self):
        return None

    def robot_description(self):
        return None

    def row_predictor(self):
        def predict(row):
            self.rows.append(np.array(row))
            return np.zeros(6), None

        return predict


def test_causal_option_equals_what_the_compensator_estimates_in_the_loop(tmp_path):
    """The logged [q; q̇] played into CompensatorSystem (sampled at the log's period): the
    q̈ it builds each row from equals the causal option's, row for row."""
    log = sine_log(200)
    log.to_csv(tmp_path / "log.csv", index=False)
    cutoff = 12.0
    train = load_training_data(tmp_path / "log.csv", ReadOptions(
        velocities="qd_*", qdd_estimate="causal", acceleration_cutoff_hz=cutoff))

    q, qd = log.filter(regex=r"^q_").to_numpy(), log.filter(regex=r"^qd_").to_numpy()
    # Zero-order hold whose steps sit half a period before each sample time, so the sample
    # the system reads at t_k = k·DT is row k whatever the rounding of t_k.
    breaks = (np.arange(len(log) + 1) - 0.5) * DT
    samples = np.vstack([np.hstack([q, qd]), np.hstack([q, qd])[-1:]]).T
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(breaks,
                                                                                  samples)))
    recorder = _RowRecorder()
    dut = builder.AddSystem(CompensatorSystem(recorder, DT, acceleration_cutoff_hz=cutoff))
    builder.Connect(source.get_output_port(), dut.get_input_port_joint_state())
    builder.ExportInput(dut.get_input_port_wrench_measured(), "wrench_measured")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.get_input_port(0).FixValue(simulator.get_mutable_context(), np.zeros(6))
    simulator.AdvanceTo((len(log) - 0.5) * DT)

    loop = np.array(recorder.rows)
    assert loop.shape == (len(log), 3 * N_JOINTS)
    np.testing.assert_array_equal(loop[:, :2 * N_JOINTS], np.hstack([q, qd]))
    np.testing.assert_allclose(train.X[:, 2 * N_JOINTS:], loop[:, 2 * N_JOINTS:],
                               rtol=0, atol=1e-9)


def test_read_options_round_trip_and_validate():
    options = ReadOptions(targets="tau_*", qdd_estimate="causal", acceleration_cutoff_hz=20.0)
    assert ReadOptions.from_dict(options.to_dict()) == options
    # An older manifest kept only the column and topic options.
    assert ReadOptions.from_dict({"targets": "tau_*", "time": None}) == ReadOptions(
        targets="tau_*")
    assert options.updated(targets=None, time="stamp") == dc.replace(options, time="stamp")
    with pytest.raises(ConfigError, match="qdd_estimate must be one of"):
        ReadOptions(qdd_estimate="central")
    with pytest.raises(ConfigError, match="unknown read options"):
        ReadOptions.from_dict({"velocity": "qd_*"})


def test_errors_name_the_option_the_way_the_caller_spells_it(tmp_path):
    """Python callers read ``group='COLUMN'``; a front end can make it a flag."""
    log = sine_log()
    pd.concat([log, log]).to_csv(tmp_path / "two.csv", index=False)  # time restarts
    with pytest.raises(LogError, match=r"time goes backwards.*pass group='COLUMN'"):
        load_training_data(tmp_path / "two.csv")
    with option_spelling(lambda name, value: f"--{name} {value}"), \
            pytest.raises(LogError, match=r"pass --group COLUMN to read each apart"):
        load_training_data(tmp_path / "two.csv")
    pd.concat([log.assign(run=0), log.assign(run=1)]).to_csv(tmp_path / "runs.csv", index=False)
    dut = load_training_data(tmp_path / "runs.csv", ReadOptions(group="run"))
    assert dut.rows["used"] == 2 * len(log) and set(dut.groups) == {0, 1}
    with pytest.raises(LogError, match="no such file"):
        load_training_data(tmp_path / "missing.csv")
