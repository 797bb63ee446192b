"""ROS 2's sensor_msgs/Imu for a model that takes an IMU at the sensor: the message's bytes
read as the chain's IMU input, a station whose model needs an IMU without ros2.imu_topic
is refused naming the setting, and an IMU that stops is said on /diagnostics (ERROR, the
reason and the fix) until it resumes."""

import numpy as np
import pytest

from ftdrake import ConfigError, ScenarioConfig
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.station import Ros2Station, imu_sample
from tests.helpers import imu_message, imu_rows

NAMES = [f"arm_joint_{k + 1}" for k in range(7)]


def test_an_imu_message_reads_as_proper_acceleration_and_rate_in_S():
    msg = imu_message(2.25)
    t, values = imu_sample(type(msg).deserialize(msg.serialize()))
    assert t == 2.25
    np.testing.assert_array_equal(values, [1.0, 2.0, 9.8, 0.1, -0.2, 0.3])


def test_a_model_that_needs_an_imu_needs_the_imu_topic():
    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    with pytest.raises(ConfigError, match=r"ros2\.imu_topic"):
        Ros2Station(Ros2Config(joint_names=NAMES), ImuPayloadCompensator().fit(*imu_rows()),
                    scenario.chain_config())
    with pytest.raises(ConfigError, match=r"ros2\.imu_max_skew_s"):
        Ros2Config(joint_names=NAMES, imu_topic="/imu", imu_max_skew_s=0.0).validate()
