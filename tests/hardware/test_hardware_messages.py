"""Hardware layer: config validation, message round-trips (also over LCM memq://)."""

import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed
from pydrake.lcm import DrakeLcm

from ftdrake import ConfigError
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import (
    ContactState,
    decode_contact_state,
    decode_joint_state,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_wrench,
)


def test_config_loads_from_yaml_and_names_bad_field():
    dut = yaml_load_typed(schema=HardwareConfig, data="""
lcm_url: memq://
joint_state_type: panda_status
joint_state_channel: PANDA_STATUS
n_joints: 7
""").validate()
    assert dut.joint_state_type == "panda_status" and dut.lcm_url == "memq://"
    with pytest.raises(ConfigError, match=r"hardware.joint_state_type"):
        HardwareConfig(joint_state_type="ur_state").validate()
    with pytest.raises(ConfigError, match=r"hardware.velocity_channel"):
        HardwareConfig(joint_state_type="robot_state").validate()
    with pytest.raises(ConfigError, match=r"hardware.sensor_timeout_s"):
        HardwareConfig(sensor_timeout_s=0.0).validate()
    with pytest.raises(ConfigError, match=r"hardware.ft_channel"):
        HardwareConfig(ft_channel="IIWA_STATUS").validate()


@pytest.mark.parametrize("kind", ["iiwa_status", "panda_status", "robot_state"])
def test_joint_state_round_trip(kind):
    rng = np.random.default_rng(0)
    q, v, tau = rng.normal(size=(3, 7))
    dut = decode_joint_state(kind, encode_joint_state(kind, 12.345678, q, v, tau))
    assert dut.t == pytest.approx(12.345678, abs=1e-12)
    if kind == "robot_state":  # float32 on the wire
        np.testing.assert_allclose(dut.q, q.astype(np.float32), rtol=0, atol=0)
        assert dut.v is None and dut.tau is None
    else:
        np.testing.assert_array_equal(dut.q, q)
        np.testing.assert_array_equal(dut.v, v)
        np.testing.assert_array_equal(dut.tau, tau)


def test_wrench_and_contact_round_trip_over_memq():
    lcm = DrakeLcm("memq://")
    got = []
    lcm.Subscribe("FT", got.append)
    lcm.Subscribe("CONTACT", got.append)
    w = np.array([1.0, -2.0, 3.5, 0.1, -0.2, 0.3])  # Fx Fy Fz N, Tx Ty Tz N·m
    lcm.Publish("FT", encode_wrench(0.001, w))
    lcm.Publish("CONTACT", encode_contact_state(ContactState(0.001, True, 4.2, False, True)))
    assert lcm.HandleSubscriptions(0) == 2
    ft = decode_wrench(got[0])
    assert ft.t == pytest.approx(0.001)
    np.testing.assert_array_equal(ft.wrench, w)
    assert decode_contact_state(got[1]) == ContactState(0.001, True, 4.2, False, True)
