"""Ros2Config: the ROS 2 topics, QoS, joint names and timeouts of a live robot.

Loadable with ``pydrake.common.yaml.yaml_load_typed(schema=Ros2Config, ...)``
(``ftdrake serve --ros2 --ros2-config FILE``); call ``validate()`` after loading (errors name
the field, as ``ros2.<field>: ...``).
"""

# No `from __future__ import annotations`: yaml_load_typed reads the field types.
import dataclasses as dc
import math

from ...conventions import OUTPUTS as CHAIN_OUTPUTS_BY_PORT
from ...conventions import PUBLISHED, ROS2_TYPES
from ...errors import ConfigError
from ..config import (
    check_batch_period,
    check_compiled_path,
    check_cpu_affinity,
    check_outputs,
    check_yield_io_threads,
)
from .dds import QOS_PROFILES, dds_topic

#: Output topics under `output_namespace` and their ROS 2 types: the chain outputs
#: :data:`ftdrake.conventions.PUBLISHED` that have a topic of their own (the others,
#: ``fault``, ``out_of_domain`` and ``payload_change``, are keys of the diagnostics), named as
#: the ports: ``wrench_compensated``, ``wrench_contact``, ``contact``, ``contact_force``,
#: ``bias``, ``payload``.
OUTPUTS = {port: ROS2_TYPES[port] for port in PUBLISHED
           if not CHAIN_OUTPUTS_BY_PORT[port].ros2.startswith("/")}


@dc.dataclass
class Ros2Config:
    """Where a ROS 2 robot's streams are, what ftdrake publishes, how stale inputs may get.

    Inputs (the driver's topics):
      `joint_state_topic`: ``sensor_msgs/msg/JointState`` (position rad, velocity rad/s, by
        name). `joint_names` are the model's joints in the model's order: each message is
        reordered by name into it; a message missing one of them, or naming one twice, is
        faulted as ``joint_names`` with the names in the detail. Joints a message carries
        beyond them (another arm's, a gripper's, as a robot's ``/joint_states`` holds them)
        are ignored, said once as a warning. Velocities are required.
      `wrench_topic`: ``geometry_msgs/msg/WrenchStamped`` (N, N·m) in the sensor frame, as
        ``force_torque_sensor_broadcaster`` publishes it; each message runs the chain once.
      `wrench_frame_id`: the sensor frame the model compensates readings in (the
        broadcaster's ``frame_id``); a wrench with another ``header.frame_id`` faults the
        inputs (``frame_id``, naming both). "" (the default) accepts any.
      `temperature_topic` (only for a model trained with the sensor temperature):
        ``sensor_msgs/msg/Temperature`` (°C).
      `imu_topic` (only for a model that takes an IMU at the sensor): ``sensor_msgs/msg/Imu``
        (proper acceleration m/s², angular velocity rad/s, axes along S), each wrench paired
        with the message stamped nearest to it within `imu_max_skew_s` (s); none: a fault.
      `tare_topic`, `payload_topic` (optional, for ``chain.bias_tracker``):
        ``std_msgs/msg/Empty``: the sensor was re-zeroed / a payload was grasped or let go.
      `*_qos`: ``reliable`` (rclcpp's default; what ros2_control's broadcasters offer) or
        ``sensor_data`` (best effort, keep last 5: matches a best-effort or a reliable
        publisher, may drop messages).
      Message stamps (``header.stamp``) are the samples' times: they must increase.
    Outputs, under `output_namespace` (see :data:`OUTPUTS`; the LCM station publishes the
      same outputs under the same names): ``wrench_contact`` the contact wrench the detector
      judges (measured − predicted − the tracker's bias and payload) and
      ``wrench_compensated`` (measured − predicted), both with the input's ``frame_id`` and
      stamp, only while the inputs are fault-free; ``contact`` (Bool) and
      ``contact_force`` (Float64, ‖F‖ N while in contact, else 0), ``bias``
      (WrenchStamped, with the tracker) and ``payload`` (InertiaStamped with ``m`` = Δm kg,
      ``com`` = Δ(m·c)/Δm m in the sensor frame (zero while |Δm| < 1 g), moments zero: not
      estimated; with ``track_payload``) with each published wrench, so never under a fault
      (these types carry no fault flag); and on `diagnostics_topic`
      a ``diagnostic_msgs/msg/DiagnosticArray`` every `diagnostics_period_s` and at each fault
      change (level OK / WARN out of domain / ERROR fault; keys fault, reason, out_of_domain,
      payload_change, message rates, counts).
    `outputs`: the outputs published (default: all of them; ``fault``, ``out_of_domain``
      and ``payload_change`` are keys of the diagnostics, always published): each topic
      costs a serialisation and a DDS write per F/T sample (most of the station's CPU per
      message on a small machine, docs/results/live.md), so list only those read.
    `batch_period_s`: serve's loop wakes at most once per this many s and then handles
      every message that arrived: fewer wake-ups, less CPU per message, up to that much more
      latency; 0 (default) wakes for each message.
    `yield_io_threads`: Cyclone DDS's threads, started with the station's participant, run
      under ``SCHED_BATCH`` (:mod:`ftdrake.hardware.threads`): a receive thread does not
      preempt the chain's thread mid-sample; false keeps the default policy. The first
      participant in a process starts them; a station made on a node the caller opened
      changes none.
    `cpu_affinity`: CPUs the whole process (every thread) is kept on
      (:func:`ftdrake.hardware.threads.pin_process`): the chain's data stays in those cores'
      caches between messages; [] (default) leaves it to the scheduler.
    `queue_depth`: samples a subscription (and each of ftdrake's writers) keeps while the
      station lags (1 s at 1 kHz); a lag beyond it loses the oldest.
    `max_backlog_s`: behind the wrench stream by more than this (s), the station drops the
      oldest wrenches (not run through the chain) until it has caught up, faulting the inputs
      as ``overload`` with the input rate and the rate it sustains
      (:mod:`ftdrake.hardware.overload`); the diagnostics carry ``lost_ft``, ``dropped_ft``,
      ``backlog_ms`` and ``sustained_hz``.
    `pair_tolerance_s`: each wrench is paired with the joint state whose ``header.stamp`` is
      within this (s) of its own: the newest when it is, else the nearest of the last 64; an
      older one is brought forward to the wrench's stamp
      (:func:`~ftdrake.hardware.live_inputs.joint_state_at`);
      none within it faults the inputs (``stamp_gap``) and the wrench is not judged. At least
      the joint-state period. 0 pairs by arrival only (the newest joint state, as it is).
    `reorder_window_s`: 0 hands messages to the station as they arrive (lowest latency, as
      on LCM); > 0 holds them that long and hands them over in publication order, so a joint
      state retransmitted after a lost datagram still precedes the wrench published after it
      (DDS keeps each topic in order, not the two topics together); adds that much latency.
    `compiled_path`: the per-message work (take, checks, chain update, publish) runs in one
      compiled loop whenever the station is in its ordinary state, and in Python otherwise,
      with the same results (:mod:`ftdrake.hardware.ros2.fast`); false: always in Python.
      Used only where it applies (the summary's ``compiled_path`` says whether and why
      not). Found in numba's cache it is loaded before the station serves; else it is
      compiled in a process of its own while the Python path serves (a first start after
      an install), then loaded.
    DDS: `domain_id` is ROS_DOMAIN_ID; `dds_config` is ``loopback`` (this machine only),
      ``environment`` (CYCLONEDDS_URI or Cyclone's defaults, as a ROS 2 node has) or a
      Cyclone XML / ``file://`` URL (:mod:`ftdrake.hardware.ros2.dds`).
    """

    joint_names: list[str] = dc.field(default_factory=list)
    joint_state_topic: str = "/joint_states"
    joint_state_qos: str = "reliable"
    wrench_topic: str = "/force_torque_sensor_broadcaster/wrench"
    wrench_qos: str = "reliable"
    wrench_frame_id: str = ""
    temperature_topic: str = ""
    temperature_timeout_s: float = 1.0
    # A model that takes an IMU at the sensor: its sensor_msgs/msg/Imu topic (linear
    # acceleration: proper acceleration, m/s², REP 145; angular velocity, rad/s; both in S),
    # each wrench paired with the IMU message stamped nearest to it within imu_max_skew_s.
    # "" (off) unless the model needs it.
    imu_topic: str = ""
    imu_max_skew_s: float = 0.002
    tare_topic: str = ""
    payload_topic: str = ""
    output_namespace: str = "/ftdrake"
    diagnostics_topic: str = "/diagnostics"
    diagnostics_period_s: float = 1.0
    sensor_timeout_s: float = 0.005
    joint_state_timeout_s: float = 0.02
    outputs: list[str] = dc.field(default_factory=lambda: list(PUBLISHED))
    queue_depth: int = 1000
    max_backlog_s: float = 0.5
    batch_period_s: float = 0.0
    yield_io_threads: bool = True
    cpu_affinity: list[int] = dc.field(default_factory=list)
    pair_tolerance_s: float = 0.005
    reorder_window_s: float = 0.0
    compiled_path: bool = True
    domain_id: int = 0
    dds_config: str = "loopback"

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def output_topic(self, name: str) -> str:
        """The ROS 2 topic of output `name` (a key of :data:`OUTPUTS`)."""
        return self.output_namespace.rstrip("/") + "/" + name

    def validate(self, where: str = "ros2") -> "Ros2Config":
        """Checks every field; ConfigError names the first wrong one (`where` is its path)."""
        self._check_joint_names(where)
        self._check_topics(where)
        self._check_numbers(where)
        check_outputs(self.outputs, f"{where}.outputs")
        check_batch_period(self.batch_period_s, self.max_backlog_s, where)
        check_yield_io_threads(self.yield_io_threads, where)
        check_compiled_path(self.compiled_path, where)
        check_cpu_affinity(self.cpu_affinity, where)
        if not isinstance(self.wrench_frame_id, str):
            raise ConfigError(f"{where}.wrench_frame_id: the sensor frame's name (a string; "
                              f"'' accepts any), got {self.wrench_frame_id!r}")
        if not (isinstance(self.dds_config, str) and self.dds_config):
            raise ConfigError(f"{where}.dds_config: 'loopback', 'environment', Cyclone XML "
                              "or a file:// URL")
        return self

    def _check_joint_names(self, where: str) -> None:
        names = self.joint_names
        if not (isinstance(names, list) and names and all(isinstance(n, str) and n
                                                          for n in names)):
            raise ConfigError(f"{where}.joint_names: list the model's joints in the model's "
                              "order, e.g. a UR's [shoulder_pan_joint, shoulder_lift_joint, "
                              "elbow_joint, wrist_1_joint, wrist_2_joint, wrist_3_joint]")
        if len(set(names)) != len(names):
            raise ConfigError(f"{where}.joint_names: {names} names a joint twice")

    def _check_topics(self, where: str) -> None:
        optional = [f for f in ("temperature_topic", "tare_topic", "payload_topic",
                                "imu_topic") if getattr(self, f)]
        topics = {field: getattr(self, field) for field in (
            "joint_state_topic", "wrench_topic", "diagnostics_topic", *optional)}
        for name in OUTPUTS:
            topics[f"output_namespace ({name})"] = self.output_topic(name)
        seen = {}
        for field, topic in topics.items():
            dds_topic(topic, f"{where}.{field.split(' ')[0]}")
            if topic in seen:
                raise ConfigError(f"{where}.{field}: topic {topic!r} is also {where}."
                                  f"{seen[topic]}")
            seen[topic] = field
        for field in ("joint_state_qos", "wrench_qos"):
            if getattr(self, field) not in QOS_PROFILES:
                raise ConfigError(f"{where}.{field}: {getattr(self, field)!r} is not one of "
                                  f"{', '.join(QOS_PROFILES)}")

    def _check_numbers(self, where: str) -> None:
        for field in ("sensor_timeout_s", "joint_state_timeout_s", "temperature_timeout_s",
                      "diagnostics_period_s", "max_backlog_s", "imu_max_skew_s"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and value > 0 and math.isfinite(value)):
                raise ConfigError(f"{where}.{field}: must be a positive number of seconds, "
                                  f"got {value!r}")
        if not (isinstance(self.reorder_window_s, (int, float)) and
                0 <= self.reorder_window_s < 1):
            raise ConfigError(f"{where}.reorder_window_s: seconds in [0, 1), got "
                              f"{self.reorder_window_s!r}")
        if not (isinstance(self.pair_tolerance_s, (int, float)) and self.pair_tolerance_s >= 0
                and math.isfinite(self.pair_tolerance_s)):
            raise ConfigError(f"{where}.pair_tolerance_s: seconds ≥ 0 (0: pair by arrival), "
                              f"got {self.pair_tolerance_s!r}")
        if not (isinstance(self.queue_depth, int) and self.queue_depth >= 1):
            raise ConfigError(f"{where}.queue_depth: must be a positive integer, got "
                              f"{self.queue_depth!r}")
        if not (isinstance(self.domain_id, int) and 0 <= self.domain_id <= 232):
            raise ConfigError(f"{where}.domain_id: a ROS_DOMAIN_ID in 0..232, got "
                              f"{self.domain_id!r}")
