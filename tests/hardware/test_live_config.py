"""A live robot's config file: the chain section plus its transport (LiveConfig), a chain
config alone, and a scenario file read for its chain until the next release."""

import warnings

import pytest

import ftdrake
from ftdrake.cli.main import main
from ftdrake.hardware.live_config import load_live_config

LIVE = """
chain:
  detector: {force_on: 4.0}
  sensor: {rate_hz: 500.0, noise_std: [0.05, 0.05, 0.08, 0.002, 0.002, 0.002]}
lcm: {lcm_url: "memq://", ft_channel: "MY_FT"}
ros2: {joint_names: [a1, a2, a3, a4, a5, a6, a7], wrench_topic: /ft/wrench}
"""


def test_a_live_file_holds_the_chain_and_its_transports(tmp_path):
    path = tmp_path / "live.yaml"
    path.write_text(LIVE)
    live = load_live_config(path)
    assert live.chain.detector.force_on == 4.0
    assert live.chain.sensor.period == pytest.approx(1 / 500)
    assert live.chain.sensor.spec().noise_std[2] == 0.08
    assert live.lcm.ft_channel == "MY_FT" and live.ros2.wrench_topic == "/ft/wrench"
    # The same file's chain, read where only a chain is wanted (replay --config).
    assert ftdrake.load_chain_config(path).detector.force_on == 4.0


def test_a_chain_file_alone_and_its_errors_name_the_field(tmp_path):
    path = tmp_path / "chain.yaml"
    path.write_text("detector: {force_on: 3.0}\nrobot: {file: arm.urdf}\n")
    with pytest.raises(ftdrake.ConfigError, match=r"chain\.robot\.sensor_frame"):
        load_live_config(path)
    path.write_text("detector: {force_onn: 3.0}\n")
    with pytest.raises(ftdrake.ConfigError, match=r"chain\.detector\.force_onn: unknown field"):
        load_live_config(path)
    path.write_text("chain: {sensor: {rate_hz: -5}}\nlcm: {}\n")
    with pytest.raises(ftdrake.ConfigError, match=r"chain\.sensor\.rate_hz"):
        load_live_config(path)
    path.write_text("sensor: {wrench_delay_s: 0.004}\n")
    assert load_live_config(path).chain.sensor.wrench_delay_s == 0.004


def test_a_live_file_with_only_a_transport_keeps_the_default_chain(tmp_path):
    path = tmp_path / "ros2_only.yaml"
    path.write_text("ros2: {joint_names: [a, b], wrench_topic: /ft/w}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no scenario-layout warning: it is a live file
        live = load_live_config(path)
    assert live.ros2.joint_names == ["a", "b"] and live.ros2.wrench_topic == "/ft/w"
    assert live.chain.detector.force_on == ftdrake.ChainConfig().detector.force_on


def test_a_scenario_file_still_loads_with_a_warning_naming_the_layout(tmp_path):
    path = tmp_path / "scenario.yaml"
    path.write_text("time_step: 0.001\nsensor: {rate_hz: 500.0}\n"
                    "detector: {force_on: 5.0}\n")
    with pytest.warns(ftdrake.ConfigLayoutWarning) as seen:
        live = load_live_config(path)
    messages = " ".join(str(w.message) for w in seen)
    assert "chain config" in messages and "now live under 'chain:'" in messages
    # Its chain: the chain section on the simulated sensor's stream.
    assert live.chain.detector.force_on == 5.0 and live.chain.sensor.period == 1 / 500
    path.write_text("time_step: 0.001\nchain: {detector: {force_on: 5.0}}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", ftdrake.ConfigLayoutWarning)
        assert ftdrake.load_config(path).chain.detector.force_on == 5.0  # the new layout


def test_serve_runs_on_a_live_file(tmp_path, capsys):
    """``serve --config live.yaml``: the chain's rate and the file's LCM URL, no other flag;
    it says it is building before the build (which compiles for seconds on a first run)
    and how long that took, before the channels."""
    import numpy as np

    forest = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(
        np.random.default_rng(0).uniform(-1, 1, (40, 21)), np.zeros((40, 6)))
    ftdrake.save_model(forest, tmp_path / "m.ftd")
    (tmp_path / "live.yaml").write_text(LIVE)
    assert main(["serve", "--model", str(tmp_path / "m.ftd"), "--config",
                 str(tmp_path / "live.yaml"), "--duration", "0.1"]) == 0
    err = capsys.readouterr().err
    assert "500 Hz updates" in err and "MY_FT" in err
    lines = err.splitlines()

    def first(text):
        return next(i for i, line in enumerate(lines) if text in line)

    assert first("m.ftd and building the chain") < first("ready in") < first("Hz updates")
