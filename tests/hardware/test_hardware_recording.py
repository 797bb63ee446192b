"""An LCM log written with lcm.EventLog reads back to the collect layout, unmatched counted."""

import json

import lcm
import numpy as np
import pandas as pd

from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from ftdrake.hardware.recording import read_lcm_log, record_to_parquet


def test_log_reads_back(tmp_path):
    config = HardwareConfig(lcm_url="memq://")
    log = lcm.EventLog(str(tmp_path / "log.lcm"), "w", overwrite=True)
    for k in range(5):
        t = 0.001 * (k + 1)
        log.write_event(int(t * 1e6), config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, np.full(7, k), np.full(7, -k)))
        log.write_event(int(t * 1e6) + 1, config.ft_channel, encode_wrench(t, np.arange(6.0) + k))
    log.write_event(10_000, config.ft_channel, encode_wrench(0.010, np.zeros(6)))  # no joint ≤ 2 ms
    log.close()
    report = record_to_parquet(tmp_path / "log.lcm", tmp_path / "out.parquet", config)
    dut = pd.read_parquet(tmp_path / "out.parquet")
    assert report == {"ft": 6, "joint": 5, "rows": 5, "unmatched_ft": 1, "unused_joint": 0,
                      "malformed": 0}
    assert list(dut.columns[:2]) == ["t", "q_0"] and "qd_6" in dut and "meas_Tz" in dut
    np.testing.assert_allclose(dut["t"], 0.001 * np.arange(1, 6))
    np.testing.assert_array_equal(dut["q_3"], np.arange(5.0))
    np.testing.assert_array_equal(dut["meas_Fy"], np.arange(5.0) + 1)


def _robot_log(n_rows, seed, start=0):
    """A collect-layout table of a smooth motion from sample `start` on (t on the µs grid, as
    a recorder stores it); `seed` draws the noise."""
    motion, rng = np.random.default_rng(0), np.random.default_rng(seed)
    t = np.arange(start + 1, start + n_rows + 1) * 1000 * 1e-6
    phase, freq = motion.uniform(0, 6, 7), motion.uniform(1.0, 2.0, 7)
    q = 0.8 * np.sin(2 * np.pi * freq * t[:, None] + phase)
    qd = 0.8 * 2 * np.pi * freq * np.cos(2 * np.pi * freq * t[:, None] + phase)
    meas = np.c_[3 * np.sin(q[:, :3]), 0.2 * np.cos(q[:, 3:6])] + rng.normal(0, 0.02, (n_rows, 6))
    table = pd.DataFrame({"t": t})
    for name, values in (("q", q), ("qd", qd)):
        for i in range(7):
            table[f"{name}_{i}"] = values[:, i]
    for i, axis in enumerate(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")):
        table[f"meas_{axis}"] = meas[:, i]
    return table


def _write_lcm_log(table, path, config):
    log = lcm.EventLog(str(path), "w", overwrite=True)
    q = table[[f"q_{i}" for i in range(7)]].to_numpy()
    qd = table[[f"qd_{i}" for i in range(7)]].to_numpy()
    w = table[[c for c in table if c.startswith("meas_")]].to_numpy()
    for k, t in enumerate(table["t"]):
        utime = round(t * 1e6)
        log.write_event(utime, config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q[k], qd[k]))
        log.write_event(utime + 100, config.ft_channel, encode_wrench(t, w[k]))
    log.close()


def test_lcm_log_trains_the_model_the_parquet_trains(tmp_path, capsys):
    """`record --from-log` → train → evaluate scores exactly as train on the equivalent
    Parquet → evaluate."""
    from ftdrake.cli.main import main

    config = HardwareConfig()
    table = _robot_log(1000, seed=0)
    table.to_parquet(tmp_path / "direct.parquet", index=False)
    _robot_log(300, seed=1, start=100).to_parquet(tmp_path / "held_out.parquet", index=False)
    _write_lcm_log(table, tmp_path / "robot.lcmlog", config)
    assert main(["record", "--from-log", str(tmp_path / "robot.lcmlog"),
                 "--out", str(tmp_path / "recorded.parquet")]) == 0
    assert json.loads(capsys.readouterr().out)["rows"] == 1000
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "recorded.parquet"), table)
    scores = {}
    for source in ("recorded", "direct"):
        model = tmp_path / f"{source}.ftd"
        assert main(["train", "--data", str(tmp_path / f"{source}.parquet"), "--model", "rf",
                     "--features", "q,qd", "--preset", "none", "--velocities", "qd_*",
                     "--jobs", "1", "--quiet", "--out", str(model)]) == 0
        assert main(["evaluate", "--model", str(model), "--data",
                     str(tmp_path / "held_out.parquet"), "--quiet",
                     "--json", str(tmp_path / f"{source}.json")]) == 0
        scores[source] = json.loads((tmp_path / f"{source}.json").read_text())["metrics"]
    assert scores["recorded"] == scores["direct"]
    assert 0 < scores["direct"]["all"]["meas_Fx"]["nmse"] < 0.1  # a real fit


def test_robot_state_log_pairs_velocities(tmp_path):
    config = HardwareConfig(joint_state_type="robot_state", joint_state_channel="ROBOT_STATE",
                            velocity_channel="ROBOT_VELOCITY")
    log = lcm.EventLog(str(tmp_path / "log.lcm"), "w", overwrite=True)
    for k in range(1, 6):
        t = k * 1e-3
        if k != 3:  # the velocity of t = 3 ms is lost: that position is unpaired
            log.write_event(k * 1000, config.velocity_channel,
                            encode_joint_state("robot_state", t, np.full(7, -0.5 * k)))
        log.write_event(k * 1000 + 1, config.joint_state_channel,
                        encode_joint_state("robot_state", t, np.full(7, 0.25 * k)))
        log.write_event(k * 1000 + 2, config.ft_channel, encode_wrench(t, np.full(6, k)))
    log.close()
    dut, report = read_lcm_log(tmp_path / "log.lcm", config)
    assert report["unpaired"] == 1 and report["rows"] == 5 and report["joint"] == 4
    np.testing.assert_array_equal(dut["qd_0"], [-0.5, -1.0, -1.0, -2.0, -2.5])  # 3 ms: 2 ms's
    np.testing.assert_array_equal(dut["q_6"], [0.25, 0.5, 0.5, 1.0, 1.25])
