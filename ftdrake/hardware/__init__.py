"""ftdrake on a live robot over LCM: configuration and message codecs.

Modules: ``config`` (HardwareConfig: channels, message types, timeouts), ``live_config``
(LiveConfig: a live config file, the chain and its transports), ``messages``
(decode joint state and F/T, encode the published wrenches and the contact state),
``live_inputs`` (StreamMonitor: per-message checks, fault, counters; RobotStatePairer),
``transport`` (open_lcm: an LCM connection that does not drop queued messages), ``core``
(StationCore: the message-driven loop around the runtime chain, whatever the transport),
``station`` (HardwareStation: StationCore on LCM; measure_latency),
``recording`` (LCM messages or log → the ``collect`` Parquet layout).
The simulated robot that publishes what a real one does is :mod:`ftdrake.sim.lcm_publisher`
(this package imports nothing of the simulation). The commands: ``ftdrake serve``,
``ftdrake record``, ``ftdrake simulate --lcm`` (:mod:`ftdrake.cli.hardware`). The same on
ROS 2 topics over Cyclone DDS: :mod:`ftdrake.hardware.ros2` (``--ros2``).
"""

from .config import JOINT_STATE_TYPES, HardwareConfig
from .live_config import LiveConfig, load_live_config
from .live_inputs import REASONS, RobotStatePairer, StreamMonitor
from .messages import (
    ContactState,
    JointSample,
    WrenchSample,
    decode_contact_state,
    decode_joint_state,
    decode_wrench,
    encode_contact_state,
    encode_joint_state,
    encode_wrench,
)
from .recording import read_lcm_log, record_to_parquet
from .station import FaultEvent, HardwareStation, build_hardware_station, measure_latency
from .transport import open_lcm

__all__ = [
    "JOINT_STATE_TYPES",
    "REASONS",
    "ContactState",
    "FaultEvent",
    "HardwareConfig",
    "HardwareStation",
    "JointSample",
    "LiveConfig",
    "RobotStatePairer",
    "StreamMonitor",
    "WrenchSample",
    "build_hardware_station",
    "decode_contact_state",
    "decode_joint_state",
    "decode_wrench",
    "encode_contact_state",
    "encode_joint_state",
    "encode_wrench",
    "load_live_config",
    "measure_latency",
    "open_lcm",
    "read_lcm_log",
    "record_to_parquet",
]
