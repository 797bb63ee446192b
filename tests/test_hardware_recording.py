"""An LCM log written with lcm.EventLog reads back to the collect layout, unmatched counted."""

import lcm
import numpy as np
import pandas as pd

from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from ftdrake.hardware.recording import record_to_parquet


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
