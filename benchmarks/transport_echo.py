"""The least a Python process does per live message on ftdrake's transports: the lower
bound of serve's CPU per message, for `live_rate.py --echo` (which starts it in place of
serve).

Per F/T message it publishes the wrench back as ``wrench_contact`` (the same stamp, so the
driver's end-to-end latency is measured as for serve) and a contact flag; a joint state is
taken and counted. No decode beyond the wrench's, no checks, no chain, no status: only the
transport's receive and send, on the same channels or topics, QoS, receive threads
(``yield_io_threads``'s policy) and wake-ups serve uses.

    python benchmarks/transport_echo.py lcm URL [OUTPUT_URL]
    python benchmarks/transport_echo.py ros2 DOMAIN wait|listener|compiled

``wait``: the ROS 2 station's own delivery (``Ros2Node.spin`` in the main thread, woken by
a wait set); ``listener``: Cyclone DDS hands each reader's data to a callback on its own
receive thread (no wake-up of another thread; the main thread sleeps); ``compiled``: the
main thread's loop compiled (``compiled_echo.py``: the least a compiled per-message path
costs, to set against serve's own compiled path). It prints
``out: ready`` on stderr once listening and, after SIGINT, one JSON line with the counts
in the keys of serve's summary that ``live_rate.py`` reads.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time

from ftdrake.hardware.threads import NewThreads


def lcm_echo(url: str, output_url: str | None, counts: dict):
    """Subscriptions on `url`, outputs on `output_url` (default: `url`); returns the
    function that handles what arrived, waiting up to 2 ms, and the connections (to keep)."""
    from ftdrake.hardware.config import HardwareConfig
    from ftdrake.hardware.messages import ContactState, encode_contact_state
    from ftdrake.hardware.transport import open_lcm

    config = HardwareConfig(lcm_url=url).validate()
    lc = open_lcm(url)
    out = open_lcm(output_url) if output_url else lc
    contact = encode_contact_state(ContactState(0.0, False, 0.0, False))  # no contact
    wrench_channel = config.output_channel("wrench_contact")
    contact_channel = config.output_channel("contact")

    def on_wrench(data: bytes) -> None:
        counts["ft"] += 1
        out.publish(wrench_channel, data)  # lcmt_force_torque in, the same type out
        out.publish(contact_channel, contact)

    def on_joint(_data: bytes) -> None:
        counts["joint"] += 1

    lc.subscribe(config.ft_channel, on_wrench)
    lc.subscribe(config.joint_state_channel, on_joint)
    lc.start_receiving()
    return (lambda: lc.handle(2)), (lc, out)


def ros2_echo(domain: int, delivery: str, counts: dict):
    """Readers and writers on the default topics of `domain`; returns the function that
    handles what arrived (``wait``), or that sleeps while the listeners do (``listener``),
    and the node (to keep: its participant closes with it)."""
    from ftdrake.hardware.ros2.cdr import JointStateReader
    from ftdrake.hardware.ros2.cdr import wrench_stamped as read_wrench
    from ftdrake.hardware.ros2.config import Ros2Config
    from ftdrake.hardware.ros2.dds import Ros2Node
    from ftdrake.hardware.ros2.packing import ValueWriter, WrenchWriter

    config = Ros2Config(joint_names=[f"joint_{k}" for k in range(7)], domain_id=domain,
                        queue_depth=20_000).validate()
    node = Ros2Node(domain)
    writers = (node.publisher(config.output_topic("wrench_contact"),
                              "geometry_msgs/msg/WrenchStamped"),
               node.publisher(config.output_topic("contact"), "std_msgs/msg/Bool"))
    wrench_out, contact_out = WrenchWriter(writers[0]), ValueWriter(writers[1], "bool")

    def on_wrench(msg, _arrival=None) -> None:
        counts["ft"] += 1
        f, tau, stamp = msg.wrench.force, msg.wrench.torque, msg.header.stamp
        wrench_out.write(stamp.sec, stamp.nanosec, msg.header.frame_id,
                         [f.x, f.y, f.z, tau.x, tau.y, tau.z])
        contact_out.write(False)

    def on_joint(_msg, _arrival=None) -> None:
        counts["joint"] += 1

    for topic, msgtype, handler, read, profile in (
            (config.wrench_topic, "geometry_msgs/msg/WrenchStamped", on_wrench, read_wrench,
             config.wrench_qos),
            (config.joint_state_topic, "sensor_msgs/msg/JointState", on_joint,
             JointStateReader().read, config.joint_state_qos)):
        node.subscribe(topic, msgtype, handler, profile=profile, depth=config.queue_depth,
                       read=read)
    if delivery == "wait":
        return (lambda: node.spin(2)), node
    if delivery == "compiled":  # compiled_echo.py, beside this file
        from compiled_echo import compiled_spin

        return compiled_spin(node, *node._readers, *writers, counts), node
    return on_cyclones_thread(node), node


def on_cyclones_thread(node):
    """The node's readers hand their messages over from a listener, on the Cyclone thread
    that received them (the node's own delivery, ``spin(0)``, run there); returns the main
    thread's sleep."""
    from cyclonedds.core import Listener

    lock = threading.Lock()  # one delivery at a time, whichever thread Cyclone calls it on

    def on_data_available(_reader) -> None:
        with lock:
            node.spin(0)

    for reader in node._readers:
        reader.set_listener(Listener(on_data_available=on_data_available))
    return lambda: time.sleep(0.05)


def main(argv: list[str]) -> None:
    counts = {"ft": 0, "joint": 0}
    with NewThreads() as receivers:  # as serve's stations, yield_io_threads: true
        if argv[0] == "lcm":
            spin, _kept = lcm_echo(argv[1], argv[2] if len(argv) > 2 else None, counts)
        else:
            spin, _kept = ros2_echo(int(argv[1]), argv[2], counts)
    receivers.yield_to_caller()
    stop = [False]
    signal.signal(signal.SIGINT, lambda *_: stop.__setitem__(0, True))
    print("out: ready", file=sys.stderr, flush=True)
    while not stop[0]:
        spin()
    print(json.dumps({"received": {"ft": counts["ft"], "joint": counts["joint"]},
                      "processed": counts["ft"], "published_wrench": counts["ft"],
                      "latency_ms": {"p50": float("nan"), "p99": float("nan")}}))


if __name__ == "__main__":
    main(sys.argv[1:])
