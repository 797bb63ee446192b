"""Streams aligned in time: a delay injected between the joint states and the wrench is
recovered from the log, corrected offline, and applied live by the chain's delay line."""

import numpy as np
import pandas as pd
import pytest

import ftdrake
from ftdrake import ScenarioConfig, replay
from ftdrake.conventions import wrench_columns
from ftdrake.data.stream_delay import estimate_stream_delay, fit_aligned, shift_wrench
from ftdrake.offline.replay import chain_config_of

PERIOD = 1e-3
PHYSICS = ["--model", "physics", "--robot", "ftdrake"]


@pytest.fixture(scope="module")
def free_log():
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "fourier"
    scenario.trajectory.duration_s = 10.0
    scenario.validate()
    return ftdrake.simulate(ftdrake.build_station(scenario), progress=False).log


def physics(log):
    return ftdrake.PhysicsPayloadCompensator(features="q,qd,qdd").fit(
        ftdrake.joint_state_layout(log, source="plant"), ftdrake.wrench_targets(log))


@pytest.mark.slow
@pytest.mark.parametrize("injected", [0.002, 0.0075, 0.030])
def test_an_injected_delay_is_recovered_within_one_sample(free_log, injected):
    """The wrench columns moved `injected` s later (the wrench stream lagging); a physics
    model fitted on the delayed log finds it (fit, estimate, correct, fit again), measured
    from the estimate on the log as simulated (whose own offset is the simulated sensor's)."""
    def aligned(log):
        model = ftdrake.PhysicsPayloadCompensator(features="q,qd,qdd")
        return fit_aligned(model, log, source="plant")

    baseline = aligned(free_log)[1].delay_s
    model, dut = aligned(shift_wrench(free_log, -injected))
    assert dut.delay_s - baseline == pytest.approx(injected, abs=PERIOD)
    assert dut.std_s > 0 and dut.period_s == pytest.approx(PERIOD)
    assert model.wrench_delay_s_ == dut.delay_s  # fitted with it (fit's wrench_delay_s)
    # One pass without the refit is biased towards zero by the misaligned fit.
    once = estimate_stream_delay(physics(shift_wrench(free_log, -injected)),
                                 shift_wrench(free_log, -injected)).delay_s
    assert abs(once - baseline - injected) >= abs(dut.delay_s - baseline - injected) - 1e-4


def test_shift_wrench_moves_the_reading_and_keeps_the_joint_state():
    t = np.arange(50) * PERIOD


    log = pd.DataFrame({"t": t, "q_0": np.sin(t), **{c: t**2 + j for j, c in
                                                      enumerate(wrench_columns("meas"))}})
    dut = shift_wrench(log, 0.0025)
    assert len(dut) == 47  # t + 2.5 ms beyond the last t (49 ms): dropped
    np.testing.assert_array_equal(dut["q_0"], log["q_0"][:47])
    np.testing.assert_allclose(dut["meas_Fx"], np.interp(t[:47] + 0.0025, t, t**2), atol=1e-15)


@pytest.mark.slow
def test_the_chain_applies_a_model_s_delay_like_the_offline_correction(free_log, tmp_path):
    """A wrench lagging by 5 samples: the model fitted with the correction keeps the delay
    in its file; the chain (replayed, as live) then delays the joint state by 5 samples, so
    its compensated wrench is the undelayed log's, 5 rows later."""
    lag = 5
    delayed = shift_wrench(free_log, -lag * PERIOD)
    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=5, random_state=0)
    model, estimate = fit_aligned(forest, delayed, delay_s=lag * PERIOD, source="plant")
    assert estimate is None and model.wrench_delay_s_ == pytest.approx(0.005)
    ftdrake.save_model(model, tmp_path / "m.ftd", target_names=list(ftdrake.WRENCH_AXES),
                       target_units=list(ftdrake.WRENCH_UNITS))
    loaded = ftdrake.load_model(tmp_path / "m.ftd")
    assert loaded.wrench_delay_s_ == pytest.approx(0.005)
    assert ftdrake.CompensationChain(loaded).delay_line is not None
    no_delay = ftdrake.ChainConfig(sensor=ftdrake.SensorStreamConfig(wrench_delay_s=0.0))
    assert ftdrake.CompensationChain(loaded, no_delay).delay_line is None
    # The delayed log replayed with the stored delay against the original replayed without:
    # shifting dropped the original's first `lag` rows, so row k of the delayed log holds the
    # joint state of row k + lag and the reading of row k; the delay line pairs the reading
    # of row k with the joint state of row k again (after its first `lag` samples).
    n = len(delayed)
    dut = replay(loaded, delayed)[wrench_columns("wrench_compensated")].to_numpy()
    reference = replay(loaded, free_log.iloc[:n], _without_delay(free_log))
    np.testing.assert_allclose(dut[lag:], reference[wrench_columns("wrench_compensated")]
                               .to_numpy()[lag:], rtol=0, atol=1e-12)
    assert np.abs(dut[lag:] - replay(loaded, delayed, _without_delay(delayed))[
        wrench_columns("wrench_compensated")].to_numpy()[lag:]).max() > 0.01  # the delay matters


@pytest.mark.slow
def test_train_aligns_the_streams_and_the_model_keeps_the_delay(free_log, tmp_path, capsys):
    from ftdrake.cli.main import main as train_cli
    from ftdrake.compensation.files.persistence import read_manifest

    found = {}
    for name, injected in (("as_simulated", 0.0), ("delayed", 0.010)):
        path = tmp_path / f"{name}.parquet"
        ftdrake.save_dataset(shift_wrench(free_log, -injected) if injected else free_log, path)
        out = tmp_path / f"{name}.ftd"
        assert train_cli(["train", "--data", str(path), *PHYSICS, "--align", "--out",
                          str(out), "--quiet"]) == 0
        found[name] = read_manifest(out)["extra"]["stream_delay"]
        assert ftdrake.load_model(out).wrench_delay_s_ == found[name]["delay_s"]
    recovered = found["delayed"]["delay_s"] - found["as_simulated"]["delay_s"]
    assert recovered == pytest.approx(0.010, abs=PERIOD)
    assert found["delayed"]["std_s"] > 0
    assert train_cli(["train", "--data", str(tmp_path / "delayed.parquet"), *PHYSICS,
                      "--delay", "0.01", "--out", str(tmp_path / "given.ftd"), "--quiet"]) == 0
    assert ftdrake.load_model(tmp_path / "given.ftd").wrench_delay_s_ == 0.01
    capsys.readouterr()


def test_a_hybrid_finds_the_delay_its_forest_learnt_on_the_training_rows(free_log):
    """A hybrid's residual forest fitted on the delayed rows reproduces their reading (it
    learnt the delay along the trajectory, so the whole hybrid's prediction shows none); the
    delay is read from its physics part, and fit_aligned finds what it finds with a physics
    model alone."""
    log = shift_wrench(free_log, -0.02)
    forest = ftdrake.RandomForestCompensator(features="q", per_output=False, n_estimators=10,
                                             min_samples_leaf=5, random_state=0)
    hybrid = ftdrake.HybridCompensator(physics=ftdrake.PhysicsPayloadCompensator(),
                                       residual=forest)
    alone = fit_aligned(ftdrake.PhysicsPayloadCompensator(features="q,qd,qdd"), log,
                        source="plant")[1].delay_s
    assert abs(alone) > 5 * PERIOD  # the delay is there to find
    model, found = fit_aligned(hybrid, log, source="plant")
    assert found.delay_s == pytest.approx(alone, abs=PERIOD)
    assert model.wrench_delay_s_ == found.delay_s


def _without_delay(log):
    """The chain config a replay of `log` runs, with no delay line."""
    config = chain_config_of(log)
    config.sensor.wrench_delay_s = 0.0
    return config
