"""ftdrake on a ROS 2 robot, over Cyclone DDS, without a ROS installation.

Modules: ``messages`` (ROS 2 message types as Cyclone ``IdlStruct`` classes, generated from
rosbags' copy of ROS 2's definitions), ``dds`` (the participant, loopback configuration, ROS 2
topic names and QoS, arrival-ordered delivery), ``config`` (Ros2Config: topics, joint names,
QoS, timeouts), ``station`` (Ros2Station: the runtime chain on the driver's topics; shares
:class:`~ftdrake.hardware.core.StationCore` with the LCM station), ``recording`` (live
messages → the ``collect`` Parquet layout). The simulated robot on ROS 2 is
:mod:`ftdrake.sim.ros2_publisher`. Needs the ``cyclonedds`` package (``ftdrake[ros2]``).
"""

from .config import OUTPUTS, Ros2Config

__all__ = ["OUTPUTS", "Ros2Config"]
