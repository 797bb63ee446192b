"""Replay: the runtime chain run offline over a log gives the in-loop chain's numbers."""

import json

import numpy as np
import pandas as pd
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

import ftdrake
from ftdrake import LogError, ScenarioConfig, replay, save_model
from ftdrake.cli.main import main
from ftdrake.conventions import WRENCH_AXES, WRENCH_UNITS, wrench_columns
from ftdrake.runtime.delay_line import DelayLine
from ftdrake.signals import causal_acceleration
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.testing import fit_forest

CHAIN_COLUMNS = [*wrench_columns("wrench_internal"), *wrench_columns("wrench_compensated"),
                 *wrench_columns("wrench_contact"), *wrench_columns("wrench_std"),
                 "contact", "contact_force", "fault", "out_of_domain",
                 *wrench_columns("bias"), *wrench_columns("tracker_std")]


@pytest.fixture(scope="module")
def contact_run():
    """The demo's contact scenario (a 12 mm press on the table after free motion) with a
    small forest, trained on the first 0.5 s, in the loop: (scenario, model, log)."""
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "contact"
    scenario.validate()
    model = fit_forest(scenario, duration=0.5)
    log = simulate(build_station(scenario, model), progress=False).log
    return scenario, model, log


@pytest.mark.slow
def test_replay_of_a_simulated_log_equals_the_loop(contact_run):
    scenario, model, log = contact_run
    assert log["contact"].sum() > 1000 and log["contact_true"].sum() > 1000  # a real press
    dut = replay(model, log, scenario.chain_config(), pairing="simulated")
    assert list(dut.columns) == ["t", *CHAIN_COLUMNS]
    np.testing.assert_array_equal(dut["t"], log["t"])
    for name in CHAIN_COLUMNS:
        np.testing.assert_allclose(dut[name], log[name], rtol=0, atol=1e-12, err_msg=name)
    # The held view is the aligned one a row later: what the output ports held on arrival.
    held = replay(model, log, scenario.chain_config(), pairing="simulated", view="held")
    assert held.iloc[0, 1:].isna().all()
    np.testing.assert_array_equal(held[CHAIN_COLUMNS].to_numpy()[1:],
                                  dut[CHAIN_COLUMNS].to_numpy(dtype=float)[:-1])
    # Each update of the aligned view: the compensator's output is wrench − model(inputs) of
    # the same update (the previous row's reading in the simulated pairing), computed here
    # independently with the model's batch predict on the loop's q̈ estimate.
    row = replay(model, log, scenario.chain_config())
    X = np.hstack([ftdrake.joint_state_layout(log, source="plant")[:, :14],
                   causal_acceleration(
                       log[[f"qd_{i}" for i in range(7)]].to_numpy(), 1e-3,
                       scenario.chain.compensator.acceleration_cutoff_hz)])
    expected = log[wrench_columns("meas")].to_numpy() - model.predict(X)
    np.testing.assert_allclose(row[wrench_columns("wrench_compensated")], expected, atol=1e-9)


@pytest.mark.slow
def test_replay_command_writes_the_function_s_result(contact_run, tmp_path, capsys):
    scenario, model, log = contact_run
    log.iloc[:3000].to_parquet(tmp_path / "log.parquet")
    save_model(model, tmp_path / "model.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    ftdrake.save_config(scenario, tmp_path / "scenario.yaml")
    assert main(["replay", "--model", str(tmp_path / "model.ftd"), "--log",
                 str(tmp_path / "log.parquet"), "--out", str(tmp_path / "out.csv"),
                 "--config", str(tmp_path / "scenario.yaml"), "--pairing", "simulated"]) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    got = pd.read_csv(tmp_path / "out.csv")
    expected = log.iloc[:3000]
    assert report["rows"] == len(got) == 3000
    np.testing.assert_allclose(got[CHAIN_COLUMNS], expected[CHAIN_COLUMNS], atol=1e-9)


def test_replay_names_a_missing_column_and_what_produces_it():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (100, 21))
    model = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(X, X[:, :6])
    log = pd.DataFrame({"t": np.arange(20) * 1e-3,
                        **{f"q_{i}": np.zeros(20) for i in range(7)},
                        **{f"qd_{i}": np.zeros(20) for i in range(7)},
                        **{c: np.zeros(20) for c in wrench_columns("meas")[:5]}})
    with pytest.raises(LogError, match=r"meas_Tz.*the sensor's reading.*add_recorder"):
        replay(model, log)


def test_replay_computes_missing_velocities_as_train_does(tmp_path, capsys):
    """A log without qd_* columns: replay computes q̇ from q as train and evaluate do
    (issue 42 item 20; it used to refuse the log) and says so; the result equals a replay of
    the same log with the reader's q̇ written in, computed independently by
    load_training_data."""
    rng = np.random.default_rng(1)
    t = np.arange(400) * 0.01
    frame = pd.DataFrame({"t": t, **{f"q_{i}": 0.5 * np.sin(0.7 * t * (i + 1) + i)
                                     for i in range(7)}})
    for c in wrench_columns("meas"):
        frame[c] = rng.normal(size=len(t))
    X = rng.uniform(-1, 1, (200, 21))
    model = ftdrake.RandomForestCompensator(features="q,qd", n_estimators=3).fit(X, X[:, 7:13])
    save_model(model, tmp_path / "m.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    frame.to_csv(tmp_path / "bare.csv", index=False)
    qd = ftdrake.load_training_data(tmp_path / "bare.csv").X[:, 7:14]
    given = frame.assign(**{f"qd_{i}": qd[:, i] for i in range(7)})
    given.to_csv(tmp_path / "given.csv", index=False)
    for name in ("bare", "given"):
        assert main(["replay", "--model", str(tmp_path / "m.ftd"), "--log",
                     str(tmp_path / f"{name}.csv"), "--out", str(tmp_path / f"{name}_out.csv")
                     ]) == 0
    err = capsys.readouterr().err
    assert ("warning: replay: the log has no velocity columns; q̇ computed from q_0..q_6 as "
            "train and evaluate compute it (Savitzky–Golay, 0.1 s window, order 4; "
            "--velocities PAT chooses recorded ones)") in err
    bare, given = (pd.read_csv(tmp_path / f"{n}_out.csv") for n in ("bare", "given"))
    np.testing.assert_allclose(bare.to_numpy(), given.to_numpy(), rtol=0, atol=1e-12)
    # The model predicts q̇_0 as Fx: its prediction follows the computed q̇.
    assert np.corrcoef(bare["wrench_internal_Fx"], qd[:, 0])[0, 1] > 0.8


@pytest.mark.parametrize("delay", [0.0, 1.0, 2.4, 3.75])
def test_delay_line_outputs_the_input_delay_samples_ago(delay):
    """Against np.interp of the input's samples (held at the first before it starts)."""
    period = 1e-3
    t = np.arange(40) * period
    u = np.c_[np.sin(40 * t), t**2]
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
        np.r_[t, t[-1] + period], np.c_[u.T, u[-1]])))
    dut = builder.AddSystem(DelayLine(2, delay, period))
    builder.Connect(source.get_output_port(), dut.get_input_port_signal())
    logger = LogVectorOutput(dut.get_output_port_delayed(), builder, period)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    # Sample the output just after each update: the logger publishes before the update at
    # the same time, so read it one period later.
    simulator.AdvanceTo(t[-1])
    got = logger.FindLog(simulator.get_context()).data().T
    expected = np.column_stack([np.interp(t - delay * period, t, u[:, j]) for j in range(2)])
    # The log at t_k shows the output computed with the input u[k] and the buffer of the
    # updates before t_k.
    np.testing.assert_allclose(got, expected, atol=1e-12)


@pytest.mark.slow
def test_evaluate_detection_takes_a_replay_and_names_what_is_missing(contact_run):
    scenario, model, log = contact_run
    noise = scenario.sensor.spec().noise_std
    truth_only = log.drop(columns=CHAIN_COLUMNS)
    with pytest.raises(LogError, match=r"'contact' \(the runtime chain's outputs.*replay"):
        ftdrake.evaluate_detection(truth_only, noise)
    replayed = replay(model, truth_only, scenario.chain_config(), pairing="simulated")
    assert ftdrake.evaluate_detection(truth_only, noise, replayed) == \
        ftdrake.evaluate_detection(log, noise)
    # Without the simulator's internal wrench, that metric is named as not computed.
    partial = ftdrake.evaluate_detection(log.drop(columns=wrench_columns("internal_true")), noise)
    assert partial["compensation_error_rms"] is None
    assert "simulate's log" in partial["not_computed"]["compensation_error_rms"]
    assert partial["detected_contacts"] == ftdrake.evaluate_detection(log, noise)[
        "detected_contacts"] >= 1


def test_joint_state_layout_names_the_source_that_the_log_has():
    frame = pd.DataFrame({f"{p}_{i}": np.zeros(3) for p in ("q", "qd", "qdd") for i in range(2)})
    with pytest.raises(LogError, match=r"qd_est_0.*source='plant'"):
        ftdrake.joint_state_layout(frame)
    assert ftdrake.joint_state_layout(frame, source="plant").shape == (3, 6)
    with pytest.raises(LogError, match="add_recorder"):
        ftdrake.joint_state_layout(frame[["q_0", "q_1"]])


def test_replay_command_reads_an_lcm_log(tmp_path, capsys):
    """An lcm-logger file of joint states and F/T messages: rows paired by timestamp, each
    row one update; the compensated wrench is reading − model(row)."""
    lcm = pytest.importorskip("lcm")
    from ftdrake.hardware import HardwareConfig
    from ftdrake.hardware.messages import encode_joint_state, encode_wrench

    rng = np.random.default_rng(2)
    X = rng.uniform(-1, 1, (300, 21))
    model = ftdrake.RandomForestCompensator(features="q", n_estimators=3, random_state=0)
    model.fit(X, np.sin(X[:, :6]))
    save_model(model, tmp_path / "m.ftd", target_names=list(WRENCH_AXES),
               target_units=list(WRENCH_UNITS))
    hardware = HardwareConfig()
    log = lcm.EventLog(str(tmp_path / "run.lcmlog"), "w", overwrite=True)
    q, w = rng.uniform(-1, 1, (40, 7)), rng.normal(size=(40, 6))
    for k in range(40):
        t = (k + 1) * 1e-3
        log.write_event(int(t * 1e6), hardware.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q[k], np.zeros(7)))
        log.write_event(int(t * 1e6) + 1, hardware.ft_channel, encode_wrench(t, w[k]))
    log.close()
    assert main(["replay", "--model", str(tmp_path / "m.ftd"), "--log",
                 str(tmp_path / "run.lcmlog"), "--out", str(tmp_path / "out.parquet")]) == 0
    got = pd.read_parquet(tmp_path / "out.parquet")
    expected = w - model.predict(np.c_[q, np.zeros((40, 14))])
    np.testing.assert_allclose(got[wrench_columns("wrench_compensated")], expected, atol=1e-9)
    assert json.loads(capsys.readouterr().out)["rows"] == 40
