"""Station over memq://: published external wrench == measured − model.predict, exactly once."""

import numpy as np
from pydrake.lcm import DrakeLcm

from ftdrake import DetectorConfig, RandomForestCompensator
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import decode_wrench, encode_joint_state, encode_wrench
from ftdrake.hardware.station import build_hardware_station


def test_station_compensates_each_message_once():
    rng = np.random.default_rng(1)
    n = 7
    X = rng.uniform(-1, 1, size=(200, 3 * n))
    Y = np.c_[np.sin(X[:, :6]) * 3.0]
    model = RandomForestCompensator(features="q", n_estimators=5).fit(X, Y)
    lcm = DrakeLcm("memq://")
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=10.0, joint_state_timeout_s=10.0)
    _, handles = build_hardware_station(config, model, DetectorConfig(), lcm=lcm)
    dut = handles["station"]
    out = []
    lcm.Subscribe(config.external_wrench_channel, lambda d: out.append(decode_wrench(d)))
    rows, meas = [], []
    for k in range(20):
        t = 0.001 * (k + 1)
        q, w = rng.uniform(-1, 1, n), rng.normal(size=6)
        lcm.Publish(config.joint_state_channel,
                    encode_joint_state("iiwa_status", t, q, np.zeros(n)))
        lcm.Publish(config.ft_channel, encode_wrench(t, w))
        dut.spin_once(0)
        rows.append(np.r_[q, np.zeros(2 * n)])
        meas.append(w)
    lcm.HandleSubscriptions(0)
    expected = np.asarray(meas) - model.predict(np.asarray(rows))
    got = np.asarray([o.wrench for o in out])
    assert len(out) == 20 and dut.processed == 20
    np.testing.assert_allclose(got, expected, atol=1e-9)
    assert dut.monitor.received == {"ft": 20, "joint": 20} and not dut.monitor.rejected
