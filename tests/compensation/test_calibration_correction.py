"""The sensor's gain/cross-talk correction (iCub's secondary calibration matrix) from static poses
of the simulated sensor with a known injected gain error and cross-talk."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pandas as pd
import pytest
import yaml

from ftdrake import SensorConfig
from ftdrake.cli.main import main
from ftdrake.compensation.calibration.calibration import (
    KNOWN_COM,
    KNOWN_MASS,
    calibrate_table,
    true_wrench,
)
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.errors import ConfigError
from ftdrake.testing import SIGMA
from tests.helpers import LOADS, WRENCH, sensor_poses


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def test_three_known_loads_recover_the_full_6x6_correction():
    tables = [sensor_poses(10 + i, 40, load) for i, load in enumerate(LOADS)]
    K = tables[0][1]  # the injected calibration: reading = K·W + bias
    train = pd.concat([t for t, _ in tables], ignore_index=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)  # fully determined: no warning
        dut = calibrate_table(train, correction="full").correction
    assert dut.rank == (7,) and dut.loads == 3 and dut.known_payload
    # Measured: max |M − K| per block 6.3e-4 (FF; injected up to 0.03), 7.7e-3 1/m (FT; up
    # to 0.35), 1.3e-5 m (TF; up to 8.7e-4), 1.4e-4 (TT; up to 0.03); the largest error is
    # 2.0 of its standard error (M and C).
    error = dut.sensor_matrix - K
    for block, tolerance in (((slice(0, 3), slice(0, 3)), 3e-3),
                             ((slice(0, 3), slice(3, 6)), 0.03),
                             ((slice(3, 6), slice(0, 3)), 5e-5),
                             ((slice(3, 6), slice(3, 6)), 5e-4)):
        assert np.abs(error[block]).max() < tolerance, (block, error[block])
    assert np.abs(error / dut.sensor_std_errors).max() < 4
    C_true = np.linalg.inv(K)
    assert np.abs((dut.matrix - C_true) / dut.std_errors).max() < 4
    np.testing.assert_allclose(dut.matrix @ dut.sensor_matrix, np.eye(6), atol=1e-12)
    # Held-out poses of the three loads: the corrected reading against gravity + bias only.
    held = pd.concat([sensor_poses(20 + i, 30, load)[0] for i, load in enumerate(LOADS)],
                     ignore_index=True)
    W_S = true_wrench(np.c_[held.gx, held.gy, held.gz],
                      np.c_[held[KNOWN_MASS], held[KNOWN_MASS].to_numpy()[:, None]
                            * held[list(KNOWN_COM)].to_numpy()])
    measured = held[WRENCH].to_numpy()
    uncorrected = measured - W_S
    uncorrected = np.sqrt(np.mean((uncorrected - uncorrected.mean(axis=0)) ** 2, axis=0))
    corrected = np.sqrt(np.mean((measured - dut.reading(W_S)) ** 2, axis=0))
    # Measured: 0.15–0.23 σ corrected (the 50-sample means' noise), 4.6–27 σ uncorrected
    # (31–152 × larger).
    assert np.all(corrected < 0.5 * SIGMA), corrected / SIGMA
    assert np.all(uncorrected > 10 * corrected), uncorrected / corrected


def test_one_load_gives_the_force_block_and_names_what_it_cannot():
    (train, K), (held, _) = sensor_poses(1, 60, LOADS[0]), sensor_poses(2, 200, LOADS[0])
    mass, com = LOADS[0]
    with pytest.warns(ExcitationWarning, match="torque correction along 1 direction"):
        dut = calibrate_table(train.drop(columns=[KNOWN_MASS, *KNOWN_COM]), correction="block",
                              known_payload={"mass": mass, "com": com}).correction
    # The force block for this load: K_FF + K_FT·[c]× (its torques are c × F); measured max
    # error 1.1e-4 (1.9 of its standard error; 0.03 from K_FF alone).
    effective = K[:3, :3] + K[:3, 3:] @ skew(np.asarray(com))
    error = dut.sensor_matrix[:3, :3] - effective
    assert np.abs(error).max() < 5e-4 and np.abs(error / dut.sensor_std_errors[:3, :3]).max() < 4
    assert np.all(np.isfinite(dut.std_errors[:3, :3]))
    # One load's torques are all ⊥ c: no torque entry is determined, said with its direction.
    assert np.all(np.isinf(dut.std_errors[3:, 3:]))
    assert dut.free_directions.shape == (1, 6) and "torque" in dut.undetermined[0]
    assert abs(dut.free_directions[0, 3:] @ com) / np.linalg.norm(com) > 0.99

    # A user without a known payload: the full linear model of this load against gravity +
    # bias only, on 200 held-out poses. Measured: rigid 4.3–26 σ, corrected 0.17–0.44 σ
    # (22–158 × smaller).
    table = train.drop(columns=[KNOWN_MASS, *KNOWN_COM])
    with pytest.warns(ExcitationWarning, match="wrench correction along 3 direction"):
        cal = calibrate_table(table, correction="full")
    measured = held[WRENCH].to_numpy()
    rigid = np.sqrt(np.mean((cal.predict(held, corrected=False) - measured) ** 2, axis=0))
    corrected = np.sqrt(np.mean((cal.predict(held) - measured) ** 2, axis=0))
    assert np.all(corrected < SIGMA), corrected / SIGMA
    assert np.all(rigid > 10 * corrected), rigid / corrected


def test_cli_prints_and_writes_the_correction_and_names_bad_input(tmp_path, capsys):
    table, _ = sensor_poses(1, 40, LOADS[0])
    table.drop(columns=[KNOWN_MASS, *KNOWN_COM]).to_csv(tmp_path / "poses.csv", index=False)
    code = main(["calibrate", "--data", str(tmp_path / "poses.csv"), "--correction", "block",
                 "--known-mass", "1.5", "--known-com", "0.02,0.0067,0.0867",
                 "--out", str(tmp_path / "cal")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "gain/cross-talk correction C" in out and "± ∞" not in out and " free " in out
    assert re.search(r"Fx: \+0\.99\d+ ± \d\.\de-0[45]", out), out  # a finite std error
    assert "warning: the poses do not determine the whole gain/cross-talk correction" in err
    saved = yaml.safe_load((tmp_path / "cal" / "calibration.yaml").read_text())
    correction = saved["calibration"]["correction"]
    assert np.shape(correction["matrix"]) == (6, 6) and correction["std_errors"][3][3] == "inf"
    assert correction["payload"] == "known (given)"
    assert main(["calibrate", "--data", str(tmp_path / "poses.csv"), "--known-mass", "1.5",
                 "--out", str(tmp_path / "bad")]) == 2
    assert "add --correction" in capsys.readouterr().err
    for argv, message in (  # refused while parsing
            (["--correction", "block", "--known-mass", "-1"], "--known-mass: must be a positive"),
            (["--correction", "full", "--known-mass", "1", "--known-com", "1,2"],
             "--known-com: expected X,Y,Z")):
        with pytest.raises(SystemExit):
            main(["calibrate", "--data", str(tmp_path / "poses.csv"), *argv,
                  "--out", str(tmp_path / "bad")])
        assert message in capsys.readouterr().err
    with pytest.raises(ConfigError, match="correction must be one of"):
        calibrate_table(table, correction="diagonal")
    with pytest.raises(ConfigError, match=r"sensor\.gain_error"):
        SensorConfig(gain_error=[0.5] + [0.0] * 5).validate()
