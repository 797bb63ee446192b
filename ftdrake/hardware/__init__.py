"""ftdrake on a live robot over LCM (issue 11): configuration and message codecs.

Modules: ``config`` (HardwareConfig: channels, message types, timeouts), ``messages``
(decode joint state and F/T, encode the external wrench and the contact state),
``live_inputs`` (StreamMonitor: per-message checks, fault, counters), ``station``
(build_hardware_station: a message-driven loop around the unchanged CompensatorSystem and
ContactDetector; measure_latency), ``recording`` (LCM log → the ``collect`` Parquet layout).
"""

from .config import JOINT_STATE_TYPES, HardwareConfig
from .live_inputs import REASONS, StreamMonitor
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
from .station import HardwareStation, build_hardware_station, measure_latency

__all__ = [
    "JOINT_STATE_TYPES",
    "REASONS",
    "ContactState",
    "HardwareConfig",
    "HardwareStation",
    "JointSample",
    "StreamMonitor",
    "WrenchSample",
    "build_hardware_station",
    "decode_contact_state",
    "decode_joint_state",
    "decode_wrench",
    "encode_contact_state",
    "encode_joint_state",
    "encode_wrench",
    "measure_latency",
    "read_lcm_log",
    "record_to_parquet",
]
