"""ROS 2's sensor_msgs/Imu for a model that takes an IMU at the sensor: the message's bytes
read as the chain's IMU input, a station whose model needs an IMU without ros2.imu_topic
is refused naming the setting, and an IMU that stops is said on /diagnostics (ERROR, the
reason and the fix) until it resumes."""

import numpy as np
import pytest

from ftdrake import ConfigError, ScenarioConfig
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.hardware.ros2.config import Ros2Config
from ftdrake.hardware.ros2.messages import header, ros2_type
from ftdrake.hardware.ros2.station import ERROR, WARN, Ros2Station, imu_sample
from tests.helpers import imu_rows

NAMES = [f"arm_joint_{k + 1}" for k in range(7)]


def imu_message(t, acc=(1.0, 2.0, 9.8), gyro=(0.1, -0.2, 0.3)):
    imu, vector = ros2_type("sensor_msgs/msg/Imu"), ros2_type("geometry_msgs/msg/Vector3")
    return imu(header=header(t, "ft_sensor"),
               orientation=ros2_type("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0),
               orientation_covariance=[0.0] * 9,
               angular_velocity=vector(**dict(zip("xyz", gyro, strict=True))),
               angular_velocity_covariance=[0.0] * 9,
               linear_acceleration=vector(**dict(zip("xyz", acc, strict=True))),
               linear_acceleration_covariance=[0.0] * 9)


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


def test_an_imu_that_stops_is_an_error_on_diagnostics_until_it_resumes():
    pytest.importorskip("cyclonedds")
    from tests.hardware.ros2.test_ros2_station import Rig, wait_for

    scenario = ScenarioConfig()
    scenario.chain.bias_tracker.enabled = False
    rig = Rig(scenario, model=ImuPayloadCompensator().fit(*imu_rows()), imu_topic="/ft_imu")
    try:
        imu = rig.driver.publisher("/ft_imu", "sensor_msgs/msg/Imu")
        wait_for(lambda: all(rig.driver.matched().values()), "the IMU topic to match")

        def step(t, with_imu=True):
            if with_imu:  # received before the wrench of its stamp
                accepted = rig.dut.imu.accepted
                imu.write(imu_message(t))
                wait_for(lambda: (rig.dut.spin_once(0), rig.dut.imu.accepted)[1] > accepted,
                         "the station to receive the IMU sample")
            rig.step(t)

        for k in range(5):
            step(0.001 * k)
        assert len(rig.got["wrench"]) == 5 and not rig.dut.monitor.fault
        for k in range(5, 10):  # silent: from 7 ms on no IMU sample is within 2 ms
            step(0.001 * k, with_imu=False)
        status, values = rig.last_status()
        assert status.level == ERROR and values["reason"] == "imu_stamp_gap"
        assert status.message.startswith("fault imu_stamp_gap: no IMU sample stamped within")
        assert "Fix: the IMU's driver on ros2.imu_topic '/ft_imu'" in status.message
        assert values["unpaired_imu"] == "1" and values["received_imu"] == "5"  # at the rise
        assert [(e.kind, e.reason) for e in rig.events] == [("recovered", ""),
                                                             ("fault", "imu_stamp_gap")]
        assert len(rig.got["wrench"]) == 7
        step(0.010)
        status, values = rig.last_status()
        # No fault; WARN for the start-up warning (these joint names are not the model's
        # robot's).
        assert status.level == WARN and "joint_names" in status.message
        assert values["fault"] == "false" and len(rig.got["wrench"]) == 8
        assert rig.events[-1].kind == "recovered"
    finally:
        rig.close()
