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


def test_codecs_give_the_lcm_classes_bytes_and_values():
    """The station's one-struct codecs against Drake's lcm-gen classes: the same bytes out,
    the same values in, the same errors for another type or a truncated message."""
    import struct

    from drake import lcmt_drake_signal, lcmt_force_torque, lcmt_iiwa_status

    from ftdrake.hardware.messages import CONTACT_COORDS

    rng = np.random.default_rng(3)
    for _ in range(50):
        t, w = rng.uniform(0, 1e4), rng.normal(size=6) * 100
        ref = lcmt_force_torque()
        ref.timestamp = round(t * 1e6)
        ref.fx, ref.fy, ref.fz, ref.tx, ref.ty, ref.tz = w
        assert encode_wrench(t, w) == ref.encode()
        sample = decode_wrench(ref.encode())
        assert sample.t == ref.timestamp * 1e-6 and np.array_equal(sample.wrench, w)
        state = ContactState(t, *(bool(b) for b in rng.integers(2, size=1)), rng.normal(),
                             *(bool(b) for b in rng.integers(2, size=3)))
        signal = lcmt_drake_signal()
        signal.timestamp, signal.dim, signal.coord = round(t * 1e6), 5, list(CONTACT_COORDS)
        signal.val = [float(state.contact), state.contact_force, float(state.fault),
                      float(state.out_of_domain), float(state.payload_change)]
        assert encode_contact_state(state) == signal.encode()
        q, v, tau = rng.normal(size=(3, 7))
        status = lcmt_iiwa_status.decode(encode_joint_state("iiwa_status", t, q, v, tau))
        status.joint_position_measured, status.joint_velocity_estimated = q, v
        status.joint_torque_measured = tau
        joint = decode_joint_state("iiwa_status", status.encode())
        assert joint.t == status.utime * 1e-6
        for got, want in ((joint.q, q), (joint.v, v), (joint.tau, tau)):
            assert np.array_equal(got, want)
    with pytest.raises(ValueError):
        decode_wrench(encode_joint_state("iiwa_status", 1.0, np.ones(7)))
    with pytest.raises(ValueError):
        decode_joint_state("iiwa_status", encode_wrench(1.0, np.ones(6)))
    with pytest.raises(struct.error):
        decode_wrench(encode_wrench(1.0, np.ones(6))[:-1])
    with pytest.raises(struct.error):
        decode_joint_state("iiwa_status", encode_joint_state("iiwa_status", 1.0,
                                                             np.ones(7))[:-1])
