"""Messages that name the fix: a robot whose base floats (a URDF without a world joint) is
refused with the flag that welds it, by the payload and the whole-arm model, and that flag
fixes it; wrench columns that are not found name the option that chooses them."""

import numpy as np
import pandas as pd
import pytest

from ftdrake import LogError, PhysicsPayloadCompensator, RobotModelError, calibrate_table
from ftdrake.cli.main import main
from ftdrake.compensation.arm import ArmDynamicsCompensator
from ftdrake.compensation.physics import ExcitationWarning

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
                                              r"--base-frame base \(base_frame='base'"):
        model.fit(rows(), np.zeros((30, 6)))
    model.set_params(base_frame="base")  # the fix the message names
    with pytest.warns(ExcitationWarning):  # one vertical joint turns no gravity into view
        model.fit(rows(), np.zeros((30, 6)))
    assert model.n_joints_ == 1


def test_the_arm_model_names_base_frame(floating_urdf):
    model = ArmDynamicsCompensator(robot=floating_urdf)
    with pytest.raises(RobotModelError, match=r"--base-frame base"):
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
