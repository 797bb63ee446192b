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
from ftdrake.compensation.gpr import GPRCompensator


def user_error(capsys, argv) -> str:
    """The one stderr line of a command that must fail as a user error (exit code 2)."""
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ftdrake {argv[0]}: error: "), err
    return lines[0].removeprefix(f"ftdrake {argv[0]}: error: ")


@pytest.mark.parametrize("command", ["simulate", "collect", "demo"])
def test_missing_config_names_the_flag_and_writes_nothing(command, tmp_path, capsys):
    missing, out = tmp_path / "nope.yaml", tmp_path / "out"
    message = user_error(capsys, [command, "--config", missing, "--out", out, "--quiet"])
    assert message == f"--config {missing}: no such file"
    assert not out.exists()


@pytest.mark.parametrize(("text", "field"), [
    ("sensor:\n  noise_std: [1, 2]\n", "sensor.noise_std"),  # checked on loading
    ("models:\n  arm: /no/such/arm.sdf\n", "models.arm"),  # checked on building the scene
])
def test_invalid_config_names_the_flag_and_the_field(text, field, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    message = user_error(capsys, ["simulate", "--config", bad, "--scenario", "free",
                                  "--out", tmp_path / "out", "--quiet"])
    assert message.startswith(f"--config {bad}: ") and field in message
    assert not (tmp_path / "out").exists()


def test_missing_or_unexportable_model_names_the_flag(tmp_path, capsys):
    missing = tmp_path / "nope.ftd"
    message = user_error(capsys, ["export", "--model", missing, "--out", tmp_path / "m.onnx"])
    assert message == f"--model {missing}: no such file"

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
    message = user_error(capsys, ["simulate", "--scenario", "free", "--out", a_file])
    assert message == f"--out {a_file}: is a file; give a folder name"
    message = user_error(capsys, ["collect", "--out", tmp_path])
    assert message == f"--out {tmp_path}: is a folder; give a file name"


@pytest.mark.parametrize("argv", [
    ["simulate", "--duration", "-1"], ["simulate", "--seed", "-3"], ["demo", "--duration", "x"],
    ["collect", "--trajectories", "0"], ["collect", "--jobs", "0"],
])
def test_bad_number_is_refused_before_running(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"ftdrake {argv[0]}: error: argument {argv[1]}: "), last
    assert repr(argv[2]) in last


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
        main(["simulate", "--scenario", "free", "--out", str(tmp_path / "out"), "--quiet"])
    assert "error:" not in capsys.readouterr().err


def test_python_m_ftdrake_reports_a_user_error(tmp_path):
    """`python -m ftdrake`: one line on stderr, exit code 2 (a bug's traceback and exit code 1
    are Python's own: see test_bug_in_the_library_propagates)."""
    missing = tmp_path / "nope.yaml"
    done = subprocess.run([sys.executable, "-m", "ftdrake", "simulate", "--config", str(missing)],
                          check=False, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2
    assert done.stderr == f"ftdrake simulate: error: --config {missing}: no such file\n"


def test_evaluate_detection_names_a_bad_model_flag_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "det"
    assert main(["evaluate-detection", "--model", str(tmp_path / "none.ftd"),
                 "--out", str(out)]) == 2
    assert "--model" in capsys.readouterr().err and not out.exists()
    bad = tmp_path / "bad.ftd"
    bad.write_bytes(b"not a model")
    assert main(["evaluate-detection", "--model", str(bad), "--out", str(out)]) == 2
    assert f"--model {bad}" in capsys.readouterr().err and not out.exists()
