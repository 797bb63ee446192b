"""The `ftdrake` command's errors: a problem the user can fix is one line naming the flag that
fixes it (exit code 2); anything else is a bug in ftdrake and keeps its traceback."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ftdrake import conventions as col
from ftdrake import save_model
from ftdrake.cli.main import main
from ftdrake.compensation.estimators.gpr import GPRCompensator


def user_error(capsys, argv) -> str:
    """The one stderr line of a command that must fail as a user error (exit code 2)."""
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ftdrake {argv[0]}: error: "), err
    return lines[0].removeprefix(f"ftdrake {argv[0]}: error: ")


def refused(capsys, argv) -> str:
    """The message of a command line that argparse must refuse before running (exit code 2,
    usage, then ``ftdrake CMD: error: MESSAGE``)."""
    with pytest.raises(SystemExit) as exit_:
        main([str(a) for a in argv])
    assert exit_.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"ftdrake {argv[0]}: error: "), last
    return last.removeprefix(f"ftdrake {argv[0]}: error: ")


@pytest.mark.parametrize("command", ["simulate", "collect", "demo", "study",
                                     "learn-feedforward", "evaluate-detection", "serve"])
def test_missing_config_names_the_flag_and_writes_nothing(command, tmp_path, capsys):
    missing, out = tmp_path / "nope.yaml", tmp_path / "out"
    message = refused(capsys, [command, "--config", missing, "--out", out, "--quiet"])
    assert message == f"argument --config: {missing}: no such file"
    assert not out.exists()


@pytest.mark.parametrize(("text", "field"), [
    ("sensor:\n  noise_std: [1, 2]\n", "sensor.noise_std"),  # checked on loading
    ("models:\n  arm: /no/such/arm.sdf\n", "models.arm"),  # checked on building the scene
])
def test_invalid_config_names_the_flag_and_the_field(text, field, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    message = user_error(capsys, ["simulate", "--config", bad, "--trajectory", "fourier",
                                  "--out", tmp_path / "out", "--quiet"])
    assert message.startswith(f"--config {bad}: ") and field in message
    assert not (tmp_path / "out").exists()


def test_missing_or_unexportable_model_names_the_flag(tmp_path, capsys):
    missing = tmp_path / "nope.ftd"
    message = refused(capsys, ["export", "--model", missing, "--out", tmp_path / "m.onnx"])
    assert message == f"argument --model: {missing}: no such file"
    message = refused(capsys, ["export", "--model", tmp_path, "--out", tmp_path / "m.onnx"])
    assert message == f"argument --model: {tmp_path}: a folder, not a file"

    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (40, 21))
    gp_model = GPRCompensator(features="q", shared_kernel=True).fit(X, np.sin(X[:, :6]))
    gp = save_model(gp_model, tmp_path / "gp.ftd",
                    target_names=col.WRENCH_AXES, target_units=col.WRENCH_UNITS)
    message = user_error(capsys, ["export", "--model", gp, "--out", tmp_path / "m.onnx"])
    assert message.startswith(f"--model {gp}: a GPRCompensator has no ONNX export")
    assert not (tmp_path / "m.onnx").exists()


def test_output_of_the_wrong_kind_names_the_flag(tmp_path, capsys):
    a_file = tmp_path / "log.txt"
    a_file.write_text("")
    message = refused(capsys, ["simulate", "--trajectory", "fourier", "--out", a_file])
    assert message == f"argument --out: {a_file}: is a file; give a folder name"
    message = refused(capsys, ["collect", "--out", tmp_path])
    assert message == f"argument --out: {tmp_path}: is a folder; give a file name"
    message = refused(capsys, ["record", "--out", a_file / "log.parquet"])
    assert message == f"argument --out: {a_file / 'log.parquet'}: {a_file} is a file, not a folder"


@pytest.mark.parametrize(("argv", "allowed"), [
    (["simulate", "--duration", "-1"], "a positive number"),
    (["simulate", "--seed", "-3"], "in [0, 2**32)"),
    (["demo", "--duration", "x"], "a positive number"),
    (["collect", "--trajectories", "0"], ">= 1"),
    (["collect", "--jobs", "0"], ">= 1, or -1 for all cores"),
    (["study", "--duration", "-5"], "a positive number"),
    (["study", "--trajectories", "0"], ">= 1"),
    (["learn-feedforward", "--duration", "-1"], "a positive number"),
    (["train", "--jobs", "0"], ">= 1, or -1 for all cores"),
    (["train", "--t-start", "nan"], "a finite number"),
    (["evaluate-detection", "--budget", "0"], "a positive number"),
    (["study", "--halving-factor", "1"], ">= 2"),
    (["study", "--svr-max-iter", "0"], ">= 1, or -1 for no cap"),
])
def test_bad_number_is_refused_before_running(argv, allowed, capsys):
    message = refused(capsys, argv)
    assert message.startswith(f"argument {argv[1]}: must be "), message
    assert allowed in message and message.endswith(f"got {argv[2]!r}"), message


def test_cross_flag_range_names_both_flags(tmp_path, capsys):
    message = user_error(capsys, ["study", "--trajectories", "3", "--test-trajectories", "3",
                                  "--out", tmp_path / "study", "--quiet"])
    assert message.startswith("--test-trajectories 3: must be fewer than --trajectories (3)")
    assert not (tmp_path / "study").exists()


def test_field_set_by_a_flag_is_reported_as_the_flag(tmp_path, capsys):
    """--duration overrides trajectory.duration_s: the contact scenario's check names the flag."""
    message = user_error(capsys, ["simulate", "--duration", "0.5", "--out", tmp_path / "out",
                                  "--quiet"])
    assert message.startswith("--duration 0.5: ") and "need at least" in message
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bug", [KeyError, ValueError, FileNotFoundError])
def test_bug_in_the_library_propagates(bug, monkeypatch, tmp_path, capsys):
    """Not a FtdrakeError: a bug, raised with its traceback, not printed as a user error."""

    def broken(*args, **kwargs):
        raise bug("internal")

    monkeypatch.setattr("ftdrake.sim.station.build_station", broken)
    with pytest.raises(bug, match="internal"):
        main(["simulate", "--trajectory", "fourier", "--out", str(tmp_path / "out"), "--quiet"])
    assert "error:" not in capsys.readouterr().err


def test_python_m_ftdrake_reports_a_user_error(tmp_path):
    """`python -m ftdrake`: one line on stderr, exit code 2 (a bug's traceback and exit code 1
    are Python's own: see test_bug_in_the_library_propagates)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensor:\n  noise_std: [1, 2]\n")
    done = subprocess.run([sys.executable, "-m", "ftdrake", "simulate", "--config", str(bad)],
                          check=False, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2
    assert done.stderr == (f"ftdrake simulate: error: --config {bad}: scenario.sensor.noise_std: "
                           "must have 6 entries, got 2\n")


def test_evaluate_detection_names_a_bad_model_flag_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "det"
    message = refused(capsys, ["evaluate-detection", "--model", tmp_path / "none.ftd",
                               "--out", out])
    assert message.startswith("argument --model: ") and not out.exists()
    bad = tmp_path / "bad.ftd"
    bad.write_bytes(b"not a model")
    assert main(["evaluate-detection", "--model", str(bad), "--out", str(out)]) == 2
    assert f"--model {bad}" in capsys.readouterr().err and not out.exists()
