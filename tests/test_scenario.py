"""Configuration, trajectories and the `ftdrake simulate` command, including bad input."""

import json

import numpy as np
import pandas as pd
import pytest
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import ConfigError, ScenarioConfig, TrajectoryError, build_station, load_config
from ftdrake import conventions as col
from ftdrake.cli.main import main
from ftdrake.config import default_scenario_path, dump_config, parse_config
from ftdrake.sim.station import robot_geometry
from ftdrake.sim.trajectories import JointLimits, check_limits, make_trajectory, trajectory_extent


def test_shipped_default_yaml_equals_defaults_and_round_trips(tmp_path):
    assert load_config() == ScenarioConfig()
    assert parse_config(dump_config(ScenarioConfig())) == ScenarioConfig()
    assert default_scenario_path().is_file()


@pytest.mark.parametrize(
    "text, message",
    [
        ("sensor: {noise_std: [1, 2", "malformed YAML"),
        ("sensor: {bogus: 1}", r"scenario\.sensor\.bogus: unknown field"),
        ("trajectory: {kind: spiral}", r"scenario\.trajectory\.kind: unknown kind"),
        ("time_step: -0.001", r"scenario\.time_step"),
        ("controller: {kp: 0}", r"scenario\.controller\.kp"),
        ("home_q: [0, 0, 0]", r"home_q: has 3 entries"),
        ("- a\n- b", "expected a mapping"),
    ],
)
def test_bad_yaml_names_the_problem(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        config = load_config(path)
        build_station(config)


def test_missing_config_file_is_a_clear_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read config"):
        load_config(tmp_path / "nope.yaml")


@pytest.mark.parametrize("field", ["arm", "tool", "environment"])
def test_unknown_model_path_names_the_field(field):
    config = ScenarioConfig()
    setattr(config.models, field, "/no/such/model.sdf")
    with pytest.raises(ConfigError, match=f"scenario.models.{field}: no such model file"):
        build_station(config)


def test_unknown_package_model_names_the_field():
    config = ScenarioConfig()
    config.models.tool = "package://ftdrake/no_such_tool.sdf"
    with pytest.raises(ConfigError, match="scenario.models.tool: cannot load"):
        build_station(config)


@pytest.fixture(scope="module")
def geometry():
    config = ScenarioConfig()
    g = robot_geometry(config)
    limits = JointLimits.from_plant(g._plant, g._scene.arm, config.trajectory.acceleration_limit)
    return config, g, limits


def test_trajectory_outside_limits_names_joint_and_time(geometry):
    _, _, limits = geometry
    q = np.zeros((7, 3))
    q[3] = [0.0, 3.0, 0.0]  # joint_u beyond its ±135°
    traj = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, 5.0, 10.0], q, np.zeros((7, 1)), np.zeros((7, 1))
    )
    with pytest.raises(TrajectoryError, match=r"position limit of joint_u at t = \d"):
        check_limits(traj, limits)


@pytest.mark.parametrize("kind", ["random", "fourier", "reference", "z_rich", "contact"])
def test_every_kind_respects_limits(geometry, kind):
    config, g, limits = geometry
    tc = config.trajectory
    tc.kind, tc.duration_s = kind, 14.0
    traj = make_trajectory(tc, config.home_q, limits, g)
    check_limits(traj, limits, dt=0.002)
    np.testing.assert_allclose(traj.value(0.0).ravel(), config.home_q, atol=1e-9)
    if kind != "contact":
        assert g.clear_of_environment(traj)


def test_reference_moves_little_in_z_and_z_rich_a_lot(geometry):
    config, g, limits = geometry
    extents = {}
    for kind in ("reference", "z_rich"):
        tc = config.trajectory
        tc.kind, tc.duration_s, tc.seed = kind, 30.0, 0
        extents[kind] = trajectory_extent(make_trajectory(tc, config.home_q, limits, g), g)
    ref, rich = extents["reference"], extents["z_rich"]
    horizontal = np.hypot(ref["x"]["std"], ref["y"]["std"])
    assert ref["z"]["std"] < 0.25 * horizontal  # mostly a horizontal-plane motion
    assert rich["z"]["std"] > 2 * ref["z"]["std"]
    assert rich["tilt"]["std"] > 2 * ref["tilt"]["std"]  # z_S swings relative to gravity


def test_too_short_contact_scenario_is_refused(geometry):
    config, g, limits = geometry
    config.trajectory.kind, config.trajectory.duration_s = "contact", 6.0
    with pytest.raises(TrajectoryError, match="duration_s"):
        make_trajectory(config.trajectory, config.home_q, limits, g)


def test_simulate_cli_writes_documented_outputs(tmp_path):
    out = tmp_path / "run"
    assert main(["simulate", "--scenario", "free", "--duration", "3", "--seed", "2",
                 "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("duration_s", "wall_time_s", "real_time_factor", "samples",
                "first_contact_time_s", "sensor_preset"):
        assert key in summary
    assert summary["first_contact_time_s"] is None and summary["samples"] == 3000
    log = pd.read_parquet(out / "log.parquet")
    expected = ([col.TIME] + col.joint_columns(col.Q) + col.joint_columns(col.QD)
                + col.joint_columns(col.QDD) + col.joint_columns(col.QD_EST)
                + col.joint_columns(col.QDD_EST) + col.wrench_columns(col.IDEAL)
                + col.wrench_columns(col.MEASURED) + col.wrench_columns(col.INTERNAL)
                + col.wrench_columns(col.EXTERNAL) + [col.CONTACT, col.SATURATED])
    assert list(log.columns) == expected
    assert (out / "wrench.png").stat().st_size > 10_000
    # Numerically differentiated velocities agree with the plant's (smooth motion, 1 kHz).
    qd, qd_est = log[col.joint_columns(col.QD)].to_numpy(), log[col.joint_columns(col.QD_EST)].to_numpy()
    assert np.abs(qd - qd_est)[5:-5].max() < 0.01 * np.abs(qd).max() + 1e-3


def test_simulate_cli_bad_config_leaves_no_files(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensor: {noise_std: [-1, 0, 0, 0, 0, 0]}")
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(bad), "--out", str(out), "--quiet"]) == 2
    assert "noise_std" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


def test_failure_while_writing_leaves_no_partial_outputs(tmp_path, monkeypatch):
    import ftdrake.plots

    def broken_plot(*args, **kwargs):
        raise RuntimeError("disk full while plotting")

    monkeypatch.setattr(ftdrake.plots, "plot_wrench_log", broken_plot)
    out = tmp_path / "run"
    with pytest.raises(RuntimeError, match="disk full"):
        main(["simulate", "--scenario", "free", "--duration", "2", "--out", str(out), "--quiet"])
    assert list(out.iterdir()) == []  # no log.parquet left behind, no staging folder


def test_atomic_outputs_get_the_usual_permissions(tmp_path):
    import os
    import stat

    from ftdrake.io import atomic_write_text

    atomic_write_text(tmp_path / "a.json", "{}")
    mode = stat.S_IMODE((tmp_path / "a.json").stat().st_mode)
    mask = os.umask(0)
    os.umask(mask)
    assert mode == 0o666 & ~mask
