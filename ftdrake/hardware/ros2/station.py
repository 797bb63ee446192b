"""Ros2Station: the runtime chain on a ROS 2 robot's topics, over Cyclone DDS.

    /joint_states (JointState) ──► by name, into joint_names' order ──┐
    …/wrench (WrenchStamped) ───────────────────────────────────────► StationCore
                                                                        │ (CompensationChain)
    <ns>/wrench_contact, <ns>/wrench_compensated  WrenchStamped ◄── wrench_contact,
                                  wrench_compensated (the input's frame_id and stamp)
    <ns>/contact Bool, <ns>/contact_force Float64 ◄── contact, contact_force
    <ns>/bias WrenchStamped, <ns>/payload InertiaStamped ◄── the bias tracker's estimates
    /diagnostics DiagnosticArray ◄── fault, reason, out_of_domain, payload_change, rates,
                                     counts

The outputs are the LCM station's, under the same names (:data:`ftdrake.conventions.PUBLISHED`).

The message-driven loop, the checks (:class:`~ftdrake.hardware.live_inputs.StreamMonitor`),
the fault episodes and the counts are :class:`~ftdrake.hardware.core.StationCore`'s, the same
as on LCM: each fault-free wrench message updates the diagram once; a silent stream, time going
back, NaN, or a joint state that lacks one of ``joint_names`` (or names one twice) faults
the inputs (joints it carries beyond them, another arm's or a gripper's, are ignored, said
once as a warning), and
then no wrench, contact, bias or payload is published (a stale value is never published as
fresh) while the diagnostics say why, at once. Messages of all topics are handled in the
order they arrived (:class:`~ftdrake.hardware.ros2.dds.Ros2Node`).

Python entry point::

    station = Ros2Station(Ros2Config(joint_names=[...]), load_model("m.ftd"), ChainConfig())
    while running:
        station.spin_once(timeout_ms=2)

Per message the work is done by a compiled loop whenever the station is in its ordinary
state (:class:`~ftdrake.hardware.ros2.fast.path.CompiledPath`: Cyclone's C take and write,
the CDR, the checks, the chain's update and the outputs in one call without the GIL), and
by the Python path above otherwise; anything unusual in a message goes to the Python path,
so the two publish and count the same (``ros2.compiled_path``; ``summary()["compiled_path"]``
says whether it runs and why not).

``ftdrake serve --ros2`` runs exactly this (:mod:`ftdrake.cli.ros2`). See
:class:`~ftdrake.hardware.ros2.config.Ros2Config` for the topics and their types.
"""

from __future__ import annotations

import time

import numpy as np

from ...config import ChainConfig
from ...errors import ConfigError
from ..config import rate_levers
from ..core import StationCore
from ..live_checks import check_joint_count, joint_names_problem, ros2_type_name
from ..messages import JointSample, WrenchSample
from ..overload import CpuMeter
from ..threads import NewThreads, pin_process
from .cdr import JointStateReader
from .cdr import wrench_stamped as read_wrench_stamped
from .config import OUTPUTS, Ros2Config
from .dds import Ros2Node, dds_topic
from .fast.path import BUDGET_S, CompiledPath
from .messages import from_stamp, header, ros2_type, wrench_of
from .packing import ValueWriter, WrenchWriter

#: ``diagnostic_msgs/msg/DiagnosticStatus`` levels.
OK, WARN, ERROR = 0, 1, 2
#: The DiagnosticStatus name ftdrake publishes.
DIAGNOSTIC_NAME = "ftdrake: F/T compensation"
_TYPE_CHECK_PERIOD_S = 0.2  # DDS discovery is asked this often while an input is silent
_MIN_PAYLOAD_KG = 1e-3  # below this the payload's centre of mass is not published (0)
#: The outputs published as WrenchStamped (with the input's frame_id and stamp).
WRENCH_TOPICS = tuple(name for name, msgtype in OUTPUTS.items()
                      if msgtype == "geometry_msgs/msg/WrenchStamped")


def _imu_values(imu) -> dict:
    """The IMU's counts (live_imu.ImuPairing) as diagnostic values."""
    return {"received_imu": imu.accepted + sum(imu.rejected.values()),
            "unpaired_imu": imu.unpaired,
            **{f"rejected_imu_{k}": v for k, v in imu.rejected.items()}}


def _load_values(load) -> dict:
    """The LoadMonitor's counts and rates as diagnostic values."""
    rate = {k: "" if v is None else f"{v:.1f}" for k, v in (
        ("input_hz", load.input_hz), ("sustained_hz", load.sustained_hz))}
    return {"overload": load.overloaded, "lost_ft": load.lost, "dropped_ft": load.dropped,
            "backlog_ms": f"{load.backlog_s * 1e3:.1f}", **rate}


class Ros2Station(StationCore):
    """StationCore fed by ROS 2 topics (see the module and Ros2Config).

    `chain`: the :class:`~ftdrake.config.ChainConfig` the chain is built from (default
    ``ChainConfig()``; joint-state gravity on the model's own robot unless ``chain.robot``
    names one). `node`: a :class:`~ftdrake.hardware.ros2.dds.Ros2Node` (default: one on
    ``config.domain_id`` with ``config.dds_config`` and `clock`). `clock` gives arrival times
    in s (monotonic); `on_event(FaultEvent)` is called on every fault change. With
    ``config.cpu_affinity`` set, building the station keeps every thread of this process
    on those CPUs (:func:`~ftdrake.hardware.threads.pin_process`).
    """

    def __init__(self, config: Ros2Config, model, chain: ChainConfig | None = None,
                 node: Ros2Node | None = None, *, clock=time.monotonic, on_event=None,
                 max_events: int = 10_000, on_warning=None):
        self.config = c = config.validate()
        events = tuple(name for name, topic in (("tared", c.tare_topic),
                                                ("payload_changed", c.payload_topic)) if topic)
        self._user_on_event, self._user_on_warning = on_event, on_warning
        check_joint_count(model, c.n_joints, "ros2.joint_names",
                          f"the model's {getattr(model, 'n_joints_', '')} joint names, in "
                          "the model's order")
        names = joint_names_problem(model, c.joint_names)
        if names is not None and names[1]:
            raise ConfigError(names[0])
        self._diagnostics = None  # the writer, once the node exists
        super().__init__(model, chain, n_joints=c.n_joints,
                         sensor_timeout_s=c.sensor_timeout_s,
                         joint_state_timeout_s=c.joint_state_timeout_s,
                         temperature_timeout_s=c.temperature_timeout_s, events=events,
                         clock=clock, on_event=self._on_fault_change, max_events=max_events,
                         on_warning=self._on_warning, joint_names=c.joint_names,
                         max_backlog_s=c.max_backlog_s, pair_tolerance_s=c.pair_tolerance_s,
                         imu_max_skew_s=c.imu_max_skew_s)
        self.load.levers = rate_levers(c, "ros2")  # its warnings name the keys to change
        self.monitor.pair_key = "ros2.pair_tolerance_s"  # its stamp gaps name the key
        if self.imu is not None:  # its faults name the keys to change
            self.imu.source = f"ros2.imu_topic {c.imu_topic!r}"
            self.imu.skew_key = "ros2.imu_max_skew_s"
        with NewThreads() as dds_threads:  # Cyclone's, started with the first participant
            self.node = node if node is not None else Ros2Node(
                c.domain_id, c.dds_config, clock=clock, reorder_window_s=c.reorder_window_s)
        if c.yield_io_threads:
            dds_threads.yield_to_caller()
        if c.cpu_affinity:
            pin_process(c.cpu_affinity)
        self._index = {name: k for k, name in enumerate(c.joint_names)}
        self._ignored: list[str] = []  # joints of the messages not in joint_names
        self.joint_states_ignored = 0  # messages naming none of joint_names (another device's)
        self._order = (None, None)  # (names of the last message, their permutation)
        self._header = None  # the wrench message being processed
        self._contact_due = False  # its wrench was published: contact and force follow
        self._open_writers(c)
        self._diagnostics = self.node.publisher(c.diagnostics_topic,
                                                "diagnostic_msgs/msg/DiagnosticArray")
        self._types = {name: ros2_type(msgtype) for name, msgtype in (
            ("bool", "std_msgs/msg/Bool"), ("float64", "std_msgs/msg/Float64"),
            ("inertia", "geometry_msgs/msg/Inertia"),
            ("inertia_stamped", "geometry_msgs/msg/InertiaStamped"),
            ("vector3", "geometry_msgs/msg/Vector3"),
            ("array", "diagnostic_msgs/msg/DiagnosticArray"),
            ("status", "diagnostic_msgs/msg/DiagnosticStatus"),
            ("key_value", "diagnostic_msgs/msg/KeyValue"))}
        depth = c.queue_depth
        # The two per-sample inputs read from their bytes (ros2/cdr.py).
        self.node.subscribe(c.joint_state_topic, "sensor_msgs/msg/JointState", self._on_joint,
                            c.joint_state_qos, depth, read=JointStateReader().read)
        self.node.subscribe(c.wrench_topic, "geometry_msgs/msg/WrenchStamped", self._on_wrench,
                            c.wrench_qos, depth, read=read_wrench_stamped)
        if self._temperature_in is not None:
            self.node.subscribe(c.temperature_topic, "sensor_msgs/msg/Temperature",
                                self._on_temperature, c.wrench_qos, depth)
        if self.imu is not None:
            self.node.subscribe(c.imu_topic, "sensor_msgs/msg/Imu", self._on_imu,
                                c.wrench_qos, depth)
        for name, topic in (("tared", c.tare_topic), ("payload_changed", c.payload_topic)):
            if topic:
                self.node.subscribe(topic, "std_msgs/msg/Empty",
                                    lambda _msg, _arrival, n=name: self.on_event_signal(n, True),
                                    "reliable", depth)
        self.diagnostics_published = 0
        self._last_diagnostics = self.clock()
        self._last_received = dict(self.monitor.received)
        self.rates_hz: dict[str, float] = {}
        # serve's CPU between two periodic diagnostics (the process's: every thread).
        self.cpu_meter = CpuMeter(self._last_diagnostics, self.processed)
        # DDS discovery's publications, to name another type published on an input topic.
        self._inputs = {dds_topic(c.joint_state_topic): ("joint", "sensor_msgs/msg/JointState",
                                                         "joint_state_topic"),
                        dds_topic(c.wrench_topic): ("ft", "geometry_msgs/msg/WrenchStamped",
                                                    "wrench_topic")}
        self._publications = self.node.publications()
        self._last_type_check = -np.inf
        if names is not None:
            self.warn(names[0])
        # Last: it reads the node's readers and writers and the station's state.
        self.compiled = CompiledPath(self, 0.0 if c.batch_period_s > 0 else BUDGET_S)

    def _open_writers(self, c: Ros2Config) -> None:
        """The outputs' writers; the per-sample ones packed (ros2/packing.py): wrenches,
        contact, contact force."""
        self._writers = {name: self.node.publisher(c.output_topic(name), msgtype,
                                                   depth=c.queue_depth)
                         for name, msgtype in OUTPUTS.items()
                         if self.has_output(name) and name in c.outputs}
        self._wrench_out = [(name, WrenchWriter(self._writers[name])) for name in WRENCH_TOPICS
                            if name in self._writers]
        self._value_out = {name: ValueWriter(self._writers[name], kind) for name, kind in (
            ("contact", "bool"), ("contact_force", "float64")) if name in self._writers}

    def _check_sources(self, chain) -> None:
        c = self.config
        if c.tare_topic and not chain.HasInputPort("tared"):
            raise ConfigError("ros2.tare_topic: a re-tare goes to the bias tracker; enable "
                              "chain.bias_tracker or leave the topic empty")
        if c.payload_topic and not chain.HasInputPort("payload_changed"):
            raise ConfigError("ros2.payload_topic: a grasp goes to the bias tracker's payload "
                              "estimate; set chain.bias_tracker.enabled and track_payload, "
                              "or leave the topic empty")
        if chain.needs_imu and not c.imu_topic:
            raise ConfigError("ros2.imu_topic: the model takes an IMU at the sensor; name the "
                              "sensor_msgs/msg/Imu topic (axes along the sensor frame S)")
        if chain.needs_temperature and not c.temperature_topic:
            raise ConfigError("ros2.temperature_topic: the model was trained with the sensor "
                              "temperature; name the sensor_msgs/msg/Temperature topic (°C)")

    # -- inputs -------------------------------------------------------------------------------
    def _permutation(self, names: list[str]):
        """Indices of joint_names in the message's `names`, a detail saying what is wrong, or
        None for a message that names none of them."""
        if names == self._order[0]:
            return self._order[1]
        if not any(n in self._index for n in names):
            return None  # none of the model's joints: another device's state
        unknown = [n for n in names if n not in self._index]
        missing = [n for n in self.config.joint_names if n not in names]
        twice = [n for n in self.config.joint_names if names.count(n) > 1]
        if missing or twice:
            parts = [f"unknown {unknown}" if unknown else "",
                     f"missing {missing}" if missing else "",
                     f"{twice} twice" if twice else ""]
            return ("joint state names " + ", ".join(p for p in parts if p)
                    + f"; ros2.joint_names is {self.config.joint_names}")
        if unknown and unknown != self._ignored:  # another arm's, a gripper's: said once
            self._ignored = unknown
            self.warn(f"joint states also carry {unknown}, not in ros2.joint_names: ignored "
                      "(the model's joints are taken from them by name)")
        order = np.array([names.index(n) for n in self.config.joint_names])
        self._order = (list(names), order)
        return order

    def _on_joint(self, msg, arrival: float) -> None:
        names = list(msg.name)
        order = self._permutation(names)
        if order is None:  # a gripper driver's own JointState on the same topic: not ours
            self.joint_states_ignored += 1
            if self.joint_states_ignored == 1:
                self.warn(f"joint states that name none of ros2.joint_names arrive on "
                          f"{self.config.joint_state_topic} (e.g. {names}): ignored, as "
                          "another device's (the summary counts them)")
            return
        if isinstance(order, str):
            self.monitor.reject_joint("joint_names", order)
            self._note(None)
            return
        q, v = np.asarray(msg.position, float), np.asarray(msg.velocity, float)
        if len(q) != len(names) or len(v) not in (0, len(names)):
            self.monitor.reject_joint("malformed", (
                f"joint state has {len(names)} names, {len(q)} positions and {len(v)} "
                "velocities"))
            self._note(None)
            return
        self.on_joint_sample(JointSample(from_stamp(msg.header.stamp), q[order],
                                         v[order] if len(v) else None, None), arrival)

    def summary(self) -> dict:
        """StationCore's counts, and ``joint_states_ignored``: joint-state messages that
        named none of ``joint_names`` (another device's, not used)."""
        return {**super().summary(), "joint_states_ignored": self.joint_states_ignored,
                "compiled_path": self.compiled.summary()}

    def _on_wrench(self, msg, arrival: float) -> None:
        self._header = msg.header
        frame, want = msg.header.frame_id, self.config.wrench_frame_id
        problem = None if not want or frame == want else ("frame_id", (
            f"wrench frame_id {frame!r} is not ros2.wrench_frame_id {want!r}: the model "
            f"compensates readings in {want!r}. Fix: publish the sensor's own frame (the "
            "broadcaster's frame_id parameter), or set ros2.wrench_frame_id to the frame "
            "the model was trained in ('' accepts any)"))
        self.on_wrench_sample(WrenchSample(from_stamp(msg.header.stamp),
                                           np.array(wrench_of(msg), float)), arrival, problem)

    def _on_imu(self, msg, arrival: float) -> None:
        self.on_imu_sample(imu_sample(msg), arrival)

    def _on_temperature(self, msg, arrival: float) -> None:
        self.on_temperature_sample((from_stamp(msg.header.stamp), msg.temperature), arrival)

    # -- outputs ------------------------------------------------------------------------------
    def _publish_wrench(self, t: float) -> None:
        h, types, w = self._header, self._types, self._writers
        del t  # the stamp is the input's header's
        stamp = h.stamp
        for name, out in self._wrench_out:  # bias: with the tracker
            out.write(stamp.sec, stamp.nanosec, h.frame_id, self.value(name).tolist())
        self._contact_due = True
        if "payload" in w:
            dm, *mc = (float(x) for x in self.output("payload"))
            com = [x / dm for x in mc] if abs(dm) >= _MIN_PAYLOAD_KG else [0.0] * 3
            w["payload"].write(types["inertia_stamped"](header=h, inertia=types["inertia"](
                m=dm, com=types["vector3"](*com), ixx=0.0, ixy=0.0, ixz=0.0, iyy=0.0, iyz=0.0,
                izz=0.0)))

    def _publish_contact(self, t: float, fault: bool) -> bool:
        """Contact and force go out after each published wrench, never stale (a Bool has no
        fault flag); a fault goes to the diagnostics (_on_fault_change)."""
        if not self._contact_due or fault:
            return False
        self._contact_due = False
        out = self._value_out
        if not out:
            return False
        state = self.contact_state(t, fault)
        if "contact" in out:
            out["contact"].write(state.contact)
        if "contact_force" in out:
            out["contact_force"].write(state.contact_force)
        return True

    def _on_fault_change(self, event) -> None:
        self.publish_diagnostics()
        if self._user_on_event is not None:
            self._user_on_event(event)

    def _on_warning(self, warning: str) -> None:
        if self._diagnostics is not None:
            self.publish_diagnostics()
        if self._user_on_warning is not None:
            self._user_on_warning(warning)

    def check_input_types(self) -> None:
        """Faults the inputs when a stream has no message yet and DDS discovery shows a
        publisher of another type on its topic (``wrong_type``, naming both types) or one
        whose QoS its subscription cannot match (``qos``, naming the key)."""
        for (topic, dds_type) in self._publications():
            stream, expected, key = self._inputs.get(topic, (None, None, None))
            found = ros2_type_name(dds_type)
            if stream is None or found == expected:
                continue
            ros_topic = "/" + topic[len("rt/"):]
            self.flag_missing(stream, "wrong_type", (
                f"{ros_topic} carries {found} (a publisher found by DDS discovery), ftdrake "
                f"reads {expected} there. Fix: publish {expected} on {ros_topic}, or set "
                f"ros2.{key} to the topic that carries it"))
        for topic, count in self.node.incompatible_qos().items():
            stream, _, key = self._inputs.get(topic, (None, None, None))
            if stream is None or not count or stream in self.monitor.missing:
                continue
            field = key.replace("_topic", "_qos")
            have = getattr(self.config, field)
            other = "sensor_data" if have == "reliable" else "reliable"
            ros_topic = "/" + topic[len("rt/"):]
            self.flag_missing(stream, "qos", (
                f"a publisher on {ros_topic} offers a QoS that ros2.{field} {have!r} cannot "
                "match (a best-effort publisher never matches a reliable subscription). "
                f"Fix: set ros2.{field}: {other}"))

    def diagnostic_status(self):
        """The DiagnosticStatus of now (see Ros2Config: level, message, key values)."""
        m, types = self.monitor, self._types
        out_of_domain = bool(self.output("out_of_domain")[0] > 0.5)
        model_fault = bool(self.output("fault")[0] > 0.5) and self.processed > 0
        if m.fault or model_fault:
            level = ERROR
            message = (f"fault {m.reason}: {m.detail}" if m.fault
                       else "fault: the compensator's inputs hold NaN or inf")
        elif out_of_domain:
            level, message = WARN, "joint state outside the model's training range"
        elif self.warnings:
            level, message = WARN, self.warnings[-1]
        else:
            level, message = OK, "ok"
        p50, p99 = self.latency_percentiles()
        values = {"fault": m.fault or model_fault, "reason": m.reason,
                  "out_of_domain": out_of_domain,
                  "contact": bool(self.output("contact")[0] > 0.5),
                  "payload_change": self.contact_state(0.0, False).payload_change,
                  **{f"rate_{k}_hz": f"{v:.1f}" for k, v in self.rates_hz.items()},
                  **{f"received_{k}": v for k, v in m.received.items()},
                  **{f"rejected_{k}": v for k, v in m.rejected.items()},
                  "processed": self.processed, "published": self.published,
                  **_load_values(self.load),
                  **(_imu_values(self.imu) if self.imu is not None else {}),
                  "latency_p50_ms": f"{p50 * 1e3:.3f}", "latency_p99_ms": f"{p99 * 1e3:.3f}",
                  **{f"cpu_{k}": "" if v is None else f"{v:.1f}"
                     for k, v in self.cpu_meter.latest.items()}}
        return types["status"](
            level=level, name=DIAGNOSTIC_NAME, message=message,
            hardware_id=self.config.wrench_topic,
            values=[types["key_value"](key=k, value=str(v).lower() if isinstance(v, bool)
                                       else str(v)) for k, v in values.items()])

    def publish_diagnostics(self) -> None:
        """Publishes the DiagnosticArray now, stamped on the streams' clock."""
        self._diagnostics.write(self._types["array"](
            header=header(self._stream_time()), status=[self.diagnostic_status()]))
        self.diagnostics_published += 1

    # -- running ------------------------------------------------------------------------------
    def close(self) -> None:
        """Leaves DDS (deletes the node's participant); stops a compile still running."""
        self.compiled.close()
        self.node.close()

    def spin_once(self, timeout_ms: float = 1) -> int:
        """Handles the messages that arrived (waiting up to `timeout_ms` for one), checks the
        timeouts (a silent stream's fault is published at once), and publishes the periodic
        diagnostics. Returns the number of messages handled."""
        if self.compiled.why_not is None and self.compiled.ready():
            handled = self.compiled.spin(timeout_ms)
        else:
            handled = self.node.spin(timeout_ms)
        self.check_timeouts()
        now = self.clock()
        if (self.monitor.last_time("ft") is None or self.monitor.last_time("joint") is None) \
                and now - self._last_type_check >= _TYPE_CHECK_PERIOD_S:
            self._last_type_check = now
            self.check_input_types()
        if now - self._last_diagnostics >= self.config.diagnostics_period_s:
            received = self.monitor.received
            dt = now - self._last_diagnostics
            self.rates_hz = {k: (received[k] - self._last_received.get(k, 0)) / dt
                             for k in ("joint", "ft")}
            self._last_diagnostics, self._last_received = now, dict(received)
            self.cpu_meter.reading(now, self.processed)
            self.publish_diagnostics()
        return handled


def imu_sample(msg) -> tuple[float, np.ndarray]:
    """``(t s, [f_S; ω_S] (6,))`` of a ``sensor_msgs/msg/Imu``: its stamp, linear acceleration
    (m/s², proper acceleration: +9.81 up at rest, REP 145) and angular velocity (rad/s), read
    as in S (the IMU's axes along the sensor's)."""
    a, w = msg.linear_acceleration, msg.angular_velocity
    return from_stamp(msg.header.stamp), np.array([a.x, a.y, a.z, w.x, w.y, w.z], dtype=float)
