"""Recording a diagram that is not ftdrake's: the example records a 3-joint arm from its own
URDF, identifies its gripper, runs the chain in the loop, and the replay equals the loop."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

import ftdrake
from ftdrake.conventions import QD, QDD_EST, joint_columns
from ftdrake.signals import DEFAULT_ACCELERATION_CUTOFF_HZ, causal_acceleration
from tests.helpers import ROOT

EXAMPLE = ROOT / "examples" / "record_your_diagram.py"


@pytest.mark.slow
def test_the_example_records_a_user_arm_trains_and_replays_the_loop(tmp_path):
    result = subprocess.run([sys.executable, str(EXAMPLE), "--seconds", "12", "--out",
                             str(tmp_path / "out")], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    # The URDF's gripper: 0.9 kg at (12, -6, 65) mm in S.
    assert report["mass_kg"] == pytest.approx(0.9, rel=0.03)
    np.testing.assert_allclose(report["com_mm"], [12.0, -6.0, 65.0], atol=8.0)  # mm
    assert report["replay_minus_loop_max"] <= 1e-12
    assert report["contact_samples"] == 0
    assert max(report["free_motion_residual_over_noise"]) < 10.0

    # The recorded layout: the loop's q̈ estimate, recomputed independently, and what
    # joint_state_layout reads.
    log = pd.read_parquet(tmp_path / "out" / "recorded.parquet")
    assert report["rows_recorded"] == len(log) == 12_000
    qd = log[joint_columns(QD, 3)].to_numpy()
    np.testing.assert_allclose(log[joint_columns(QDD_EST, 3)],
                               causal_acceleration(qd, 1e-3, DEFAULT_ACCELERATION_CUTOFF_HZ),
                               atol=1e-12)
    X = ftdrake.joint_state_layout(log)
    np.testing.assert_array_equal(X[:, 3:6], qd)
