"""Messages that name the fix: a robot whose base floats (a URDF without a world joint) is
refused with the flag that welds it, by the payload and the whole-arm model, and that flag
fixes it; wrench columns that are not found name the option that chooses them."""

import re
import warnings

import numpy as np
import pandas as pd
import pytest
import yaml
from pydrake.multibody.plant import MultibodyPlant

from ftdrake import LogError, PhysicsPayloadCompensator, RobotModelError, calibrate_table
from ftdrake.cli.args import flag_hint
from ftdrake.cli.main import main
from ftdrake.compensation.estimators.arm import ArmDynamicsCompensator
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.compensation.files.persistence import read_manifest, save_model
from ftdrake.data.logs import LogWarning, option_spelling, read_table
from ftdrake.data.training import load_training_data
from ftdrake.errors import ConfigError
from ftdrake.physics.robot import RobotDescriptionWarning, add_robot_model, show_parser_warnings

ARM = """<?xml version="1.0"?>
<robot name="little_arm">
  <link name="base"/>
  <link name="l1"><inertial><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="sensor"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="50" velocity="2"/></joint>
  <joint name="flange" type="fixed"><parent link="l1"/><child link="sensor"/>
    <origin xyz="0.1 0 0"/></joint>
</robot>
"""


@pytest.fixture
def floating_urdf(tmp_path):
    path = tmp_path / "floating.urdf"  # no joint to the world: Drake lets "base" float
    path.write_text(ARM)
    return str(path)


def rows(n=30):
    q = np.random.default_rng(0).uniform(-2, 2, (n, 1))
    return np.hstack([q, np.zeros_like(q), np.zeros_like(q)])


def test_the_payload_model_names_base_frame(floating_urdf):
    model = PhysicsPayloadCompensator(mode="static", features="q", robot=floating_urdf,
                                      sensor_frame="sensor")
    with pytest.raises(RobotModelError, match=r"'base' floats: weld it to the world with "
                                              r"base_frame base"):
        model.fit(rows(), np.zeros((30, 6)))
    model.set_params(base_frame="base")  # the fix the message names
    with pytest.warns(ExcitationWarning):  # one vertical joint turns no gravity into view
        model.fit(rows(), np.zeros((30, 6)))
    assert model.n_joints_ == 1


def test_the_arm_model_names_base_frame(floating_urdf):
    model = ArmDynamicsCompensator(robot=floating_urdf)
    with pytest.raises(RobotModelError, match=r"with base_frame base"):
        model.fit(rows(), np.zeros((30, 1)))


def table_without_wrench_columns(tmp_path):
    """Static poses whose wrench columns are not named meas_* (a user's own table)."""
    frame = pd.DataFrame({f"q_{i}": np.zeros(4) for i in range(7)})
    for axis in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"):
        frame[f"force_torque_{axis}"] = 0.0
    path = tmp_path / "poses.csv"
    frame.to_csv(path, index=False)
    return frame, path


def test_missing_wrench_columns_name_the_targets_option(tmp_path, capsys):
    frame, path = table_without_wrench_columns(tmp_path)
    with pytest.raises(LogError, match=r"wrench columns \(choose them with targets='PAT'\)"):
        calibrate_table(frame)
    assert main(["calibrate", "--data", str(path), "--out", str(tmp_path / "cal")]) == 2
    assert "wrench columns (choose them with --targets PAT)" in capsys.readouterr().err


# -- the column syntax, the time column, derivatives --------------------------------------------
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def motion(n=200, dt=0.01, time="t", derivatives=True):
    """Two joints moving smoothly (q = sin), their exact derivatives and a wrench."""
    t = np.arange(n) * dt
    frame = pd.DataFrame({time: t})
    for i in range(2):
        frame[f"q_{i}"] = np.sin(t + i)
    if derivatives:
        for i in range(2):
            frame[f"qd_{i}"] = np.cos(t + i)
        for i in range(2):
            frame[f"qdd_{i}"] = -np.sin(t + i)
    for k, axis in enumerate(AXES):
        frame[f"meas_{axis}"] = np.cos(t * (k + 1))
    return frame


def csv(frame, tmp_path, name="log.csv"):
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return str(path)


def rf(*extra):
    return ["--kind", "rf", "--preset", "none", "--quiet", *extra]


def test_read_table_takes_the_column_syntax_of_the_command_line():
    log = read_table(motion(), positions=r"re:q_\d+", velocities="qd_0, qd_1",
                     accelerations="qdd_*")
    assert log.joint_names == ["q_0", "q_1"] and log.derived == []
    np.testing.assert_array_equal(log.qd[:, 1], motion()["qd_1"])


def test_a_pattern_matching_several_kinds_of_columns_warns_with_the_fix(tmp_path, capsys):
    with pytest.warns(LogWarning, match=r"positions: pattern 'q\*' matches 3 kinds of columns "
                                        r"\(q_0..q_1, qd_0..qd_1, qdd_0..qdd_1\).*narrow it: "
                                        r"positions='q_\*'"):
        read_table(motion(), positions="q*", check_units=False)
    path = csv(motion(), tmp_path)
    main(["train", "--data", path, "--positions", "q*", "--no-check-units",
          "--out", str(tmp_path / "m.ftd"), *rf()])
    assert "narrow it: --positions 'q_*' or --positions 're:q_\\d+'" in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("error", LogWarning)  # one kind: nothing to say
        read_table(motion(), positions="q_*")


def static_poses(n=40):
    """Gravity in S per pose and the reading of a 1.2 kg tool (CoM 5 cm along z) there."""
    g = np.random.default_rng(1).normal(size=(n, 3))
    g = 9.81 * g / np.linalg.norm(g, axis=1, keepdims=True)
    F = 1.2 * g
    T = np.cross([0.0, 0.0, 0.05], F)
    frame = pd.DataFrame(g, columns=["gx", "gy", "gz"])
    for k, axis in enumerate(AXES):
        frame[f"force_torque_{axis}"] = np.hstack([F, T])[:, k]
    return frame


# Its one-load fit leaves free entries with no residual: their error is ∞, not 0 · ∞ = NaN.
@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("targets", [r"re:force_torque_.*",
                                     ",".join(f"force_torque_{a}" for a in AXES)])
def test_calibrate_takes_regexes_and_comma_lists(tmp_path, capsys, targets):
    path = csv(static_poses(), tmp_path)
    assert main(["calibrate", "--data", path, "--targets", targets,
                 "--out", str(tmp_path / "cal")]) == 0
    found = yaml.safe_load((tmp_path / "cal" / "calibration.yaml").read_text())
    assert found["calibration"]["parameters"]["m"]["value"] == pytest.approx(1.2)


def test_a_time_column_named_time_is_named_not_taken_for_static_poses(tmp_path, capsys):
    path = csv(motion(time="time"), tmp_path)
    out = str(tmp_path / "m.ftd")
    assert main(["train", "--data", path, "--out", out, *rf()]) == 2
    err = capsys.readouterr().err
    assert "no time column 't'; the table has ['time']: choose it with --time time" in err
    assert "static poses" not in err
    assert main(["train", "--data", path, "--time", "time", "--out", out, *rf()]) == 0
    # calibrate takes a moving log with any time-like column as a motion, and names --time.
    assert main(["calibrate", "--data", path, "--robot", "ftdrake",
                 "--out", str(tmp_path / "cal")]) == 2
    err = capsys.readouterr().err
    assert "choose it with --time time" in err and "static poses" not in err
    # Poses one after another without a time column: the calibrate hint stays.
    poses = pd.DataFrame(np.random.default_rng(2).uniform(-2, 2, (30, 2)), columns=["q_0", "q_1"])
    for axis in AXES:
        poses[f"meas_{axis}"] = 0.0
    assert main(["train", "--data", csv(poses, tmp_path, "poses.csv"), "--out", out, *rf()]) == 2
    assert "looks like a table of static poses" in capsys.readouterr().err


def with_gap(frame, start=100, length=40):
    """`frame` without rows start..start+length (a gap in time)."""
    return frame.drop(index=range(start, start + length)).reset_index(drop=True)


def test_no_gap_warning_when_the_derivatives_are_given():
    frame = with_gap(motion())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_table(frame, velocities="qd_*", accelerations="qdd_*")
    assert not [w for w in caught if "gap" in str(w.message)]
    with pytest.warns(LogWarning, match="derivatives are computed separately between gaps"):
        read_table(frame)  # computed from q: the gap matters


def quadratic(n=60, dt=0.01, c=1.5):
    """q = 0.2 + 0.4 t + c t² on one joint: every Savitzky–Golay order ≥ 2 is exact."""
    t = np.arange(n) * dt
    frame = pd.DataFrame({"t": t, "q_0": 0.2 + 0.4 * t + c * t**2})
    for axis in AXES:
        frame[f"meas_{axis}"] = 0.0
    return frame


def test_a_short_segment_adapts_its_order_and_names_the_one_that_fits_all():
    frame = with_gap(quadratic(), start=3, length=20)  # 3 rows, a gap, then the rest
    with pytest.warns(LogWarning, match=r"1 of 2 segment\(s\) between gaps are too short for a "
                                        r"Savitzky–Golay fit of order 4 \(shortest: 3 rows.*"
                                        r"sg_polyorder=2 fits every segment"):
        log = read_table(frame)
    np.testing.assert_allclose(log.qdd[:, 0], 3.0, atol=1e-8)  # 2c, the short segment too
    np.testing.assert_allclose(log.qd[:3, 0], 0.4 + 3.0 * log.t[:3], atol=1e-8)
    with option_spelling(flag_hint), pytest.warns(LogWarning, match="--sg-polyorder 2 fits"):
        read_table(frame)


def test_a_short_trajectory_does_not_stop_training(tmp_path):
    frame = pd.concat([quadratic(50).assign(trajectory=0), quadratic(9).assign(trajectory=1)])
    data = load_training_data(csv(frame, tmp_path))
    assert data.rows["used"] == 59
    np.testing.assert_allclose(data.X[:, 2], 3.0, atol=1e-8)


def test_evaluate_goes_back_to_estimating_accelerations(tmp_path, capsys):
    model = str(tmp_path / "m.ftd")
    assert main(["train", "--data", csv(motion(), tmp_path), "--velocities", "qd_*",
                 "--accelerations", "qdd_*", "--out", model, *rf()]) == 0
    bare = csv(motion(derivatives=False), tmp_path, "bare.csv")
    assert main(["evaluate", "--model", model, "--data", bare, "--quiet"]) == 2
    assert "compute them from q (--velocities derive)" in capsys.readouterr().err
    assert main(["evaluate", "--model", model, "--data", bare, "--velocities", "derive",
                 "--accelerations", "derive", "--quiet"]) == 0


# -- warnings on the command line ---------------------------------------------------------------
def test_the_excitation_warning_is_one_line_with_command_line_advice(floating_urdf, tmp_path,
                                                                     capsys):
    frame = pd.DataFrame({"t": np.arange(30) * 0.01, "q_0": rows()[:, 0]})
    for axis in AXES:
        frame[f"meas_{axis}"] = 0.0
    assert main(["train", "--data", csv(frame, tmp_path), "--kind", "physics", "--features", "q",
                 "--robot", floating_urdf, "--sensor-frame", "sensor", "--base-frame", "base",
                 "--preset", "none", "--no-check-units", "--out", str(tmp_path / "m.ftd"),
                 "--quiet"]) == 0
    lines = [x for x in capsys.readouterr().err.splitlines() if "excite" in x]
    assert len(lines) == 1 and lines[0].startswith("warning: the data does not excite")
    assert "ftdrake calibrate" in lines[0] and "prior of its mass" in lines[0]
    assert "--prior" not in lines[0]  # flags of calibrate, which train does not have
    assert "PayloadPrior" not in lines[0] and "fourier" not in lines[0] and ".py" not in lines[0]
    model = PhysicsPayloadCompensator(mode="static", features="q", robot=floating_urdf,
                                      sensor_frame="sensor", base_frame="base")
    with pytest.warns(ExcitationWarning, match=r"prior=PayloadPrior"):  # Python keeps its terms
        model.fit(rows(), np.zeros((30, 6)))


def test_drake_parser_warnings_are_summarised_once(tmp_path, capsys, caplog):
    text = ARM.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 1"/><dynamics friction="0.5"/>'
                       '<safety_controller k_velocity="1"/>')
    text = text.replace('<robot name="little_arm">', '<robot name="little_arm">\n'
                        '<link name="world"/><joint name="w" type="fixed"><parent link="world"/>'
                        '<child link="base"/></joint>')
    path = tmp_path / "vendor.urdf"
    path.write_text(text)
    model = PhysicsPayloadCompensator(mode="static", features="q", robot=str(path),
                                      sensor_frame="sensor")
    with pytest.warns(RobotDescriptionWarning, match=r"gave 2 parser warning\(s\) \(e\.g\. .*"
                                                     r"logging.getLogger"):
        model._kinematics()
    assert not [r for r in caplog.records if r.name == "drake"]
    assert "WARNING:drake" not in capsys.readouterr().err
    with warnings.catch_warnings():
        warnings.simplefilter("error", RobotDescriptionWarning)
        add_robot_model(MultibodyPlant(0.0), str(path))  # once per process and description
    path = tmp_path / "other.urdf"  # another description
    path.write_text(text)
    with show_parser_warnings(), pytest.warns(RobotDescriptionWarning):
        add_robot_model(MultibodyPlant(0.0), str(path))
    err = capsys.readouterr().err
    assert "drake parser:" in err and "safety_controller" in err and "friction" in err


def test_a_description_that_warns_prints_one_line_on_the_command_line(tmp_path, capsys):
    text = ARM.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 1"/><dynamics friction="0.4"/>')
    path = tmp_path / "cli.urdf"
    path.write_text(text)
    main(["train", "--data", csv(motion(), tmp_path), "--kind", "physics", "--robot", str(path),
          "--sensor-frame", "sensor", "--out", str(tmp_path / "m.ftd"), "--quiet"])
    err = capsys.readouterr().err
    assert "gave 1 parser warning(s)" in err and "--verbose shows them" in err
    assert "WARNING:drake" not in err


# -- model files' targets -----------------------------------------------------------------------
def test_save_model_defaults_a_wrench_and_evaluate_takes_meas_columns_for_it(tmp_path, capsys):
    frame = motion()
    model = RandomForestCompensator(n_estimators=5).fit(
        frame[["q_0", "q_1", "qd_0", "qd_1", "qdd_0", "qdd_1"]].to_numpy(),
        frame[[f"meas_{a}" for a in AXES]].to_numpy())
    path = save_model(model, tmp_path / "m.ftd")
    manifest = read_manifest(path)
    assert manifest["target_names"] == list(AXES)
    assert manifest["target_units"] == ["N", "N", "N", "N*m", "N*m", "N*m"]
    assert main(["evaluate", "--model", str(path), "--data", csv(frame, tmp_path), "--quiet"]) == 0
    assert "names differ" not in capsys.readouterr().err
    two = RandomForestCompensator(n_estimators=5).fit(np.zeros((10, 3)), np.zeros((10, 2)))
    with pytest.raises(ConfigError, match=r"needs target_names=\[one name per output\]"):
        save_model(two, tmp_path / "two.ftd")


def test_replay_takes_the_same_column_syntax(tmp_path, capsys):
    frame = motion(n=120)
    model = str(tmp_path / "m.ftd")
    assert main(["train", "--data", csv(frame, tmp_path), "--out", model, *rf()]) == 0
    assert main(["replay", "--model", model, "--log", csv(frame, tmp_path),
                 "--out", str(tmp_path / "a.csv"), "--quiet"]) == 0
    theirs = frame.rename(columns={"t": "time", "q_0": "pos_a", "q_1": "pos_b", "qd_0": "vel_a",
                                   "qd_1": "vel_b", **{f"meas_{a}": f"ft_{a}" for a in AXES}})
    log = csv(theirs, tmp_path, "theirs.csv")
    assert main(["replay", "--model", model, "--log", log, "--out", str(tmp_path / "b.csv"),
                 "--quiet"]) == 2
    assert "--positions, --velocities, --targets and --time" in capsys.readouterr().err
    assert main(["replay", "--model", model, "--log", log, "--out", str(tmp_path / "b.csv"),
                 "--time", "time", "--positions", "pos_a,pos_b", "--velocities", "re:vel_.",
                 "--targets", "ft_*", "--quiet"]) == 0
    a, b = pd.read_csv(tmp_path / "a.csv"), pd.read_csv(tmp_path / "b.csv")
    pd.testing.assert_frame_equal(a, b)


# -- a sensor frame the robot does not have (issue 42 item 1) -----------------------------------
@pytest.fixture
def welded_urdf(tmp_path):
    path = tmp_path / "welded.urdf"
    path.write_text(ARM.replace('<link name="base"/>', '<link name="world"/><joint name="w" '
                                'type="fixed"><parent link="world"/><child link="base"/></joint>'
                                '<link name="base"/>'))
    return str(path)


@pytest.mark.parametrize("flags, message", [
    (["--sensor-frame", "ft_sensor_frame"],
     (r"^ftdrake calibrate: error: --sensor-frame: robot model '.*welded\.urdf' has no sensor "
     r"frame named 'ft_sensor_frame'; its frames, closest to 'ft_sensor_frame' first: sensor, ")),
    ([], (r"^ftdrake calibrate: error: calibrate --robot \S+welded\.urdf needs --sensor-frame "
          r"NAME \(the frame S of the measured wrench in \S+\); its frames, sensor-like first: "
          r"sensor, ")),
    (["--sensor-frame", "sensor", "--base-frame", "bse"],
     (r"--base-frame: robot model '.*welded\.urdf' has no base frame named 'bse'; its frames, "
     r"closest to 'bse' first: base, ")),
])
def test_calibrate_checks_the_robots_frames_before_reading_data(welded_urdf, tmp_path, capsys,
                                                                monkeypatch, flags, message):
    """The frames are checked first (the data is never read); the message names the robot
    file and lists its frames, the closest match first."""
    import ftdrake.cli.calibrate as calibrate_cli

    def never(*_):
        raise AssertionError("the data was read before the robot's frames were checked")

    monkeypatch.setattr(calibrate_cli, "read_frame", never)
    data = csv(pd.DataFrame({"q_0": [0.0, 1.0]}), tmp_path)
    assert main(["calibrate", "--data", data, "--robot", welded_urdf, *flags,
                 "--out", str(tmp_path / "cal")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err


def test_a_fitted_models_missing_frame_names_its_robot_file(welded_urdf):
    model = PhysicsPayloadCompensator(mode="static", features="q", robot=welded_urdf,
                                      sensor_frame="ft_sensor_frame")
    with pytest.raises(RobotModelError, match=r"robot model 'welded\.urdf' \(embedded URDF, \d+ "
                                              r"characters\) has no sensor frame named "
                                              r"'ft_sensor_frame'; its frames, closest to "
                                              r"'ft_sensor_frame' first: sensor, "):
        model.fit(rows(), np.zeros((30, 6)))


# -- velocity columns: the count, and recorded ones left unused (issue 42 item 2) ---------------
def test_a_velocity_pattern_matching_too_many_columns_suggests_one_that_fits(tmp_path, capsys):
    frame = motion()
    for i in range(2):
        frame[f"qd_est_{i}"] = frame[f"qd_{i}"]
    path = csv(frame, tmp_path)
    assert main(["train", "--data", path, "--velocities", "qd_*",
                 "--out", str(tmp_path / "m.ftd"), *rf()]) == 2
    err = capsys.readouterr().err
    assert ("error: log.csv: --velocities 'qd_*' matched 4 columns (qd_0, qd_1, qd_est_0, "
            "qd_est_1) for 2 positions (q_0, q_1); one velocity column per position is "
            "needed: re:qd_\\d+ matches 2 (qd_0, qd_1): --velocities 're:qd_\\d+'") in err
    assert main(["train", "--data", path, "--velocities", r"re:qd_\d+",
                 "--out", str(tmp_path / "m.ftd"), *rf()]) == 0


def test_recorded_derivatives_left_unused_are_named(tmp_path):
    path = csv(motion(), tmp_path)
    data = load_training_data(path)  # velocities and accelerations computed from q
    assert data.derived == ["qd", "qdd"]
    assert data.warnings == [
        ("log.csv: the log records velocities qd_0..qd_1 (computed instead: Savitzky–Golay "
        "derivative of q); accelerations qdd_0..qdd_1 (computed instead: Savitzky–Golay second "
        "derivative of q); to use the recorded ones: velocities='re:qd_\\\\d+' "
        "accelerations='re:qdd_\\\\d+' (to compute them and not see this: "
        "velocities='derive' accelerations='derive')")]
    from ftdrake.data.training import ReadOptions
    used = load_training_data(path, ReadOptions(velocities=r"re:qd_\d+",
                                                accelerations=r"re:qdd_\d+"))
    derived = load_training_data(path, ReadOptions(velocities="derive", accelerations="derive"))
    assert used.derived == [] and used.warnings == [] and derived.warnings == []
    bare = load_training_data(csv(motion(derivatives=False), tmp_path, "bare.csv"))
    assert bare.warnings == []


# -- commands name their own flags (issue 42 item 20) -------------------------------------------
def test_calibrate_on_a_motion_without_robot_names_calibrates_flags(tmp_path, capsys):
    path = csv(motion(), tmp_path)
    assert main(["calibrate", "--data", path, "--out", str(tmp_path / "cal")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (
        f"ftdrake calibrate: error: {path} is a motion (a time column and moving joints): "
        "calibrate fits it with the dynamic payload model, which needs --robot FILE "
        "(URDF/SDF) with --sensor-frame NAME, or --robot ftdrake for the simulated arm")
    assert "--kind" not in err


def test_serve_on_ros2_without_its_config_names_the_flag(tmp_path, capsys):
    model = RandomForestCompensator(n_estimators=2).fit(rows(), np.zeros((30, 6)))
    save_model(model, tmp_path / "m.ftd")
    assert main(["serve", "--ros2", "--model", str(tmp_path / "m.ftd")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftdrake serve: error: --ros2 needs --ros2-config FILE (a Ros2Config "
                          "YAML; the defaults used without it fall short): ros2.joint_names: "
                          "list the model's joints"), err


# -- a residual that is an offset (issue 42 item 6) ---------------------------------------------
def test_evaluate_warns_of_a_residual_offset_as_a_bias_or_payload_change(tmp_path, capsys):
    """After a payload change Fy reads 12 N more: its residual's mean is many of its std from
    zero, which evaluate names (the variance score alone hides it); the log the model was
    trained on gives no such warning."""
    frame = motion()
    model = str(tmp_path / "m.ftd")
    assert main(["train", "--data", csv(frame, tmp_path), "--out", model, *rf()]) == 0
    assert main(["evaluate", "--model", model, "--data", csv(frame, tmp_path), "--quiet"]) == 0
    assert "constant offset" not in capsys.readouterr().err
    changed = frame.assign(meas_Fy=frame["meas_Fy"] + 12.0)
    json_path = tmp_path / "e.json"
    assert main(["evaluate", "--model", model, "--data", csv(changed, tmp_path, "new.csv"),
                 "--json", str(json_path), "--quiet"]) == 0
    err = capsys.readouterr().err
    result = yaml.safe_load(json_path.read_text())
    assert list(result["offsets"]) == ["meas_Fy"]
    offset = result["offsets"]["meas_Fy"]
    # Independently: the residual's mean and std on the changed log.
    from ftdrake.compensation.files.persistence import load_model
    from ftdrake.data.training import load_training_data as load
    data = load(csv(changed, tmp_path, "new.csv"))
    e = data.Y[:, 1] - load_model(model).predict(data.X)[:, 1]
    assert offset["mean"] == pytest.approx(e.mean()) and offset["std"] == pytest.approx(e.std())
    assert offset["mean"] == pytest.approx(12.0, abs=0.5)
    line = next(x for x in err.splitlines() if x.startswith("warning: meas_Fy:"))
    assert line.startswith(f"warning: meas_Fy: the residual's mean {offset['mean']:+.4g} N is "
                           f"{offset['mean'] / offset['std']:.1f} × its std "
                           f"({offset['std']:.4g} N) from zero: a constant offset, not the "
                           "model's scatter — a sensor bias or re-tare, or a payload changed "
                           "since the training data")


def test_train_checks_the_robots_frames_before_reading_data(welded_urdf, tmp_path, capsys,
                                                            monkeypatch):
    """``train`` too: a frame that is not in the robot is named before the data is read."""
    from ftdrake.training import pipeline

    def never(*_args, **_kwargs):
        raise AssertionError("the data was read before the robot's frames were checked")

    monkeypatch.setattr(pipeline, "load_training_data", never)
    data = csv(pd.DataFrame({"q_0": [0.0, 1.0]}), tmp_path)
    assert main(["train", "--data", data, "--kind", "physics", "--robot", welded_urdf,
                 "--sensor-frame", "ft_sensor_frame", "--out", str(tmp_path / "m.ftd")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"has no sensor frame named 'ft_sensor_frame'; its frames, closest to "
                     r"'ft_sensor_frame' first: sensor, ", err), err
