"""A live LCM station (memq://) with a model that takes an IMU at the sensor: the IMU channel
is required, each F/T sample is compensated with the IMU sample of its stamp, and a missing
or stale IMU publishes no wrench (a fault) until fresh IMU samples come back."""

import numpy as np
import pytest

from ftdrake import ConfigError, ScenarioConfig
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.live_imu import ImuPairing
from ftdrake.hardware.messages import (
    decode_imu,
    decode_wrench,
    encode_imu,
    encode_joint_state,
    encode_temperature,
    encode_wrench,
)
from tests.helpers import imu_rows

N = 7


def _imu_model():
    """The IMU model fitted to the wrench a rigid 0.8 kg tool gives at random IMU readings."""
    return ImuPayloadCompensator().fit(*imu_rows())


def test_the_imu_message_round_trips_and_refuses_other_signals():
    t, values = decode_imu(encode_imu(1.25, [0.1, 0.2, 9.8], [0.01, -0.02, 0.03]))
    assert t == 1.25
    np.testing.assert_array_equal(values, [0.1, 0.2, 9.8, 0.01, -0.02, 0.03])
    with pytest.raises(ValueError, match="not an IMU signal"):
        decode_imu(encode_temperature(1.0, 25.0))


def test_pairing_takes_the_nearest_stamp_and_refuses_stale_or_out_of_order_samples():
    pairing = ImuPairing(0.002)
    assert np.isnan(pairing.pair(0.0)).all() and pairing.unpaired == 1
    assert pairing.on_imu((0.010, np.arange(6.0))) and pairing.on_imu((0.011, np.ones(6)))
    assert not pairing.on_imu((0.011, np.zeros(6)))  # the same stamp again
    assert not pairing.on_imu((0.012, np.full(6, np.nan)))
    assert pairing.rejected == {"out_of_order": 1, "not_finite": 1}
    np.testing.assert_array_equal(pairing.pair(0.0104), np.arange(6.0))
    np.testing.assert_array_equal(pairing.pair(0.0112), np.ones(6))
    assert np.isnan(pairing.pair(0.0135)).all() and "0.013500" in pairing.detail


def test_the_station_compensates_with_the_imu_of_the_stamp_and_faults_without_it():
    model = _imu_model()
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    with pytest.raises(ConfigError, match=r"hardware\.imu_channel"):
        HardwareStation(HardwareConfig(lcm_url="memq://"), model, scenario.chain_config(),
                        "memq://")
    config = HardwareConfig(lcm_url="memq://", imu_channel="FT_IMU")
    now = [0.0]
    dut = HardwareStation(config, model, scenario.chain_config(), "memq://",
                          clock=lambda: now[0])
    wrenches = []
    dut.lcm.subscribe(config.output_channel("wrench_compensated"),
                      lambda d: wrenches.append(decode_wrench(d)))
    q = np.linspace(-0.5, 0.5, N)
    acc, gyro = np.array([0.3, -0.2, 9.7]), np.array([0.05, 0.1, -0.2])  # constant: α = 0
    measured = np.array([1.0, 2.0, 3.0, 0.1, 0.2, 0.3])

    def step(t, imu_t=None):
        now[0] = t
        if imu_t is not None:
            dut.lcm.publish(config.imu_channel, encode_imu(imu_t, acc, gyro))
        dut.lcm.publish(config.joint_state_channel,
                        encode_joint_state("iiwa_status", t, q, np.zeros(N)))
        dut.lcm.publish(config.ft_channel, encode_wrench(t, measured))
        dut.spin_once(0)
        dut.lcm.handle(0)

    step(0.000)  # no IMU yet: a fault, nothing published
    assert not wrenches and dut.output("fault")[0] == 1.0
    for k in range(1, 6):
        step(0.001 * k, imu_t=0.001 * k)
    assert len(wrenches) == 5
    row = np.concatenate([q, np.zeros(2 * N), acc, gyro, np.zeros(3)])
    expected = measured - model.predict(row[None])[0]
    np.testing.assert_allclose(wrenches[-1].wrench, expected, atol=1e-9)
    step(0.010)  # the IMU went silent 5 ms ago (> imu_max_skew_s): not compensated
    step(0.011)
    assert len(wrenches) == 5 and dut.output("fault")[0] == 1.0 and dut.imu.unpaired == 3
    step(0.012, imu_t=0.012)  # back
    assert len(wrenches) == 6 and dut.output("fault")[0] == 0.0
