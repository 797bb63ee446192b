"""`ftdrake train --kind imu-physics` and `--motion-std`: on a simulated log with an IMU at the
sensor the command's model predicts what the library's fit on the same rows predicts; a log
without the IMU's columns is a LogError naming them and the fix."""

import dataclasses as dc

import numpy as np
import pytest

from ftdrake import conventions as col
from ftdrake.cli.main import main
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.compensation.estimators.motion_std import MotionStdCompensator
from ftdrake.compensation.files.persistence import load_model
from ftdrake.config import ScenarioConfig
from ftdrake.data.dataset import imu_layout, save_dataset
from ftdrake.sim.collection import collect


@pytest.fixture(scope="module")
def imu_log(tmp_path_factory):
    config = ScenarioConfig()
    config.cable.enabled = False
    config.imu = dc.replace(config.imu, enabled=True)
    frame = collect(config, 1, kind="fourier", duration=1.0, n_jobs=1, progress=False)
    path = tmp_path_factory.mktemp("imu") / "imu.parquet"
    save_dataset(frame, path)
    return path, frame


#: The loop's joint state, as imu_layout reads it (the log's own q̇ and causal q̈ estimate).
EST = ["--velocities", r"re:qd_est_\d+", "--accelerations", r"re:qdd_est_\d+"]


def test_train_builds_the_imu_model_and_a_motion_std_around_it(imu_log, tmp_path):
    path, frame = imu_log
    out = tmp_path / "imu.ftd"
    assert main(["train", "--data", str(path), "--kind", "imu-physics", "--robot", "ftdrake",
                 "--preset", "none", "--out", str(out), "--quiet", *EST]) == 0
    model = load_model(out)
    assert type(model) is ImuPayloadCompensator
    X = imu_layout(frame)
    Y = frame[col.wrench_columns(col.MEASURED)].to_numpy()
    direct = ImuPayloadCompensator(identification="consistent").fit(X, Y)
    np.testing.assert_allclose(model.predict(X), direct.predict(X), atol=1e-9)

    wrapped = tmp_path / "imu_motion.ftd"
    assert main(["train", "--data", str(path), "--kind", "imu-physics", "--robot", "ftdrake",
                 "--preset", "none", "--motion-std", "--out", str(wrapped), "--quiet",
                 *EST]) == 0
    model = load_model(wrapped)
    assert type(model) is MotionStdCompensator and model.needs_imu
    np.testing.assert_allclose(model.predict(X), direct.predict(X), atol=1e-9)
    expected = MotionStdCompensator(direct).fit(X, Y).predict_std(X)
    np.testing.assert_allclose(model.predict_std(X), expected, rtol=1e-6)


def test_a_log_without_imu_columns_is_refused_naming_them(imu_log, tmp_path, capsys):
    _, frame = imu_log
    plain = tmp_path / "plain.parquet"
    save_dataset(frame.drop(columns=list(col.IMU_INPUTS)), plain)
    code = main(["train", "--data", str(plain), "--kind", "imu-physics", "--robot", "ftdrake",
                 "--preset", "none", "--out", str(tmp_path / "m.ftd"), "--quiet"])
    err = capsys.readouterr().err
    assert code != 0
    assert "imu_acc_x" in err and "scenario.imu.enabled" in err and "--kind physics" in err


def test_motion_std_and_a_domain_calibration_are_refused():
    from ftdrake.errors import ConfigError
    from ftdrake.training.options import TrainOptions

    with pytest.raises(ConfigError, match="motion_std"):
        TrainOptions(motion_std=True, domain_holdout=0.2)
