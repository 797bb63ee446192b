"""Every example runs from a clean folder, as a user runs it, and does what it says: each
test checks the printed numbers against the truth the example's data were made from."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ftdrake
from tests.helpers import ROOT

EXAMPLES = ROOT / "examples"


def run(name: str, cwd: Path, *args: str, timeout: float = 300) -> str:
    result = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=cwd,
                            capture_output=True, text=True, timeout=timeout, check=False)
    assert result.returncode == 0, result.stderr
    return result.stdout


def numbers(pattern: str, text: str) -> np.ndarray:
    """The numbers of the first bracketed list after `pattern` (numpy's print format)."""
    found = re.search(re.escape(pattern) + r"[^\[]*\[([^\]]*)\]", text)
    assert found, f"no '{pattern} [...]' in:\n{text}"
    return np.array([float(x) for x in found.group(1).split()])


def number(pattern: str, text: str) -> float:
    found = re.search(re.escape(pattern) + r"\s*(-?[\d.]+)", text)
    assert found, f"no '{pattern} <number>' in:\n{text}"
    return float(found.group(1))


def test_every_example_is_run_by_a_test():
    """Here (by ``run``), or by a test file of its own that names the example's path."""
    tested = set(re.findall(r'run\("(\w+\.py)"', Path(__file__).read_text()))
    for test in (ROOT / "tests").rglob("test_*.py"):
        tested |= set(re.findall(r'"examples"\s*/\s*"(\w+\.py)"', test.read_text()))
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_example_builds_own_diagram_and_compensates_at_rest(tmp_path):
    out = run("compensate_in_your_diagram.py", tmp_path)
    external = numbers("near zero):", out)
    assert np.abs(external[:3]).max() < 0.2  # N: compensated to within the model's error
    assert "contact detected: False" in out
    assert (tmp_path / "out" / "example_model.ftd").is_file()


def test_calibration_from_static_poses_recovers_the_payload(tmp_path):
    out = run("calibrate_from_static_poses.py", tmp_path)
    # The example's tool: 1.2 kg at (10, −5, 60) mm; readings with noise σ per axis.
    assert number("identified mass:", out) == pytest.approx(1.2, rel=0.005)
    np.testing.assert_allclose(numbers("identified centre of mass:", out), [10, -5, 60],
                               atol=0.5)  # mm
    ratio = numbers("held-out residual / noise σ per axis:", out)
    assert ratio.shape == (6,) and np.all((ratio > 0.8) & (ratio < 1.3))  # the noise, no more


def test_training_from_a_bag_reads_every_joint_state_and_predicts_a_new_bag(tmp_path):
    out = run("train_from_a_bag.py", tmp_path)
    # 6 s of joint states at 250 Hz (every 4th 1 kHz sample); the velocities are in the bag.
    assert "1500 rows" in out and "computed ['qdd']" in out
    # The rigid tool is 1.5 kg; the cable's hanging weight (0.12 kg) is taken as tool mass.
    assert 1.5 < number("identified tool mass:", out) < 1.75
    assert np.all(numbers("residual RMS / noise σ per axis:", out) < 15)
    model = ftdrake.load_model(tmp_path / "out" / "bag_model.ftd", expect_n_joints=7)
    assert isinstance(model, ftdrake.PhysicsPayloadCompensator)


def test_serving_on_lcm_compensates_every_message_and_reports_the_push(tmp_path):
    out = run("serve_on_lcm.py", tmp_path)
    assert "F/T messages sent 2000, processed 2000, compensated wrenches received 2000" in out
    np.testing.assert_allclose(numbers("before the push (mean, N):", out), [0, 0, 0], atol=0.5)
    np.testing.assert_allclose(numbers("during the push (mean, N):", out), [0, 0, 10], atol=0.5)
    assert 1.5 < number("contact first reported at t =", out) < 1.55  # the push starts at 1.5 s


@pytest.mark.slow
def test_detection_evaluation_finds_the_one_press(tmp_path):
    out = run("evaluate_detection.py", tmp_path)
    assert "true contacts 1, detected 1, missed 0, false positives 0" in out
    delay = numbers("detection delay (ms):", out)
    assert delay.shape == (1,) and 0 <= delay[0] <= 10
    error = numbers("contact wrench error after touchdown (RMS, N and N·m):", out)
    assert np.all(error[:3] < 2.0)  # N, on a ~25 N press


@pytest.mark.slow
def test_ur3_torque_models_transfer_to_the_other_trajectory(tmp_path):
    out = run("ur3_torque_models.py", tmp_path, "--out", str(tmp_path / "ur3"), timeout=600)
    arm = next(line for line in out.splitlines() if re.match(r"\|\s*arm\s*\|", line))
    scores = [float(x) for x in arm.split("|")[2:8]]
    assert len(scores) == 6 and min(scores) > 0.8  # every joint's variance score on id2
