"""Configuration, trajectories and the `ftdrake simulate` command, including bad input."""

import dataclasses as dc
import json

import numpy as np
import pandas as pd
import pytest
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import ConfigError, ScenarioConfig, TrajectoryError, build_station, load_config
from ftdrake import conventions as col
from ftdrake.cli.main import main
from ftdrake.config import (
    TRAJECTORY_KINDS,
    CableConfig,
    TaskConfig,
    TrajectoryConfig,
    default_scenario_path,
    dump_config,
    parse_config,
)
from ftdrake.sim.station import plan_trajectory, robot_geometry
from ftdrake.sim.trajectories import JointLimits, check_limits, trajectory_extent
from ftdrake.sim.trajectory_plan import make_trajectory
from tests.helpers import DATA


def test_shipped_default_yaml_equals_defaults_and_round_trips(tmp_path):
    assert load_config() == ScenarioConfig()
    assert parse_config(dump_config(ScenarioConfig())) == ScenarioConfig()
    assert default_scenario_path().is_file()


def test_a_loaded_scenario_is_validated_once_on_the_way_to_a_station(monkeypatch):
    calls = []
    for section in (ScenarioConfig, TrajectoryConfig, CableConfig):
        original = section.validate

        def counted(self, *args, _original=original, **kwargs):
            calls.append(type(self).__name__)
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(section, "validate", counted)
    config = load_config()
    assert sorted(calls) == ["CableConfig", "ScenarioConfig", "TrajectoryConfig"]
    build_station(config)  # the free-standing systems inside check only their own section
    assert sorted(calls) == ["CableConfig", "ScenarioConfig", "TrajectoryConfig"]


@pytest.mark.parametrize(
    "text, message",
    [
        ("sensor: {noise_std: [1, 2", "malformed YAML"),
        ("sensor: {bogus: 1}", r"scenario\.sensor\.bogus: unknown field"),
        ("trajectory: {kind: spiral}", r"scenario\.trajectory\.kind: unknown kind"),
        ("time_step: -0.001", r"scenario\.time_step"),
        ("controller: {kp: 0}", r"scenario\.controller\.kp"),
        ("home_q: [0, 0, 0]", r"scenario\.home_q: has 3 entries but the arm has 7 joints"),
        ("home_q: [0, 0, 0, 0, 0, 0, 0, 0]", r"scenario\.home_q: has 8 entries .* 7 joints"),
        ("home_q: []", r"scenario\.home_q: must list one angle \(rad\) per arm joint, got none"),
        ("home_q: [0, 0.5, .nan, 1, 0, 1, 0]", r"scenario\.home_q: entries must be finite"),
        ("trajectory: {contact_target: shelf}",
         (r"scenario\.trajectory\.contact_target: 'shelf' is not a surface of "
          r"scenario\.task\.surfaces \['table', 'wall'\]")),
        ("trajectory: {kind: rehearsal, rehearsal_height_m: 0}",
         r"scenario\.trajectory\.rehearsal_height_m: must be a positive number"),
        ("trajectory: {kind: rehearsal, rehearsal_height_m: 0.5}",
         r"scenario\.trajectory\.rehearsal_height_m: 0\.5 not in \(0, 0\.2\]"),
        ("task: {tool_tip_frame: ''}", r"scenario\.task\.tool_tip_frame: must be a frame name"),
        ("task: {bogus: 1}", r"scenario\.task\.bogus: unknown field"),
        ("- a\n- b", "expected a mapping"),
    ],
)
def test_bad_yaml_names_the_problem(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        config = load_config(path)
        build_station(config)


@pytest.mark.parametrize(
    "text, message",
    [
        ("sensor: {noise_std: -1.0}",
         r"^--config \S+: scenario\.sensor\.noise_std: must be a non-negative number, got -1\.0$"),
        ("chain: {detector: {force_on: high}}",
         r"^--config \S+: scenario\.chain\.detector\.force_on: must be a number, got 'high'$"),
        ("trajectory: {seed: 1.5}", r"scenario\.trajectory\.seed: must be a whole number"),
        ("cable: {enabled: 3}", r"scenario\.cable\.enabled: must be true or false, got 3"),
        ("sensor: {mounting_rpy_deg: 1.0}",
         (r"scenario\.sensor\.mounting_rpy_deg: must be a list of 3 numbers, got the single "
          r"number 1\.0")),
        ("sensor: {bias: [0, 0, x, 0, 0, 0]}",
         r"scenario\.sensor\.bias: entries must be numbers, got 'x'"),
        ("sensor: 0.1", r"scenario\.sensor: must be a mapping of fields"),
    ],
)
def test_a_mistyped_value_names_its_field(tmp_path, text, message):
    """A value of the wrong type names the field and what it must be (not Python's 'float
    object is not iterable' or 'could not convert string to float' with no field)."""
    from ftdrake.cli.args import load_scenario

    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_scenario(type("Args", (), {"config": str(path)})())


@pytest.mark.parametrize("field", ["noise_std", "bias", "range", "drift_std"])
def test_a_single_number_for_a_per_axis_list_means_every_axis(field):
    config = parse_config(f"sensor: {{{field}: 0.25}}")
    assert getattr(config.sensor, field) == [0.25] * 6
    listed = parse_config(f"sensor: {{{field}: [0.25, 0.25, 0.25, 0.25, 0.25, 0.25]}}")
    assert dump_config(config) == dump_config(listed)


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
    with pytest.raises(ConfigError, match=r"scenario.models.tool: cannot load"):
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


def test_every_kind_is_tested():
    assert set(TRAJECTORY_KINDS) == {"random", "fourier", "reference", "z_rich", "contact",
                                     "rehearsal", "study", "task_covering"}


@pytest.mark.parametrize("kind", TRAJECTORY_KINDS)
def test_every_kind_respects_limits(geometry, kind):
    config, g, limits = geometry
    tc = config.trajectory
    tc.kind, tc.duration_s = kind, 14.0
    traj = make_trajectory(tc, config.home_q, limits, g)
    check_limits(traj, limits, dt=0.002)
    if kind != "study":  # the study's motion starts where its Table 1 puts it
        np.testing.assert_allclose(traj.value(0.0).ravel(), config.home_q, atol=1e-9)
    if kind not in ("contact", "rehearsal"):
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
    expected = [col.TIME, *col.joint_columns(col.Q), *col.joint_columns(col.QD),
                *col.joint_columns(col.QDD), *col.joint_columns(col.QD_EST),
                *col.joint_columns(col.QDD_EST), *col.wrench_columns(col.IDEAL),
                *col.wrench_columns(col.MEASURED), *col.wrench_columns(col.INTERNAL_TRUE),
                *col.wrench_columns(col.EXTERNAL_TRUE), col.CONTACT_TRUE, col.SATURATED,
                col.TEMPERATURE]
    assert list(log.columns) == expected
    assert (out / "wrench.png").stat().st_size > 10_000
    # Numerically differentiated velocities agree with the plant's (smooth motion, 1 kHz).
    qd = log[col.joint_columns(col.QD)].to_numpy()
    qd_est = log[col.joint_columns(col.QD_EST)].to_numpy()
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


# ----------------------------------------------------------------------------------------------
# The task's geometry comes from the models' frames (scenario.task), not from constants.
# ----------------------------------------------------------------------------------------------
# What trajectories.py used to copy from the SDF files (TABLE_TOP_Z, WALL_FACE_X, P_STIP).
OLD_TABLE = ([0.5, 0.0, 0.75], [0.0, 0.0, 1.0])
OLD_WALL = ([0.95, 0.0, 1.2], [-1.0, 0.0, 0.0])
OLD_P_STIP = [0.03, 0.0, 0.215]


def _fields(schema, prefix=""):
    """Every field path of a config dataclass, e.g. 'trajectory.rehearsal_height_m'."""
    for f in dc.fields(schema):
        sub = f.default_factory if f.default_factory is not dc.MISSING else None
        if sub is not None and dc.is_dataclass(sub):
            yield from _fields(sub, f"{prefix}{f.name}.")
        else:
            yield prefix + f.name


def test_shipped_default_yaml_lists_every_field():
    import yaml

    data = yaml.safe_load(default_scenario_path().read_text())
    missing = []
    for path in _fields(ScenarioConfig):
        node = data
        for key in path.split("."):
            if not isinstance(node, dict) or key not in node:
                missing.append(path)
                break
            node = node[key]
    assert missing == []
    assert data["task"] == {"surfaces": {"table": "table_top", "wall": "wall_face"},
                            "tool_tip_frame": "tool_tip"}
    assert data["trajectory"]["rehearsal_height_m"] == 0.03
    assert load_config().task == TaskConfig()


def test_task_geometry_read_from_the_models_equals_the_old_constants(geometry):
    _, g, _ = geometry
    tol = {"rtol": 0, "atol": 1e-12}
    for surface, (p_W, n_W) in (("table", OLD_TABLE), ("wall", OLD_WALL)):
        p, n = g.surface(surface)
        np.testing.assert_allclose(p, p_W, **tol)
        np.testing.assert_allclose(n, n_W, **tol)
    p_STip, z_S = g.tool_tip()
    np.testing.assert_allclose(p_STip, OLD_P_STIP, **tol)
    np.testing.assert_allclose(z_S, [0.0, 0.0, 1.0], **tol)


@pytest.mark.parametrize("name, changes", [
    ("contact_table", {"kind": "contact"}),
    ("contact_wall", {"kind": "contact", "contact_target": "wall"}),
    ("rehearsal_table", {"kind": "rehearsal"}),  # was: contact with press_depth_m = -0.03
])
def test_contact_trajectories_equal_those_planned_from_the_old_constants(geometry, name, changes):
    """Against values recorded before the geometry came from the models. On Drake 1.51.1 they
    agree exactly; the tolerance leaves room for another build of the IK solver."""
    config, g, limits = geometry
    recorded = json.loads((DATA / "contact_trajectory_before_task_frames.json").read_text())
    tc = dc.replace(ScenarioConfig().trajectory, **changes)
    traj = make_trajectory(tc, config.home_q, limits, g)
    depth = tc.press_depth_m if tc.kind == "contact" else -tc.rehearsal_height_m
    poses = np.array(g.press_poses(tc.contact_target, depth, np.asarray(config.home_q)))
    q_at = np.array([traj.value(t).ravel() for t in recorded["times"]])
    np.testing.assert_allclose(poses, recorded[name]["press_poses"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(q_at, recorded[name]["q_at"], rtol=0, atol=1e-10)


def _press_tip(config):
    """Tool-tip position (W) of the planned press pose, and the press depth asked for."""
    g = robot_geometry(config)
    tc = config.trajectory
    depth = tc.press_depth_m if tc.kind == "contact" else -tc.rehearsal_height_m
    press = g.press_poses(tc.contact_target, depth, np.asarray(config.home_q))[2]
    tip, axis = g.tip_and_axis(press)
    return tip, axis


def test_moving_the_table_in_the_environment_model_moves_the_press():
    default = ScenarioConfig()
    moved = ScenarioConfig()
    moved.models.environment = str(DATA / "environment_table_moved.sdf")  # (-5, 0, +5) cm
    depth = default.trajectory.press_depth_m
    tip, axis = _press_tip(default)
    tip_moved, axis_moved = _press_tip(moved)
    ik_tol = {"rtol": 0, "atol": 6e-4}  # the IK's position box is ±0.5 mm
    np.testing.assert_allclose(tip, [0.5, 0.0, 0.75 - depth], **ik_tol)
    np.testing.assert_allclose(tip_moved, [0.45, 0.0, 0.80 - depth], **ik_tol)
    for a in (axis, axis_moved):  # pointing down into the table, within the IK's 0.02 rad
        assert np.arccos(-a[2]) <= 0.02 + 1e-6
    # The planned trajectories differ only from the approach on.
    q0 = plan_trajectory(default)
    q1 = plan_trajectory(moved)
    assert np.abs(q0.value(1.0) - q1.value(1.0)).max() < 1e-12  # free motion before it
    assert np.abs(q0.value(7.0) - q1.value(7.0)).max() > 0.01  # the press


def test_rehearsal_stays_above_the_surface(geometry):
    config, g, limits = geometry
    tc = dc.replace(ScenarioConfig().trajectory, kind="rehearsal", rehearsal_height_m=0.04)
    traj = make_trajectory(tc, config.home_q, limits, g)
    tip, _ = g.tip_and_axis(traj.value(9.5).ravel())  # mid-"press": held above the table
    np.testing.assert_allclose(tip, [0.5, 0.0, 0.75 + 0.04], rtol=0, atol=6e-4)
    lowest = trajectory_extent(traj, g, dt=0.01)["z"]["min"]
    assert lowest > 0.75 + 0.004  # its approach comes within 5 mm, never onto the table


@pytest.mark.parametrize("field, value, message", [
    ("tool_tip_frame", "no_tip",
     r"scenario\.task\.tool_tip_frame: no frame 'no_tip' in the tool model 'ft_sensor_tool'"),
    ("tool_tip_frame", "ft_sensor",  # the sensor's mounting side: the sensor does not see it
     (r"scenario\.task\.tool_tip_frame: frame 'ft_sensor' is on body 'ft_sensor', which is "
      r"not on the sensor's tool side")),
    ("surfaces", {"table": "no_top", "wall": "wall_face"},
     r"scenario\.task\.surfaces\.table: no frame 'no_top' in the environment model"),
])
def test_missing_task_frame_is_named_when_the_station_is_built(field, value, message):
    config = ScenarioConfig()
    setattr(config.task, field, value)
    with pytest.raises(ConfigError, match=message):
        build_station(config)


def test_environment_without_surface_frames_is_named():
    config = ScenarioConfig()
    config.models.environment = str(DATA / "environment_without_frames.sdf")
    with pytest.raises(ConfigError, match=r"scenario\.task\.surfaces\.table: no frame "
                                          r"'table_top' in the environment model"):
        plan_trajectory(config)
    config.trajectory.kind = "fourier"  # free motion needs no surface
    config.trajectory.duration_s = 4.0
    plan_trajectory(config)


def test_contact_target_is_checked_against_the_task_on_load():
    with pytest.raises(ConfigError, match=r"scenario\.trajectory\.contact_target: 'shelf'"):
        parse_config("trajectory: {contact_target: shelf}")
    # A surface of the user's own adds to the defaults (Drake's loader keeps map defaults).
    config = parse_config("task: {surfaces: {shelf: shelf_top}}\n"
                          "trajectory: {contact_target: shelf}")
    assert config.task.surfaces == {"table": "table_top", "wall": "wall_face",
                                    "shelf": "shelf_top"}


def test_a_press_whose_moves_need_more_time_is_planned_within_the_limits(geometry):
    """A 20 mm press into the wall turns the wrist roll fast on the last 5 mm: with the moves'
    default durations joint_r reached 4.1046 rad/s² against its 4 rad/s² (issue 42 item 24).
    The planner lengthens that move instead (the free motion before it gives up the time), and
    the press still starts when it did."""
    _, g, limits = geometry
    config = ScenarioConfig()  # the defaults (other tests change the fixture's config)
    trajectory = dc.replace(config.trajectory, kind="contact", contact_target="wall",
                            press_depth_m=0.020, seed=6110)
    traj = make_trajectory(trajectory, config.home_q, limits, g)
    # Independently of check_limits: q̈ and q̇ on a 1 ms grid.
    t = np.arange(traj.start_time(), traj.end_time(), 1e-3)
    qdd = np.hstack([traj.EvalDerivative(ti, 2) for ti in t]).T
    qd = np.hstack([traj.EvalDerivative(ti, 1) for ti in t]).T
    assert np.all(np.abs(qdd) <= limits.acceleration * (1 + 1e-9))
    assert np.all(np.abs(qd) <= limits.velocity * (1 + 1e-9))
    assert np.abs(qdd).max() > 0.9 * limits.acceleration[0]  # close to the limit, not slowed
    # The press pose is held from the same time as with the default moves (10 s before the
    # end: ascend 1.5 s, back 1.5 s, the 3 s press ... only the moves before it grew).
    _, _, press = g.press_poses("wall", 0.020, config.home_q)
    press_start = config.trajectory.duration_s - 1.5 - 1.5 - trajectory.press_duration_s
    np.testing.assert_allclose(traj.value(press_start + 0.5).ravel(), press, atol=1e-6)


@pytest.mark.parametrize(("section", "field", "value", "message"), [
    ("sensor", "noise_std", 0.1, (r"scenario\.sensor\.noise_std: must be a list of 6 numbers "
                                 r"\(one per axis Fx\.\.Tz\), got 0\.1")),
    ("sensor", "bias", 0.5, r"scenario\.sensor\.bias: must be a list of 6 numbers, got 0\.5"),
    (None, "home_q", 0.3, r"scenario\.home_q: must be a list of numbers, got 0\.3"),
])
def test_a_scalar_set_in_python_where_a_list_is_meant_names_the_field(section, field, value,
                                                                      message):
    config = ScenarioConfig()
    setattr(config if section is None else getattr(config, section), field, value)
    with pytest.raises(ConfigError, match=message):
        config.validate()
