"""ROS 2 topics → the table layout ``collect`` writes (Parquet), for train/evaluate.

:class:`Ros2Recorder` subscribes to a :class:`~ftdrake.hardware.ros2.config.Ros2Config`'s
JointState and WrenchStamped topics and keeps their samples (header stamps, s): the joint
states reordered by name into ``joint_names``, other joints a message carries ignored (a
gripper's, another arm's; as the station reads them). A message missing one of them, or
naming one twice, is not used, counted as ``joint_names``; one without velocities as
``joint_count``. :meth:`Ros2Recorder.table` pairs them as
:func:`~ftdrake.hardware.recording.table_from_samples` does for LCM: one row per wrench, with
the latest joint state at or before its stamp within the tolerance.

A recorded ROS 2 bag (``ros2 bag record``, sqlite3 or MCAP) needs no recorder: ``train`` and
``evaluate`` read it directly (:func:`ftdrake.data.bag.read_bag`).
"""

from __future__ import annotations

import collections

import numpy as np

from .config import Ros2Config
from .dds import Ros2Node
from .messages import from_stamp, wrench_of


class Ros2Recorder:
    """Collects joint-state and wrench samples from ROS 2 topics (see the module)."""

    def __init__(self, config: Ros2Config, node: Ros2Node | None = None):
        self.config = config.validate()
        self.node = node if node is not None else Ros2Node(config.domain_id, config.dds_config)
        self.joints: list[np.ndarray] = []
        self.wrenches: list[np.ndarray] = []
        self.rejected = collections.Counter()
        self._index = {name: k for k, name in enumerate(config.joint_names)}
        self.node.subscribe(config.joint_state_topic, "sensor_msgs/msg/JointState",
                            self._on_joint, config.joint_state_qos, config.queue_depth)
        self.node.subscribe(config.wrench_topic, "geometry_msgs/msg/WrenchStamped",
                            self._on_wrench, config.wrench_qos, config.queue_depth)

    def _on_joint(self, msg, _arrival) -> None:
        names = list(msg.name)
        if any(names.count(n) != 1 for n in self.config.joint_names):  # missing or twice
            self.rejected["joint_names"] += 1
            return
        if len(msg.position) != len(names) or len(msg.velocity) != len(names):
            self.rejected["joint_count"] += 1
            return
        order = [names.index(n) for n in self.config.joint_names]
        q, v = np.asarray(msg.position, float), np.asarray(msg.velocity, float)
        self.joints.append(np.r_[from_stamp(msg.header.stamp), q[order], v[order]])

    def _on_wrench(self, msg, _arrival) -> None:
        self.wrenches.append(np.r_[from_stamp(msg.header.stamp), wrench_of(msg)])

    def spin(self, timeout_ms: float = 10) -> int:
        """Handles what arrived (waiting up to `timeout_ms`); returns how many."""
        return self.node.spin(timeout_ms)

    def table(self, tolerance_s: float = 0.002):
        """(table, report) in the ``collect`` layout (see the module)."""
        from ..recording import table_from_samples  # noqa: PLC0415 (pandas only here)

        c = self.config
        return table_from_samples(self.joints, self.wrenches, c.n_joints, tolerance_s,
                                  source=f"ROS 2 {c.joint_state_topic}, {c.wrench_topic}",
                                  names=(c.wrench_topic, c.joint_state_topic),
                                  **{k: int(v) for k, v in self.rejected.items()})

    def close(self) -> None:
        self.node.close()
