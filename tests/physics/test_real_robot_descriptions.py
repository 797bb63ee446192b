"""A robot description with more joints than the log (a torso, a head and fingers around a
three-joint arm): the log's joints are named (``--joints`` / ``joints=``), the others stand
where they are told (``--fixed-joints`` / ``fixed_joints=``), the payload is identified
without editing the URDF, and the model file keeps the mapping."""

from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant

from ftdrake import PhysicsPayloadCompensator, RobotModelError
from ftdrake.assets import offline_parser
from ftdrake.cli.main import main
from ftdrake.compensation.estimators.physics import FixedJointsWarning
from ftdrake.compensation.files.persistence import load_model, save_model
from ftdrake.physics.robot import fixed_joint_values
from tests.helpers import DATA

ARM = DATA / "three_link_arm.urdf"
TORSO = 0.2  # rad: the torso pitches the whole arm, so it changes gravity seen in S
MASS, COM = 0.9, np.array([0.012, -0.006, 0.065])  # the gripper of three_link_arm.urdf
LINK = ('<link name="{0}"><inertial><mass value="0.1"/><inertia ixx="1e-4" iyy="1e-4" '
        'izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def vendor_urdf(tmp_path) -> str:
    """three_link_arm.urdf with a torso pitch joint under the arm, a head and two fingers:
    7 joints, of which the log holds j1, j2, j3."""
    text = ARM.read_text()
    text = text.replace('<parent link="base"/><child link="link1"/>',
                        '<parent link="torso_link"/><child link="link1"/>')
    extra = "".join(LINK.format(n) for n in ("torso_link", "head", "finger_l", "finger_r"))
    extra += """
  <joint name="torso" type="revolute"><parent link="base"/><child link="torso_link"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="head_pan" type="revolute"><parent link="base"/><child link="head"/>
    <origin xyz="0 0 0.6"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="finger_l" type="prismatic"><parent link="gripper"/><child link="finger_l"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/></joint>
  <joint name="finger_r" type="prismatic"><parent link="gripper"/><child link="finger_r"/>
    <axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/></joint>
"""
    text = text.replace("</robot>", extra + "</robot>")
    path = tmp_path / "vendor.urdf"
    path.write_text(text)
    return str(path)


def static_readings(urdf: str, q_arm: np.ndarray, rng) -> np.ndarray:
    """The gripper's weight in S at each pose, from Drake's own plant of the whole vendor
    URDF (every joint; the torso at TORSO, the head and fingers anywhere): F = m·g_S,
    T = c × F, plus a bias and a little noise. Independent of the chain ftdrake compiles."""
    plant = MultibodyPlant(0.0)
    offline_parser(plant).AddModels(file_name=urdf)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    frame_S = plant.GetFrameByName("gripper")
    bias = np.array([0.3, -0.2, 0.5, 0.01, -0.02, 0.015])
    out = []
    for q in q_arm:
        for name, value in (("j1", q[0]), ("j2", q[1]), ("j3", q[2]), ("torso", TORSO),
                            ("head_pan", 0.7), ("finger_l", 0.02), ("finger_r", 0.01)):
            plant.GetJointByName(name).set_default_positions([value])
        plant.SetDefaultContext(context)
        R_WS = frame_S.CalcPoseInWorld(context).rotation().matrix()
        F = MASS * (R_WS.T @ np.array([0.0, 0.0, -9.81]))
        out.append(np.r_[F, np.cross(COM, F)] + bias)
    return np.array(out) + rng.normal(0, [0.02] * 3 + [0.001] * 3, (len(q_arm), 6))


@pytest.fixture
def log(tmp_path):
    rng = np.random.default_rng(3)
    urdf = vendor_urdf(tmp_path)
    q = rng.uniform([-2.5, -1.5, -2.0], [2.5, 1.5, 2.0], (60, 3))
    Y = static_readings(urdf, q, rng)
    return urdf, q, Y


def static_model(urdf, **mapping):
    return PhysicsPayloadCompensator(mode="static", features="q", robot=urdf,
                                     sensor_frame="gripper", base_frame="base", **mapping)


def rows(q):
    return np.hstack([q, np.zeros_like(q), np.zeros_like(q)])


def test_the_log_joints_are_named_and_the_others_fixed(log, tmp_path):
    urdf, q, Y = log
    model = static_model(urdf, joints=["j1", "j2", "j3"], fixed_joints={"torso": TORSO})
    model.fit(rows(q), Y)
    assert model.parameters_[0] == pytest.approx(MASS, abs=0.01)
    assert model.parameters_[1:4] / model.parameters_[0] == pytest.approx(COM, abs=2e-3)
    saved = save_model(model, tmp_path / "m.ftd", target_names=[f"meas_{a}" for a in
                       ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")], target_units=["N"] * 3 + ["N*m"] * 3)
    Path(urdf).unlink()  # the model carries the robot and the mapping
    loaded = load_model(saved)
    assert loaded.joints == model.joints and loaded.fixed_joints == {"torso": TORSO}
    np.testing.assert_allclose(loaded.predict(rows(q[:5])), model.predict(rows(q[:5])),
                               atol=1e-12)
    assert np.sqrt(np.mean((loaded.predict(rows(q)) - Y)[:, :3] ** 2)) < 0.05  # N: the noise


def test_a_joint_left_out_stands_at_0_with_a_warning_naming_it(log):
    urdf, q, Y = log
    model = static_model(urdf, joints="j1,j2,j3")
    with pytest.warns(FixedJointsWarning, match=r"joints torso between .* fixed at 0 .*"
                                                 r" fixed_joints NAME=VALUE"):
        model.fit(rows(q), Y)
    # The torso is really at 0.2 rad: standing it at 0 leaves the tilt in the residual.
    assert model.residual_rms_[:3].max() > 5 * 0.02


def test_a_joint_count_mismatch_names_joints_and_lists_the_model_joints(log):
    urdf, q, Y = log
    with pytest.raises(RobotModelError, match=r"the data has 3 joints; the robot model has 7 "
                                              r"\(torso, j1, j2, j3, .*head_pan.*\): name the "
                                              r"log's joints .* with joints NAME"):
        static_model(urdf).fit(rows(q), Y)
    with pytest.raises(RobotModelError, match=r"\['j9'\] that robot model .* does not have"):
        static_model(urdf, joints="j1,j2,j9").fit(rows(q), Y)


def test_train_names_the_joints_on_the_command_line(log, tmp_path, capsys):
    import pandas as pd

    urdf, q, Y = log
    frame = pd.DataFrame(q, columns=["q_0", "q_1", "q_2"])
    frame.insert(0, "t", np.arange(len(q)) * 0.01)
    for i, axis in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")):
        frame[f"meas_{axis}"] = Y[:, i]
    data = tmp_path / "log.csv"
    frame.to_csv(data, index=False)
    fixed = tmp_path / "fixed.yaml"
    fixed.write_text("torso: 0.2\nhead_pan: 0.7\n")
    common = ["train", "--data", str(data), "--kind", "physics", "--features", "q",
              "--preset", "none", "--robot", urdf, "--sensor-frame", "gripper",
              "--base-frame", "base", "--no-check-units", "--out", str(tmp_path / "m.ftd")]
    assert main(common) == 2
    assert "--joints NAME,NAME" in capsys.readouterr().err
    assert main([*common, "--joints", "j1,j2,j3", "--fixed-joints", str(fixed)]) == 0
    model = load_model(tmp_path / "m.ftd")
    assert model.fixed_joints == {"torso": 0.2, "head_pan": 0.7}
    assert model.parameters_[0] == pytest.approx(MASS, abs=0.01)
    mapping = tmp_path / "joints.yaml"  # the same in one file
    mapping.write_text("joints: [j1, j2, j3]\nfixed_joints: {torso: 0.2}\n")
    assert main([*common, "--joints", str(mapping)]) == 0
    assert load_model(tmp_path / "m.ftd").parameters_[0] == pytest.approx(MASS, abs=0.01)
    mapping.write_text("joint: [j1, j2, j3]\n")
    assert main([*common, "--joints", str(mapping)]) == 2
    assert "must hold 'joints: [NAME, ...]'" in capsys.readouterr().err


def test_calibrate_names_the_joints_on_the_command_line(log, tmp_path, capsys):
    """The same static poses (no time column): calibrate takes --joints/--fixed-joints too."""
    import pandas as pd
    import yaml

    urdf, q, Y = log
    frame = pd.DataFrame(q, columns=["q_0", "q_1", "q_2"])
    for i, axis in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")):
        frame[f"meas_{axis}"] = Y[:, i]
    data = tmp_path / "poses.csv"
    frame.to_csv(data, index=False)
    common = ["calibrate", "--data", str(data), "--robot", urdf, "--sensor-frame", "gripper",
              "--base-frame", "base", "--correction", "none", "--quiet",
              "--out", str(tmp_path / "cal")]
    assert main(common) == 2
    assert "--joints NAME,NAME" in capsys.readouterr().err
    assert main([*common, "--joints", "j1,j2,j3", "--fixed-joints", "torso=0.2"]) == 0
    found = yaml.safe_load((tmp_path / "cal" / "calibration.yaml").read_text())
    assert found["calibration"]["parameters"]["m"]["value"] == pytest.approx(MASS, abs=0.01)


def test_fixed_joint_values_are_read_from_text_and_refused_when_malformed():
    assert fixed_joint_values("torso=0.2, finger_l=0.01") == (("torso", 0.2), ("finger_l", 0.01))
    with pytest.raises(RobotModelError, match="'torso' is not NAME=VALUE"):
        fixed_joint_values("torso")
