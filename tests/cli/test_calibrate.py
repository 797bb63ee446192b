"""`ftdrake calibrate` on a table of static poses: orientation-only and joint angles + robot
give the same prediction on held-out poses; bad input is named."""

import numpy as np
import pandas as pd
import pytest
import yaml

from ftdrake.cli.main import main
from ftdrake.compensation.calibration.calibration import calibrate_table
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.files.persistence import load_model
from ftdrake.conventions import WRENCH_AXES
from ftdrake.errors import ConfigError, LogError, RobotModelError
from ftdrake.testing import SIGMA, THETA, pose_tables, static_poses

WRENCH = [f"meas_{a}" for a in WRENCH_AXES]
TRUE_COM = THETA[1:4] / THETA[0]


def test_orientation_only_predicts_held_out_poses_as_well_as_joint_angles_with_a_robot():
    joints, rotation, _ = pose_tables(0, 40, temperature=True)
    held_joints, held_rotation, truth = pose_tables(1, 200, temperature=True)
    by_rotation = calibrate_table(rotation)
    by_joints = calibrate_table(joints, robot="ftdrake")
    assert by_rotation.source == "quaternion" and by_joints.source == "joint_angles"
    assert by_rotation.mounting_rpy_deg is None and by_joints.mounting_rpy_deg is not None
    errors = {}
    for name, cal, table in (("rotation", by_rotation, held_rotation),
                             ("joints", by_joints, held_joints)):
        assert cal.parameters[0] == pytest.approx(THETA[0], rel=0.01)
        np.testing.assert_allclose(cal.com, TRUE_COM, atol=2e-3)
        np.testing.assert_allclose(cal.temperature_coefficients[:3], [0.02, -0.01, 0.05],
                                   atol=5 * cal.temperature_std_errors[:3].max())
        assert np.all(cal.standard_errors > 0) and np.all(np.isfinite(cal.standard_errors))
        errors[name] = np.sqrt(np.mean(((cal.predict(table) - truth) / SIGMA) ** 2, axis=0))
    # Measured: both about 0.2–0.5 σ per axis; orientation-only no worse than 1.25×.
    assert np.all(errors["rotation"] <= 1.25 * errors["joints"] + 0.05), errors
    assert np.all(errors["rotation"] < 1.0)
    with pytest.raises(LogError, match="no 'temperature' column"):
        by_rotation.predict(held_rotation.drop(columns="temperature"))


@pytest.mark.parametrize("kind", ["rotation_matrix", "roll_pitch_yaw", "gravity"])
def test_every_orientation_form_gives_the_same_payload(kind):
    _, rotation, _ = pose_tables(0, 30)
    q = rotation[["qw", "qx", "qy", "qz"]].to_numpy()
    from scipy.spatial.transform import Rotation

    R = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()
    if kind == "rotation_matrix":
        cols = {f"r{i}{j}": R[:, i, j] for i in range(3) for j in range(3)}
    elif kind == "roll_pitch_yaw":
        rpy = Rotation.from_matrix(R).as_euler("xyz")  # extrinsic x-y-z, as Drake's RPY
        cols = dict(zip(("roll", "pitch", "yaw"), rpy.T, strict=True))
    else:
        g = np.einsum("nji,j->ni", R, [0, 0, -1.0])  # a unit gravity direction in S
        cols = dict(zip(("gx", "gy", "gz"), g.T, strict=True))
    table = pd.DataFrame({**cols, **{c: rotation[c] for c in WRENCH}})
    dut = calibrate_table(table)
    reference = calibrate_table(rotation)
    assert dut.source == kind
    np.testing.assert_allclose(dut.parameters, reference.parameters, rtol=1e-6, atol=1e-8)


def test_cli_writes_yaml_and_a_model_file_and_names_bad_input(tmp_path, capsys):
    joints, rotation, _ = pose_tables(0, 30)
    joints.to_csv(tmp_path / "joints.csv", index=False)
    rotation.to_csv(tmp_path / "rotation.csv", index=False)
    assert main(["calibrate", "--data", str(tmp_path / "joints.csv"), "--robot", "ftdrake",
                 "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "centre of mass" in out and "± " in out and "inertia needs motion" in out
    table = yaml.safe_load((tmp_path / "a" / "calibration.yaml").read_text())["calibration"]
    assert table["parameters"]["m"]["value"] == pytest.approx(THETA[0], rel=0.01)
    model = load_model(tmp_path / "a" / "model.ftd")
    X = np.hstack([joints[[f"q_{j}" for j in range(7)]].to_numpy(), np.zeros((30, 14))])
    assert model.predict(X).shape == (30, 6) and model.provides_std
    assert main(["calibrate", "--data", str(tmp_path / "rotation.csv"),
                 "--out", str(tmp_path / "b")]) == 0
    assert "absorbed" in (tmp_path / "b" / "calibration.yaml").read_text()
    # Bad input: a robot without the named frame, a negative prior mass.
    sdf = "models/ft_sensor_tool.sdf"
    with pytest.raises(RobotModelError, match="no_such_frame"):
        calibrate_table(joints, robot=sdf, sensor_frame="no_such_frame")
    with pytest.raises(SystemExit):
        main(["calibrate", "--data", str(tmp_path / "rotation.csv"), "--prior-mass", "-1",
              "--out", str(tmp_path / "c")])
    assert "argument --prior-mass: must be a positive number; got '-1'" in \
        capsys.readouterr().err
    assert not (tmp_path / "c").exists()
    with pytest.raises(ConfigError, match=r"prior\.mass"):
        calibrate_table(rotation, prior={"mass": -1.0})
    # `train` on a static table (no time column) says to use calibrate.
    assert main(["train", "--data", str(tmp_path / "rotation.csv"), "--kind", "physics",
                 "--robot", "ftdrake", "--out", str(tmp_path / "m.ftd"), "--quiet"]) == 2
    assert "ftdrake calibrate" in capsys.readouterr().err


def test_model_file_applies_the_gain_crosstalk_correction(tmp_path, capsys):
    """Joint angles + a sensor with gain and cross-talk errors: `calibrate --correction full`
    writes a model.ftd whose readings go through M, predicting held-out poses within the
    noise where the gravity + bias model does not."""
    rng = np.random.default_rng(7)
    M = np.eye(6) + np.diag([0.03, -0.02, 0.015, 0.025, -0.03, 0.02])
    M[:3, 3:] += 0.2 * rng.uniform(-1, 1, (3, 3))  # torque → force cross-talk, N per N·m
    M[3:, :3] += 0.002 * rng.uniform(-1, 1, (3, 3))
    physics = PhysicsPayloadCompensator(mode="static", features="q")

    def table(seed, n):
        X = static_poses(np.random.default_rng(seed), n)
        ideal = physics.regressor(X)[:, :, :10] @ THETA[:10]
        Y = ideal @ M.T + THETA[10:] + np.random.default_rng(seed + 100).normal(
            size=(n, 6)) * SIGMA
        return pd.DataFrame({**{f"q_{j}": X[:, j] for j in range(7)},
                             **dict(zip(WRENCH, Y.T, strict=True))}), X, Y

    train, _, _ = table(3, 60)
    _, X_held, Y_held = table(4, 200)
    train.to_csv(tmp_path / "poses.csv", index=False)
    assert main(["calibrate", "--data", str(tmp_path / "poses.csv"), "--robot", "ftdrake",
                 "--correction", "full", "--out", str(tmp_path / "cal")]) == 0
    assert "model.ftd predicts readings through the correction" in capsys.readouterr().out
    model = load_model(tmp_path / "cal" / "model.ftd")
    corrected = np.sqrt(np.mean((model.predict(X_held) - Y_held) ** 2, axis=0))
    rigid = calibrate_table(train, robot="ftdrake").model
    uncorrected = np.sqrt(np.mean((rigid.predict(X_held) - Y_held) ** 2, axis=0))
    assert np.all(corrected < 2 * SIGMA), corrected / SIGMA
    # Per axis 1.9–20× here (the Fz gain hides in the mass): overall at least 5×.
    assert np.linalg.norm(uncorrected / SIGMA) > 5 * np.linalg.norm(corrected / SIGMA)
    # The compiled row path sees the same matrix.
    mean, _ = model.row_predictor()(X_held[0])
    np.testing.assert_allclose(mean, model.predict(X_held[:1])[0], atol=1e-9)
