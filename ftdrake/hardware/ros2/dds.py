"""Cyclone DDS as ROS 2 uses it: a participant, ROS 2 topic names and QoS, arrival-ordered
delivery.

Where traffic goes (`dds_config`, see :func:`open_participant`):

* ``"loopback"`` (the default): ftdrake creates the DDS domain with :data:`LOOPBACK_XML`, a
  Cyclone configuration that binds the loopback interface ``lo`` only, turns multicast off and
  discovers peers by unicast to 127.0.0.1 (participant indices 0..`MAX_PARTICIPANTS`-1),
  and asks for 4 MB socket receive buffers (the kernel caps them at ``net.core.rmem_max``),
  so that a receiver descheduled for a while loses fewer datagrams to retransmit.
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
(reliable, volatile, keep last `depth`; what ros2_control's broadcasters publish with,
``SystemDefaultsQoS``), ``sensor_data`` its ``SensorDataQoS`` (best effort, keep last 5 for a
writer). A reader keeps `depth` samples in either profile: its history is its own (QoS
matching does not look at it), and keep-last-5 would lose samples at 1 kHz whenever a spin
comes more than 5 ms after the last. Writers use plain CDR (XCDR1), ROS 2's encoding.

:class:`Ros2Node` delivers the messages of all its subscriptions in the order they were
published, across topics: :meth:`Ros2Node.spin` waits on a DDS WaitSet (without holding
Python's GIL), takes every sample of every reader and hands them to the handlers sorted by
their DDS source timestamps (the writer's clock; one clock for all the topics of one driver
process), each stamped with the node's clock as it is handled, as LCM's ``handle`` does. So a
joint state published before a wrench is handled before it when both have arrived; with a
reorder window also when the joint state was delivered up to that long after the wrench.
"""

from __future__ import annotations

import re
import struct
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
    <Internal>
      <SocketReceiveBufferSize min="default" max="4MB"/>
    </Internal>
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
        policies = [Policy.Reliability.BestEffort,
                    Policy.History.KeepLast(5 if writer else depth)]
    else:
        raise ConfigError(f"QoS profile {profile!r} is not one of {', '.join(QOS_PROFILES)}")
    policies.append(Policy.Durability.Volatile)
    if writer:
        policies.append(Policy.DataRepresentation(use_cdrv0_representation=True))
    return Qos(*policies)


class Ros2Node:
    """A participant with ROS 2 publishers and subscriptions (see the module).

    `clock` stamps arrivals (s, monotonic) as messages are handled. Handlers are
    ``handler(message, arrival)``. `reorder_window_s` > 0 holds each message that long before
    handing it over, so that one published earlier on another topic but delivered later
    (retransmitted after a lost datagram: DDS orders each writer's messages, not messages of
    different topics) still goes first; it adds that much latency.
    """

    def __init__(self, domain_id: int = 0, dds_config: str = "loopback", *,
                 clock: Callable[[], float] = time.monotonic, reorder_window_s: float = 0.0,
                 where: str = "ros2.dds_config"):
        self.participant = None
        self.participant = open_participant(domain_id, dds_config, where)
        from cyclonedds._clayer import ddspy_take  # noqa: PLC0415 (cyclonedds only for ROS 2)
        from cyclonedds.core import (  # noqa: PLC0415 (as above)
            InstanceState,
            SampleState,
            ViewState,
            WaitSet,
        )

        # What _take_bytes calls per reader and wake-up, looked up once.
        self._ddspy_take = ddspy_take
        self._any_sample = SampleState.Any | ViewState.Any | InstanceState.Any

        self.clock = clock
        self.reorder_window_s = float(reorder_window_s)
        self._pending: list = []
        self._taken = 0
        self._waitset = WaitSet(self.participant)
        self._topics: dict[str, object] = {}
        self._readers, self._writers, self._conditions, self._handlers = [], [], [], []
        self._builtin: list = []

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
                  depth: int = 100, read=None) -> None:
        """Calls ``handler(message, arrival)`` from :meth:`spin` for each message. `read`:
        a function of the message's CDR bytes returning it (a view with the fields the
        handler reads, None to leave it to cyclonedds' deserialiser; ros2/cdr.py), to
        spare cyclonedds' Python deserialiser."""
        from cyclonedds.core import (  # noqa: PLC0415 (cyclonedds only for ROS 2)
            InstanceState,
            ReadCondition,
            SampleState,
            ViewState,
        )
        from cyclonedds.sub import DataReader  # noqa: PLC0415 (cyclonedds only for ROS 2)

        reader = DataReader(self.participant, self._topic(topic, msgtype), qos(profile, depth))
        condition = ReadCondition(reader, SampleState.Any | ViewState.Any | InstanceState.Any)
        self._waitset.attach(condition)
        self._readers.append(reader)
        self._conditions.append(condition)
        self._handlers.append((reader, ros2_type(msgtype), handler, depth, read))

    def _take(self) -> None:
        """Moves every sample waiting in a reader to the pending list, as
        (source timestamp, order taken, handler, message, taken at)."""
        now = time.monotonic()
        for reader, kind, handler, depth, read in self._handlers:
            if read is not None:
                self._take_bytes(reader, kind, handler, depth, read, now)
                continue
            while samples := reader.take(N=depth):
                for sample in samples:
                    if isinstance(sample, kind):  # not an InvalidSample (a writer went away)
                        self._taken += 1
                        self._pending.append((sample.sample_info.source_timestamp,
                                              self._taken, handler, sample, now))

    def _take_bytes(self, reader, kind, handler, depth, read, now) -> None:
        """_take for a reader whose messages `read` reads from their bytes. A take of fewer
        than `depth` samples emptied the reader: no second call to find it empty (what
        arrives meanwhile, _complete's second pass or the next wake-up takes)."""
        take, mask = self._ddspy_take, self._any_sample
        while items := take(reader._ref, mask, depth):
            if isinstance(items, int):
                from cyclonedds.core import DDSException  # noqa: PLC0415 (as above)

                raise DDSException(items, f"Occurred while taking data in {reader!r}")
            for data, info in items:
                if info.valid_data:  # not: a writer went away
                    self.hold(info.source_timestamp, data, kind, handler, read, now)
            if len(items) < depth:
                break

    def hold(self, stamp: int, data: bytes, kind, handler, read, now: float) -> None:
        """A sample's CDR bytes `data` (source timestamp `stamp`, ns), read by `read` (else,
        or when it cannot, by cyclonedds' deserialiser `kind.deserialize`), held for
        `handler` in publication order, as taken at `now` (what :meth:`spin` hands over;
        the compiled path gives back the samples it leaves this way)."""
        try:
            sample = read(data) if read is not None else None
        except (struct.error, UnicodeDecodeError):
            sample = None
        if sample is None:
            sample = kind.deserialize(data)
        self._taken += 1
        self._pending.append((stamp, self._taken, handler, sample, now))

    def _due(self, limit) -> list:
        """The pending messages to hand over now, in publication order: those published no
        later than `limit` (source timestamp) and, with a reorder window, no later than the
        newest one held for the window."""
        if limit is None:
            return []
        if self.reorder_window_s > 0:
            held_until = time.monotonic() - self.reorder_window_s
            ripe = [item[0] for item in self._pending if item[4] <= held_until]
            if not ripe:
                return []
            limit = min(limit, max(ripe))
        due = sorted(item for item in self._pending if item[0] <= limit)
        self._pending = [item for item in self._pending if item[0] > limit]
        return due

    def _complete(self):
        """Takes twice; returns the newest source timestamp up to which every message is in
        hand (None: nothing pending). Why twice: readers are taken one after the other, so a
        joint state delivered just before a wrench can be missed by the pass that takes the
        wrench; a message published before one taken in the first pass was delivered before
        it (one sender's datagrams arrive in order), so the second pass takes it."""
        self._take()
        limit = max((item[0] for item in self._pending), default=None)
        self._take()
        return limit

    def spin(self, timeout_ms: float = 0) -> int:
        """Handles the waiting messages in publication order (see the module), waiting up
        to `timeout_ms` for one. Returns how many were handled."""
        due = self._due(self._complete())
        if not due and timeout_ms > 0:
            wait_s = timeout_ms / 1e3
            if self._pending and self.reorder_window_s > 0:  # until the oldest held is due
                oldest = min(item[4] for item in self._pending)
                wait_s = min(wait_s, max(0.0, oldest + self.reorder_window_s
                                         - time.monotonic()))
            if wait_s > 0 and not (self._pending and self.reorder_window_s <= 0):
                self._waitset.wait(int(wait_s * 1e9))
            due = self._due(self._complete())
        for _, _, handler, sample, _ in due:
            handler(sample, self.clock())
        return len(due)

    def publications(self):
        """A function returning the (DDS topic, DDS type name) of every publication DDS
        discovery knows now (other participants' writers, this node's too), e.g.
        ``("rt/joint_states", "sensor_msgs::msg::dds_::JointState_")``."""
        from cyclonedds.builtin import (  # noqa: PLC0415 (cyclonedds only for ROS 2)
            BuiltinDataReader,
            BuiltinTopicDcpsPublication,
        )
        from cyclonedds.core import InstanceState  # noqa: PLC0415 (as above)

        reader = BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication)
        self._builtin.append(reader)  # not in matched(): it matches no topic of ours
        known: dict = {}

        def publications() -> list[tuple[str, str]]:
            while samples := reader.take(N=100):
                for sample in samples:
                    key = getattr(sample, "key", None)
                    if sample.sample_info.instance_state != InstanceState.Alive:
                        known.pop(key, None)
                    elif getattr(sample, "topic_name", None) is not None:
                        known[key] = (sample.topic_name, sample.type_name)
            return list(known.values())

        return publications

    def incompatible_qos(self) -> dict[str, int]:
        """Per DDS topic of a subscription: how many publishers DDS found whose QoS it could
        not match (e.g. a best-effort publisher for a reliable subscription)."""
        counts = {}
        for reader in self._readers:
            status = reader.get_requested_incompatible_qos_status()
            counts[reader.topic.name] = counts.get(reader.topic.name, 0) + status.total_count
        return counts

    def matched(self) -> dict[str, int]:
        """Matched remote endpoints per DDS topic: writers' readers and readers' writers."""
        counts = {}
        for entity in (*self._readers, *self._writers):
            status = (entity.get_subscription_matched_status() if entity in self._readers
                      else entity.get_publication_matched_status())
            name = entity.topic.name if hasattr(entity, "topic") else "?"
            counts[name] = counts.get(name, 0) + status.current_count
        return counts

    def wait_for_acks(self, timeout_s: float) -> bool:
        """Waits up to `timeout_s` until every reliable subscriber acknowledged everything
        this node's writers wrote; returns whether they all did."""
        from cyclonedds.core import DDSException  # noqa: PLC0415 (cyclonedds only for ROS 2)

        end = time.monotonic() + timeout_s
        done = True
        for writer in self._writers:
            left = max(0.0, end - time.monotonic())
            try:
                done &= bool(writer.wait_for_acks(int(left * 1e9)))
            except DDSException:  # timed out
                done = False
        return done

    def close(self) -> None:
        """Deletes the participant and with it its readers, writers, topics and wait set."""
        if self.participant is None:
            return
        self.participant.__del__()  # Entity's own deletion (dds_delete); idempotent after
        self.participant = self._waitset = None
        for entities in (self._readers, self._writers, self._conditions, self._handlers,
                         self._builtin):
            entities.clear()
        self._topics.clear()

    def __del__(self) -> None:
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
