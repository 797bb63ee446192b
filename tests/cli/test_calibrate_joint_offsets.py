"""`ftdrake calibrate --joint-offsets`: the offsets of a table of static poses, in the printout
and calibration.yaml, the joints the poses cannot determine named; bad input named."""

import numpy as np
import pandas as pd
import yaml

from ftdrake.cli.main import main
from ftdrake.conventions import WRENCH_AXES
from ftdrake.testing import SIGMA, pose_tables, readings, static_poses

OFFSETS_DEG = np.array([0.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0])


def offset_table(seed, n=200, temperature=None):
    """Static poses read by encoders 2° off on L and B: the q columns are q_true − offset."""
    rng = np.random.default_rng(seed)
    X = static_poses(rng, n)
    Y = readings(X + np.r_[np.radians(OFFSETS_DEG), np.zeros(14)], rng)
    table = {f"q_{j}": X[:, j] for j in range(7)}  # the sensor turned with X + offset
    table.update({f"meas_{a}": Y[:, i] for i, a in enumerate(WRENCH_AXES)})
    if temperature is not None:
        table["temperature"] = temperature
        for axis, drift in (("meas_Fz", 0.5), ("meas_Tx", 0.01)):  # N/K, N·m/K
            table[axis] = table[axis] + drift * (temperature - 30.0)
    return pd.DataFrame(table)


def test_cli_finds_the_offsets_and_names_the_joints_it_cannot(tmp_path, capsys):
    rng = np.random.default_rng(3)
    offset_table(1, temperature=rng.uniform(25, 35, 200)).to_csv(tmp_path / "poses.csv",
                                                                 index=False)
    assert main(["calibrate", "--data", str(tmp_path / "poses.csv"), "--robot", "ftdrake",
                 "--joint-offsets", "auto", "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "joint_s: not identifiable" in out and "model.ftd does not apply" in out
    table = yaml.safe_load((tmp_path / "a" / "calibration.yaml").read_text())["joint_offsets"]
    assert set(table["offsets_deg"]) == {"joint_l", "joint_b"}
    for name in ("joint_l", "joint_b"):
        assert abs(table["offsets_deg"][name]["value"] - 2.0) <= 0.05
    assert set(table["not_identifiable"]) == {"joint_s", "joint_t"}
    assert table["choice"]["choice"] == "joint_l+joint_b"
    # The calibration's zero drift with temperature is taken off the readings first.
    for axis, sigma in zip(WRENCH_AXES, SIGMA, strict=True):
        assert table["residual_rms"][axis] < 1.5 * sigma
    # Without the flag: no section, the calibration as before.
    assert main(["calibrate", "--data", str(tmp_path / "poses.csv"), "--robot", "ftdrake",
                 "--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert "joint_offsets" not in yaml.safe_load((tmp_path / "b" / "calibration.yaml")
                                                 .read_text())


def test_cli_needs_joint_angles(tmp_path, capsys):
    _, rotation, _ = pose_tables(0, 30)
    rotation.to_csv(tmp_path / "rotation.csv", index=False)
    assert main(["calibrate", "--data", str(tmp_path / "rotation.csv"), "--joint-offsets",
                 "all", "--out", str(tmp_path / "c")]) == 2
    assert "--joint-offsets needs joint angles" in capsys.readouterr().err
