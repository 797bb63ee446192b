"""The outputs a live station publishes (``lcm.outputs``, ``ros2.outputs``): only those
listed go out, one message each per F/T sample; all by default; a name that is not a
published output is a ConfigError naming the key and the names to choose from."""

import numpy as np
import pytest

from ftdrake import ChainConfig, ConfigError, RandomForestCompensator
from ftdrake.conventions import PUBLISHED
from ftdrake.hardware import HardwareConfig, HardwareStation
from ftdrake.hardware.messages import encode_joint_state, encode_wrench

N = 7
Q = np.linspace(-0.5, 0.5, N)
SAMPLES = 20


def forest():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(200, 3 * N))
    return RandomForestCompensator(features="q", n_estimators=3).fit(X, np.sin(X[:, :6]))


def lcm_counts(outputs=None) -> dict:
    """Messages per output channel of an LCM station (memq://) fed SAMPLES pairs."""
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=1.0, joint_state_timeout_s=1.0)
    if outputs is not None:
        config.outputs = list(outputs)
    dut = HardwareStation(config, forest(), ChainConfig(), "memq://")
    channels = {config.output_channel(port) for port in PUBLISHED}
    counts = dict.fromkeys(channels, 0)
    for channel in channels:
        dut.lcm.subscribe(channel, lambda _d, c=channel: counts.__setitem__(c, counts[c] + 1))
    for k in range(SAMPLES):
        t = (k + 1) * 1e-3
        dut.lcm.publish(config.joint_state_channel, encode_joint_state("iiwa_status", t, Q))
        dut.lcm.publish(config.ft_channel, encode_wrench(t, np.ones(6)))
        dut.spin_once(0)
    dut.spin_once(0)
    assert dut.processed == SAMPLES and dut.summary()["fault"] is False
    return counts


def test_lcm_publishes_every_output_by_default():
    assert lcm_counts() == {"FT_WRENCH_COMPENSATED": SAMPLES, "FT_WRENCH_CONTACT": SAMPLES,
                            "FT_CONTACT_STATE": SAMPLES, "FT_BIAS": SAMPLES,
                            "FT_PAYLOAD": 0}  # no payload tracking by default


def test_lcm_publishes_only_the_listed_outputs():
    assert lcm_counts(["wrench_contact", "contact"]) == {
        "FT_WRENCH_COMPENSATED": 0, "FT_WRENCH_CONTACT": SAMPLES, "FT_CONTACT_STATE": SAMPLES,
        "FT_BIAS": 0, "FT_PAYLOAD": 0}
    # The contact state carries five values: any of them sends it.
    assert lcm_counts(["fault"]) == {"FT_WRENCH_COMPENSATED": 0, "FT_WRENCH_CONTACT": 0,
                                     "FT_CONTACT_STATE": SAMPLES, "FT_BIAS": 0,
                                     "FT_PAYLOAD": 0}


@pytest.mark.parametrize("outputs, says", [
    (["wrench_contact", "wrench_internal"],
     "['wrench_internal'] not published outputs; choose from wrench_compensated"),
    (["contact", "contact"], "names an output twice"),
    ([], "list the outputs to publish"),
])
def test_an_unknown_output_names_the_key(outputs, says):
    with pytest.raises(ConfigError, match=r"^lcm\.outputs: .*" + says.replace("[", r"\[")
                       .replace("]", r"\]")):
        HardwareConfig(outputs=outputs).validate("lcm")
    pytest.importorskip("cyclonedds")
    from ftdrake.hardware.ros2.config import Ros2Config

    with pytest.raises(ConfigError, match=r"^ros2\.outputs: "):
        Ros2Config(joint_names=["a"], outputs=outputs).validate()


def test_ros2_writes_only_the_listed_outputs():
    """The ROS 2 station's handlers fed directly: writers exist only for the listed outputs,
    and with neither contact nor contact_force listed no contact goes out."""
    pytest.importorskip("cyclonedds")
    from ftdrake.hardware.ros2.config import Ros2Config
    from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_stamped
    from ftdrake.hardware.ros2.station import Ros2Station

    names = [f"j{k}" for k in range(N)]
    dut = Ros2Station(Ros2Config(joint_names=names, domain_id=229, sensor_timeout_s=1.0,
                                 joint_state_timeout_s=1.0, outputs=["wrench_contact"]),
                      forest(), ChainConfig())
    try:
        assert set(dut._writers) == {"wrench_contact"}
        JointState = ros2_type("sensor_msgs/msg/JointState")
        for k in range(SAMPLES):
            t = (k + 1) * 1e-3
            dut._on_joint(JointState(header=header(t, "base"), name=names,
                                     position=[float(x) for x in Q], velocity=[0.0] * N,
                                     effort=[]), t)
            dut._on_wrench(wrench_stamped(header(t, "ft"), np.ones(6)), t)
        summary = dut.summary()
        assert summary["published_wrench"] == SAMPLES and summary["published_contact"] == 0
    finally:
        dut.close()
