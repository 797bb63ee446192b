"""``batch_period_s`` (lcm: and ros2:): seconds in [0, max_backlog_s / 2); anything else is
a ConfigError naming the key."""

import pytest

from ftdrake import ConfigError
from ftdrake.hardware import HardwareConfig


@pytest.mark.parametrize("value", [-0.001, 0.25, float("nan"), "2 ms"])
def test_a_batch_period_outside_its_range_names_the_key(value):
    with pytest.raises(ConfigError, match=r"^lcm\.batch_period_s: seconds in \[0, "):
        HardwareConfig(batch_period_s=value).validate("lcm")
    pytest.importorskip("cyclonedds")
    from ftdrake.hardware.ros2.config import Ros2Config

    with pytest.raises(ConfigError, match=r"^ros2\.batch_period_s: "):
        Ros2Config(joint_names=["a"], batch_period_s=value).validate()


def test_a_batch_period_inside_it_is_kept():
    assert HardwareConfig(batch_period_s=0.002).validate().batch_period_s == 0.002
