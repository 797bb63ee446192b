"""A simulated robot on ROS 2: the simulation publishes what a ros2_control driver publishes.

:func:`simulate_on_ros2` runs a built :class:`~ftdrake.sim.station.Station` like
:func:`ftdrake.sim.simulate.simulate` (same initial state, events and log) and publishes, at
every sensor sample time t_j = j·period, on the topics of a
:class:`~ftdrake.hardware.ros2.config.Ros2Config` (Cyclone DDS, :mod:`ftdrake.hardware.ros2.dds`):

* ``sensor_msgs/msg/JointState`` on ``joint_state_topic``, stamped t_j: the arm's joints by
  name with position and velocity x(t_j) (no efforts), the names in alphabetical order, as
  some drivers send them (the station reorders by name: the model's order is never assumed);
* then ``geometry_msgs/msg/WrenchStamped`` on ``wrench_topic``, stamped t_{j-1}, frame
  `frame_id`: the sensor's reading of the previous sample, w(t_{j-1}), as
  ``force_torque_sensor_broadcaster`` would with one sample of transport latency;
* ``sensor_msgs/msg/Temperature`` (with ``temperature_topic``) stamped t_j, and
  ``std_msgs/msg/Empty`` on ``tare_topic`` / ``payload_topic`` once when the simulated re-tare
  or grasp starts.

The timing, and why the reading lags, are those of :mod:`ftdrake.sim.lcm_publisher`: a
:class:`~ftdrake.hardware.ros2.station.Ros2Station` on these topics publishes for the F/T
message stamped t_k the simulation's ``wrench_contact_*`` of the log row at t_{k+1} (its contact
the row's ``contact``). A run of K samples publishes K + 1 joint states and K wrenches.
``realtime_rate`` = 1 paces the simulation to the wall clock. Writers are reliable with
``config.queue_depth`` samples of history (what a slow subscriber may lag before losing one).
"""

from __future__ import annotations

import time

from ..errors import ConfigError
from ..hardware.ros2.config import Ros2Config
from ..hardware.ros2.dds import Ros2Node
from ..hardware.ros2.messages import header, ros2_type, wrench_stamped
from .sampled_publisher import SampledPublisher, simulate_publishing
from .simulate import SimResult


def arm_joint_names(station) -> list[str]:
    """The simulated arm's joint names in the plant's position order (the model's order)."""
    plant, arm = station.scene.plant, station.scene.arm
    joints = [plant.get_joint(j) for j in plant.GetJointIndices(arm)]
    joints = sorted((j for j in joints if j.num_positions() > 0), key=lambda j: j.position_start())
    return [j.name() for j in joints]


class _Publisher(SampledPublisher):
    """Per sample, the joint state, then the previous sample's reading, as ROS 2 messages."""

    def __init__(self, station, config: Ros2Config, node: Ros2Node, frame_id: str):
        events = [name for name, topic in (("tare", config.tare_topic),
                                           ("payload", config.payload_topic)) if topic]
        super().__init__(station, config.n_joints, "ros2.joint_names (their count)",
                         temperature=bool(config.temperature_topic), events=events)
        names = arm_joint_names(station)
        if names != list(config.joint_names):
            raise ConfigError(f"ros2.joint_names: {config.joint_names}, but the simulated arm's "
                              f"joints are {names} (in the model's order)")
        self.frame_id = frame_id
        order = sorted(range(self.n), key=lambda k: names[k])
        self._order, self._names = order, [names[k] for k in order]
        depth = config.queue_depth
        self._joint = node.publisher(config.joint_state_topic, "sensor_msgs/msg/JointState",
                                     depth=depth)
        self._wrench = node.publisher(config.wrench_topic, "geometry_msgs/msg/WrenchStamped",
                                      depth=depth)
        self._types = {"joint": ros2_type("sensor_msgs/msg/JointState"),
                       "temperature": ros2_type("sensor_msgs/msg/Temperature"),
                       "empty": ros2_type("std_msgs/msg/Empty")}
        if config.temperature_topic:
            self._temperature_writer = node.publisher(
                config.temperature_topic, "sensor_msgs/msg/Temperature", depth=depth)
        self._event_writers = {name: node.publisher(topic, "std_msgs/msg/Empty", depth=depth)
                               for name, topic in (("tare", config.tare_topic),
                                                   ("payload", config.payload_topic)) if topic}

    def send_joint(self, t, q, v) -> None:
        self._joint.write(self._types["joint"](
            header=header(t), name=self._names, position=[float(q[k]) for k in self._order],
            velocity=[float(v[k]) for k in self._order], effort=[]))

    def send_wrench(self, t, w) -> None:
        self._wrench.write(wrench_stamped(header(t, self.frame_id), w))

    def send_temperature(self, t, celsius) -> None:
        self._temperature_writer.write(self._types["temperature"](
            header=header(t, self.frame_id), temperature=float(celsius), variance=0.0))

    def send_event(self, name, t) -> None:
        del t  # std_msgs/Empty carries no stamp: it arrives before the sample it marks
        self._event_writers[name].write(self._types["empty"](
            structure_needs_at_least_one_member=0))


def wait_for_subscribers(node: Ros2Node, timeout_s: float, settle_s: float = 0.25) -> bool:
    """Waits up to `timeout_s` for every writer of `node` to have a subscriber and the matched
    counts to stay unchanged for `settle_s` (DDS discovery takes a moment, and a message
    written before it reaches nobody); returns whether every writer had one."""
    end = time.monotonic() + timeout_s
    last, since = None, time.monotonic()
    while time.monotonic() < end:
        matched = node.matched()
        if matched != last:
            last, since = matched, time.monotonic()
        elif all(matched.values()) and time.monotonic() - since >= settle_s:
            return True
        time.sleep(0.01)
    return bool(last) and all(last.values())


def simulate_on_ros2(station, config: Ros2Config, node: Ros2Node | None = None, *,
                     realtime_rate: float = 0.0, duration: float | None = None,
                     progress: bool = True, frame_id: str = "ft_sensor",
                     wait_for_subscriber_s: float = 0.0) -> SimResult:
    """Simulates `station` and publishes its joint state and sensor reading per sample on ROS 2
    (`node`, default one on ``config.domain_id`` with ``config.dds_config``). With
    `wait_for_subscriber_s`, waits up to that long for a subscriber on every topic first (a
    message written before discovery reaches nobody). Returns simulate()'s SimResult; its
    ``timing`` also holds ``published`` = {"joint": K + 1, "ft": K} for K samples."""
    config.validate()
    own = node is None
    node = Ros2Node(config.domain_id, config.dds_config) if own else node
    try:
        publisher = _Publisher(station, config, node, frame_id)
        if wait_for_subscriber_s > 0:
            wait_for_subscribers(node, wait_for_subscriber_s)
        result = simulate_publishing(station, publisher, realtime_rate=realtime_rate,
                                     duration=duration, progress=progress)
        # Reliable writers resend what a subscriber missed; let them before leaving.
        node.wait_for_acks(1.0)
        return result
    finally:
        if own:
            node.close()
