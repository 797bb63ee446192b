"""Cyclone DDS as ROS 2 uses it: a participant, ROS 2 topic names and QoS, arrival-ordered
delivery.

Where traffic goes (`dds_config`, see :func:`open_participant`):

* ``"loopback"`` (the default): ftdrake creates the DDS domain with :data:`LOOPBACK_XML`, a
  Cyclone configuration that binds the loopback interface ``lo`` only, turns multicast off and
  discovers peers by unicast to 127.0.0.1 (participant indices 0..`MAX_PARTICIPANTS`-1).
  Nothing leaves the machine: tests and benchmarks use it, and so do a driver and ftdrake on
  one computer whose ROS 2 nodes are configured the same way (``CYCLONEDDS_URI`` pointing at
  the same XML: :func:`loopback_xml` writes it).
* ``"environment"``: Cyclone's own configuration: the ``CYCLONEDDS_URI`` environment
  variable if set, else Cyclone's defaults (multicast discovery on the default interface),
  as a ROS 2 node with ``RMW_IMPLEMENTATION=rmw_cyclonedds_cpp`` has.
* any other string: a Cyclone configuration, XML text or ``file:///path/cyclonedds.xml``.

The configuration is per DDS domain and per process: the first participant of a domain id
sets it; asking for a different one later in the same process raises ConfigError.

Topic and type names follow ROS 2's mapping onto DDS (ros2/design, "Topic and Service name
mapping to DDS"): the ROS topic ``/joint_states`` is the DDS topic ``rt/joint_states``, the
type ``sensor_msgs/msg/JointState`` is ``sensor_msgs::msg::dds_::JointState_``
(:mod:`.messages`). QoS profiles (:data:`QOS_PROFILES`): ``reliable`` is rclcpp's default
(reliable, volatile, keep last `depth`), ``sensor_data`` its ``SensorDataQoS`` (best effort,
keep last 5). Writers use plain CDR (XCDR1), ROS 2's encoding.

:class:`Ros2Node` delivers every message of all its subscriptions in the order they arrived,
across topics, through one queue: a DDS listener (Cyclone's receive thread) takes the samples
and stamps their arrival with the node's clock; :meth:`Ros2Node.spin` calls the handlers in the
caller's thread. So a joint state that arrived before a wrench is handled before it, as on LCM.
"""

from __future__ import annotations

import queue
import re
import threading
import time
from collections.abc import Callable

from ...errors import ConfigError
from .messages import ros2_type

#: Participant indices the loopback configuration probes for peers (one per process).
MAX_PARTICIPANTS = 20

#: Cyclone DDS configuration: the loopback interface, no multicast, unicast discovery on
#: 127.0.0.1. ``Domain Id="any"`` applies it to whichever domain id it is used for.
LOOPBACK_XML = f"""<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface name="lo"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>{MAX_PARTICIPANTS - 1}</MaxAutoParticipantIndex>
      <Peers><Peer address="127.0.0.1"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>"""

#: QoS profile names (:func:`qos`).
QOS_PROFILES = ("reliable", "sensor_data")

_domains: dict[int, tuple[str, object]] = {}  # domain id → (config, Domain kept alive)
_lock = threading.Lock()
_TOPIC = re.compile(r"^/?[A-Za-z_~][A-Za-z0-9_~]*(/[A-Za-z_][A-Za-z0-9_]*)*$")


def loopback_xml(path) -> None:
    """Writes :data:`LOOPBACK_XML` to `path`, for ``CYCLONEDDS_URI=file://path`` of other
    ROS 2 nodes that should talk to ftdrake on the loopback interface."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(LOOPBACK_XML)


def open_participant(domain_id: int = 0, dds_config: str = "loopback",
                     where: str = "ros2.dds_config"):
    """A ``DomainParticipant`` on `domain_id` (ROS_DOMAIN_ID) with `dds_config` (see the
    module)."""
    from cyclonedds.core import DDSException  # noqa: PLC0415 (cyclonedds only for ROS 2)
    from cyclonedds.domain import Domain, DomainParticipant  # noqa: PLC0415 (as above)

    config = LOOPBACK_XML if dds_config == "loopback" else dds_config
    with _lock:
        if config != "environment":
            known = _domains.get(domain_id)
            if known is None:
                try:
                    _domains[domain_id] = (config, Domain(domain_id, config))
                except DDSException as e:
                    raise ConfigError(f"{where}: Cyclone DDS rejected the configuration for "
                                      f"domain {domain_id} ({e}); give 'loopback', "
                                      "'environment', XML text or a file:// URL") from None
            elif known[0] != config:
                raise ConfigError(f"{where}: domain {domain_id} already has another Cyclone "
                                  "configuration in this process; use one per domain")
        try:
            return DomainParticipant(domain_id)
        except DDSException as e:
            raise ConfigError(f"{where}: cannot create a DDS participant on domain "
                              f"{domain_id} ({e})") from None


def dds_topic(name: str, where: str = "ros2 topic") -> str:
    """ROS 2 topic name → DDS topic name: ``/joint_states`` → ``rt/joint_states``."""
    if not (isinstance(name, str) and _TOPIC.match(name)) or "~" in name:
        raise ConfigError(f"{where}: {name!r} is not a ROS 2 topic name like "
                          "'/joint_states' (letters, digits, _ and /)")
    return "rt/" + name.lstrip("/")


def qos(profile: str, depth: int = 10, *, writer: bool = False):
    """The Cyclone QoS of a ROS 2 profile (``reliable`` or ``sensor_data``); writers add
    XCDR1 (plain CDR) as their data representation."""
    from cyclonedds.qos import Policy, Qos  # noqa: PLC0415 (cyclonedds only for ROS 2)
    from cyclonedds.util import duration  # noqa: PLC0415 (as above)

    if profile == "reliable":
        policies = [Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
                    Policy.History.KeepLast(depth)]
    elif profile == "sensor_data":
        policies = [Policy.Reliability.BestEffort, Policy.History.KeepLast(5)]
    else:
        raise ConfigError(f"QoS profile {profile!r} is not one of {', '.join(QOS_PROFILES)}")
    policies.append(Policy.Durability.Volatile)
    if writer:
        policies.append(Policy.DataRepresentation(use_cdrv0_representation=True))
    return Qos(*policies)


class Ros2Node:
    """A participant with ROS 2 publishers and subscriptions (see the module).

    `clock` stamps arrivals (s, monotonic). Handlers are ``handler(message, arrival)``.
    """

    def __init__(self, domain_id: int = 0, dds_config: str = "loopback", *,
                 clock: Callable[[], float] = time.monotonic, where: str = "ros2.dds_config"):
        self.participant = None
        self.participant = open_participant(domain_id, dds_config, where)
        self.clock = clock
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._topics: dict[str, object] = {}
        self._readers, self._writers, self._listeners = [], [], []

    def _topic(self, name: str, msgtype: str):
        from cyclonedds.topic import Topic  # noqa: PLC0415 (cyclonedds only for ROS 2)

        dds_name = dds_topic(name)
        if dds_name not in self._topics:
            self._topics[dds_name] = Topic(self.participant, dds_name, ros2_type(msgtype))
        return self._topics[dds_name]

    def publisher(self, topic: str, msgtype: str, profile: str = "reliable", depth: int = 10):
        """A DataWriter of `msgtype` on the ROS 2 `topic`; ``.write(message)`` publishes."""
        from cyclonedds.pub import DataWriter  # noqa: PLC0415 (cyclonedds only for ROS 2)

        writer = DataWriter(self.participant, self._topic(topic, msgtype),
                            qos(profile, depth, writer=True))
        self._writers.append(writer)
        return writer

    def subscribe(self, topic: str, msgtype: str, handler, profile: str = "reliable",
                  depth: int = 100) -> None:
        """Calls ``handler(message, arrival)`` from :meth:`spin` for each message."""
        from cyclonedds.core import Listener  # noqa: PLC0415 (cyclonedds only for ROS 2)
        from cyclonedds.sub import DataReader  # noqa: PLC0415 (as above)

        kind = ros2_type(msgtype)
        put, clock = self._queue.put, self.clock

        def on_data_available(reader) -> None:
            samples = reader.take(N=depth)
            arrival = clock()
            for sample in samples:
                if isinstance(sample, kind):  # not an InvalidSample (a writer went away)
                    put((handler, sample, arrival))

        listener = Listener(on_data_available=on_data_available)
        reader = DataReader(self.participant, self._topic(topic, msgtype), qos(profile, depth),
                            listener)
        self._readers.append(reader)
        self._listeners.append(listener)

    def spin(self, timeout_ms: float = 0) -> int:
        """Handles every queued message in arrival order, waiting up to `timeout_ms` for the
        first one. Returns how many were handled."""
        handled = 0
        try:
            item = self._queue.get(timeout=timeout_ms / 1e3) if timeout_ms > 0 else \
                self._queue.get_nowait()
        except queue.Empty:
            return 0
        while True:
            handler, sample, arrival = item
            handler(sample, arrival)
            handled += 1
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return handled

    def matched(self) -> dict[str, int]:
        """Matched remote endpoints per DDS topic: writers' readers and readers' writers."""
        counts = {}
        for entity in (*self._readers, *self._writers):
            status = (entity.get_subscription_matched_status() if entity in self._readers
                      else entity.get_publication_matched_status())
            name = entity.topic.name if hasattr(entity, "topic") else "?"
            counts[name] = counts.get(name, 0) + status.current_count
        return counts

    def close(self) -> None:
        """Deletes the participant and with it its readers, writers and topics (Cyclone waits
        for a running listener). Before the Python objects go: a reader outliving its
        listener's Python callbacks would call freed memory."""
        if self.participant is None:
            return
        self.participant.__del__()  # Entity's own deletion (dds_delete); idempotent after
        self.participant = None
        self._readers.clear()
        self._writers.clear()
        self._topics.clear()
        self._listeners.clear()

    def __del__(self) -> None:
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
