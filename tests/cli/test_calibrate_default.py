"""`calibrate` on a table whose orientation is given directly writes a model file that
`evaluate` and `replay` use, and its default (the correction chosen from the data) is never
worse than textbook gravity + bias least squares on any axis."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

import ftdrake
from ftdrake.cli.main import main
from ftdrake.compensation.calibration.calibration import KNOWN_COM, KNOWN_MASS, calibrate_table
from ftdrake.compensation.calibration.orientation_model import OrientationPayloadCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.compensation.files.persistence import load_model
from tests.helpers import LOADS, WRENCH, sensor_poses

G_W = np.array([0.0, 0.0, -9.81])


def _quaternion_table(seed, n):
    """ATI-like static poses: the simulated sensor (1.5–3 % gains, 2 % cross-talk, noise) on
    one tool, the orientation as the quaternion of R_WS (g_S = R_WSᵀ g_W)."""
    table, _ = sensor_poses(seed, n, LOADS[0])
    g_S = table[["gx", "gy", "gz"]].to_numpy()
    quats = []
    for g in g_S:
        r, _ = Rotation.align_vectors([G_W], [g])  # R·g_S = g_W
        x, y, z, w = r.as_quat()
        quats.append([w, x, y, z])
    q = np.array(quats)
    out = table.drop(columns=["gx", "gy", "gz", KNOWN_MASS, *KNOWN_COM])
    return out.assign(qw=q[:, 0], qx=q[:, 1], qy=q[:, 2], qz=q[:, 3]), g_S


@pytest.fixture(scope="module")
def tables():
    return _quaternion_table(1, 60), _quaternion_table(2, 60)


def _textbook(g_S, Y):
    """Textbook gravity + bias by ordinary least squares over all axes: F = m·g + b_F,
    T = h × g + b_T with h = m·c (10 unknowns), computed here independently."""
    n = len(g_S)
    A = np.zeros((n, 6, 10))
    A[:, :3, 0] = g_S
    gx, gy, gz = g_S.T
    zero = np.zeros(n)
    # h × g = −g × h = −[g]× h
    A[:, 3:, 1:4] = -np.stack([np.stack([zero, -gz, gy], -1), np.stack([gz, zero, -gx], -1),
                               np.stack([-gy, gx, zero], -1)], 1)
    A[:, :, 4:] = np.eye(6)
    theta = np.linalg.lstsq(A.reshape(-1, 10), Y.reshape(-1), rcond=None)[0]
    return lambda g: _apply(g, theta)


def _apply(g_S, theta):
    F = theta[0] * g_S + theta[4:7]
    T = np.cross(theta[1:4], g_S) + theta[7:10]
    return np.hstack([F, T])


def _rms(e):
    return np.sqrt(np.mean(e ** 2, axis=0))


def test_default_is_never_worse_than_textbook_gravity_and_bias(tables):
    (train, g_train), (held, g_held) = tables
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        cal = calibrate_table(train, correction="auto")
    assert cal.choice["choice"] in ("block", "full") and cal.correction is not None
    textbook = _textbook(g_train, train[WRENCH].to_numpy())
    for table, g in ((train, g_train), (held, g_held)):
        Y = table[WRENCH].to_numpy()
        ours, theirs = _rms(Y - cal.predict(table)), _rms(Y - textbook(g))
        assert np.all(ours <= theirs * (1 + 1e-9)), (ours, theirs)
    # The chosen correction more than halves gravity + bias's held-out error on every axis.
    plain = _rms(held[WRENCH].to_numpy() - cal.predict(held, corrected=False))
    assert np.all(_rms(held[WRENCH].to_numpy() - cal.predict(held)) < 0.5 * plain)


def test_too_few_poses_keep_gravity_and_bias_and_say_why(tables):
    (train, _), _ = tables
    cal = calibrate_table(train.iloc[:12], correction="auto")
    assert cal.correction is None and cal.choice["choice"] == "none"
    assert "too few" in cal.summary()


def test_quaternion_calibration_writes_a_model_evaluate_and_replay_use(tables, tmp_path,
                                                                      capsys):
    (train, _), (held, _) = tables
    train.to_csv(tmp_path / "poses.csv", index=False)
    held.to_csv(tmp_path / "held.csv", index=False)
    assert main(["calibrate", "--data", str(tmp_path / "poses.csv"),
                 "--out", str(tmp_path / "cal")]) == 0
    out = capsys.readouterr().out
    assert "model.ftd takes the orientation columns qw,qx,qy,qz" in out
    model = load_model(tmp_path / "cal" / "model.ftd")
    assert isinstance(model, OrientationPayloadCompensator) and model.n_joints_ == 4
    # evaluate on held-out poses: the reading to the sensor's noise (simulated σ 0.05 N).
    assert main(["evaluate", "--model", str(tmp_path / "cal" / "model.ftd"), "--data",
                 str(tmp_path / "held.csv"), "--json", str(tmp_path / "ev.json")]) == 0
    scores = json.loads((tmp_path / "ev.json").read_text())["metrics"]["all"]
    assert max(row["nmse"] for row in scores.values()) < 0.01
    capsys.readouterr()
    assert main(["evaluate", "--model", str(tmp_path / "cal" / "model.ftd"), "--data",
                 str(tmp_path / "held.csv"), "--noise-std", "0.01"]) == 0
    assert "rms/σ" in capsys.readouterr().out
    assert main(["evaluate", "--model", str(tmp_path / "cal" / "model.ftd"), "--data",
                 str(tmp_path / "held.csv"), "--noise-std", "0.01,0.02"]) == 2
    assert "give one, or one per target" in capsys.readouterr().err
    # The model's own prediction equals the calibration's (same correction, same payload).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        cal = calibrate_table(train, correction="auto")
    o = held[["qw", "qx", "qy", "qz"]].to_numpy()
    X = np.hstack([o, 0 * o, 0 * o])
    np.testing.assert_allclose(model.predict(X), cal.predict(held), atol=1e-9)
    # replay: the orientation columns as q_0..q_3 with zero velocities, one row a sample.
    log = pd.DataFrame({"t": 0.01 * np.arange(len(held)),
                        **{f"q_{i}": o[:, i] for i in range(4)},
                        **{f"qd_{i}": 0.0 for i in range(4)},
                        **{c: held[c] for c in WRENCH}})
    result = ftdrake.replay(model, log)
    np.testing.assert_allclose(result[[f"wrench_internal_{a}" for a in ("Fx", "Fy", "Fz", "Tx",
                                                                        "Ty", "Tz")]].to_numpy(),
                               model.predict(X), atol=1e-9)
    log.to_csv(tmp_path / "log.csv", index=False)
    assert main(["replay", "--model", str(tmp_path / "cal" / "model.ftd"), "--log",
                 str(tmp_path / "log.csv"), "--out", str(tmp_path / "replayed.csv")]) == 0
    assert len(pd.read_csv(tmp_path / "replayed.csv")) == len(held)
    # Refitted from its rows (scikit-learn's clone + fit), it is the plain calibration.
    refit = OrientationPayloadCompensator().fit(X, held[WRENCH].to_numpy())
    plain = calibrate_table(held)
    np.testing.assert_allclose(refit.predict(X), plain.predict(held), atol=1e-6)
