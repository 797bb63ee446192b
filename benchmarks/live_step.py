"""CPU per live message: the station's per-message path with the chain updated by the Drake
diagram (its Simulator advanced one update per message) and by the ChainStep, against the
compensator's own per-sample cost in the same run.

Two models of ftdrake's arm, trained on synthetic readings of a known payload
(``ftdrake.testing``: sums of sinusoids on all seven joints, 30 s at 100 Hz): the physics
payload model and the hybrid with its default residual (one forest of 50 trees on q). The
scenario is the default one: bias tracker and detector on.

Per message, three figures (CPU µs, ``time.process_time`` over a batch of messages, the
median over batches; the two paths' batches interleaved so that both see the same load):

* LCM station: one joint-state and one F/T message, pre-encoded as a driver sends them,
  handed to an LCM ``HardwareStation``'s callbacks (decode, the stream checks, one chain
  update, encode and publish of the compensated wrench and the contact state on
  ``memq://``, nobody listening): ``serve``'s work per message except the transport's
  receive;
* ROS 2 station (with cyclonedds): the same two messages as the DDS reader hands them to a
  ``Ros2Station`` (joint names reordered, checks, one chain update, the wrench, contact and
  contact force written to DDS, nobody listening; the DDS receive and deserialisation and
  the periodic diagnostics are not in it);
* floor (``station_floor.py``): the same stations' callbacks with the per-message work taken
  out (decode, encode and publish of the same outputs, no checks, no chain update), so that
  station − floor is ftdrake's own per-message work (``live_rate.py --floor`` measures the
  same split live);
* chain: the chain's update alone (diagram: inputs fixed, ``Simulator.AdvanceTo``, the
  published outputs evaluated; step: ``ChainStep.update``);
* compensator: ``CompensatorSystem.compensate`` on arrays, the compiled compensator sample
  both paths run (input checks, q̈ estimate, the model's prediction and std, the
  compensated wrench);
* ROS 2 receive (with cyclonedds; once, not per model): the ROS 2 node's ``spin`` for a
  joint state and a wrench that another participant in this process has just written (the
  takes of both readers, the CDR reads, the hand-over to handlers that do nothing), timed
  with the thread's clock around each spin: the receive the ROS 2 station's figure leaves
  out, but for Cyclone's own receive thread (a local write is delivered in the writer's).

The messages are consecutive samples of an unseen stretch of the same motion at 1 kHz. On a
shared machine only the ratios travel; the load average is printed with the numbers. The last
line is one JSON object.

    nice -n 5 python benchmarks/live_step.py [--messages 1000] [--batches 7]

(run from anywhere: it imports ``station_floor`` from its own folder)
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings

import numpy as np
from pydrake.systems.analysis import Simulator
from station_floor import floor

from ftdrake import ChainConfig, CompensationChain
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from ftdrake.hardware.station import HardwareStation
from ftdrake.runtime.step import ChainStep
from ftdrake.signals import estimator_size
from ftdrake.testing import readings, sinusoids

N = 7
GOAL_US = 100.0


def models_and_stream(n_messages: int):
    """(models, [q, q̇, q̈] rows at 1 kHz, readings): the models fitted on another stretch."""
    rng = np.random.default_rng(0)
    X = sinusoids(rng, range(N), n=3000, duration=30.0)
    Y = readings(X, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        models = {"physics": PhysicsPayloadCompensator().fit(X, Y),
                  "hybrid": HybridCompensator(PhysicsPayloadCompensator()).fit(X, Y)}
    rows = sinusoids(np.random.default_rng(0), range(N), n=n_messages,
                     duration=n_messages * 1e-3)
    return models, rows, readings(rows, np.random.default_rng(1))


def station_batch(station, messages) -> float:
    """CPU µs per message pair through the station's callbacks."""
    start = time.process_time()
    for joint, wrench in messages:
        station._on_joint(joint)
        station._on_wrench(wrench)
    return (time.process_time() - start) / len(messages) * 1e6


class DiagramChain:
    """The chain's update as the station drove the diagram: inputs fixed, AdvanceTo."""

    def __init__(self, chain):
        self.chain = chain
        self.simulator = Simulator(chain)
        self.context = self.simulator.get_mutable_context()
        chain.initialize(self.context)
        self.simulator.Initialize()
        self.wrench = chain.get_input_port_wrench_measured().FixValue(self.context, np.zeros(6))
        self.state = chain.get_input_port_joint_state().FixValue(self.context, np.zeros(2 * N))
        self.ports = [chain.GetOutputPort(name) for name in (
            "fault", "wrench_compensated", "contact", "contact_force", "out_of_domain")]
        self.k = 0

    def update(self, wrench, state):
        self.wrench.GetMutableData().get_mutable_value().SetFromVector(wrench)
        self.state.GetMutableData().get_mutable_value().SetFromVector(state)
        self.simulator.AdvanceTo((self.k + 0.5) * self.chain.period)
        self.k += 1
        for port in self.ports:
            port.Eval(self.context)


def chain_batch(update, wrenches, states) -> float:
    start = time.process_time()
    for w, x in zip(wrenches, states, strict=True):
        update(w, x)
    return (time.process_time() - start) / len(wrenches) * 1e6


def step_batch(step, first: int, wrenches, states) -> float:
    start = time.process_time()
    for k, (w, x) in enumerate(zip(wrenches, states, strict=True), start=first):
        step.update(k * step.period, w, x)
    return (time.process_time() - start) / len(wrenches) * 1e6


def compensator_batch(comp, wrenches, states) -> float:
    """The compensator's sample on its own arrays (state: q̈ estimator and flag copies, the
    five outputs), as the step calls it."""
    state = [np.zeros(estimator_size(N) + 2), np.zeros(6), np.zeros(6), np.zeros(6),
             np.zeros(1), np.zeros(1)]
    accel = np.zeros(N)
    start = time.process_time()
    for w, x in zip(wrenches, states, strict=True):
        comp.compensate(w, x, accel, False, np.nan, *state)
    return (time.process_time() - start) / len(wrenches) * 1e6


def lcm_stations(model, scenario, states, Y):
    """The LCM station by the diagram and by the step, and the messages, pre-encoded."""
    config = HardwareConfig(lcm_url="memq://", n_joints=N, sensor_timeout_s=1e6,
                            joint_state_timeout_s=1e6)
    stations = {path: HardwareStation(config, model, scenario, "memq://")
                for path in ("diagram", "step", "floor")}
    stations["diagram"].use_diagram()
    messages = [(encode_joint_state("iiwa_status", (k + 1) * 1e-3, x[:N], x[N:]),
                 encode_wrench((k + 1) * 1e-3, w))
                for k, (x, w) in enumerate(zip(states, Y, strict=True))]
    return stations, messages


def ros2_stations(model, scenario, states, Y):
    """The ROS 2 station (Cyclone DDS, nobody listening) by the diagram and by the step, and
    the messages as the DDS reader hands them over; None without cyclonedds."""
    try:
        from ftdrake.hardware.ros2.config import Ros2Config
        from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_stamped
        from ftdrake.hardware.ros2.station import Ros2Station
    except ImportError:
        return None
    names = [f"joint_{k + 1}" for k in range(N)]
    domain = 100 + os.getpid() % 100
    stations = {path: Ros2Station(Ros2Config(
        joint_names=names, domain_id=domain, sensor_timeout_s=1e6, joint_state_timeout_s=1e6,
        output_namespace=f"/ftdrake_{path}_{os.getpid()}"), model, scenario)
        for path in ("diagram", "step", "floor")}
    stations["diagram"].use_diagram()
    joint_state = ros2_type("sensor_msgs/msg/JointState")
    messages = [(joint_state(header=header((k + 1) * 1e-3, "base_link"), name=names,
                             position=[float(v) for v in x[:N]],
                             velocity=[float(v) for v in x[N:]], effort=[]),
                 wrench_stamped(header((k + 1) * 1e-3, "ft_sensor"), w))
                for k, (x, w) in enumerate(zip(states, Y, strict=True))]
    return stations, messages


def ros2_station_batch(station, messages) -> float:
    """CPU µs per message pair through the ROS 2 station's callbacks."""
    start = time.process_time()
    for joint, wrench in messages:
        station._on_joint(joint, station.clock())
        station._on_wrench(wrench, station.clock())
    return (time.process_time() - start) / len(messages) * 1e6


def ros2_receive(pairs: int, batches: int) -> float | None:
    """CPU µs of ``Ros2Node.spin`` per joint-state + wrench pair (module docstring), the
    median over `batches` batches of `pairs`; None without cyclonedds."""
    try:
        from ftdrake.hardware.ros2.cdr import JointStateReader
        from ftdrake.hardware.ros2.cdr import wrench_stamped as read_wrench_stamped
        from ftdrake.hardware.ros2.dds import Ros2Node
        from ftdrake.hardware.ros2.messages import header, ros2_type, wrench_stamped
    except ImportError:
        return None
    domain = 100 + os.getpid() % 100
    joint_type, wrench_type = "sensor_msgs/msg/JointState", "geometry_msgs/msg/WrenchStamped"
    with Ros2Node(domain) as node, Ros2Node(domain) as driver:
        for topic, msgtype, read in (("/live_step/joint_states", joint_type,
                                      JointStateReader().read),
                                     ("/live_step/wrench", wrench_type, read_wrench_stamped)):
            node.subscribe(topic, msgtype, lambda _msg, _arrival: None, read=read)
        joints = driver.publisher("/live_step/joint_states", joint_type)
        wrenches = driver.publisher("/live_step/wrench", wrench_type)
        end = time.monotonic() + 10
        while min(node.matched().values()) < 1 and time.monotonic() < end:
            time.sleep(0.01)
        joint_state = ros2_type(joint_type)(
            header=header(1.0, "base_link"), name=[f"joint_{k + 1}" for k in range(N)],
            position=[0.1] * N, velocity=[0.2] * N, effort=[])
        wrench = wrench_stamped(header(1.0, "ft_sensor"), [1.0] * 6)
        medians = []
        for _ in range(batches + 1):  # the first warms
            spent = 0
            for _ in range(pairs):
                joints.write(joint_state)
                wrenches.write(wrench)
                start = time.thread_time_ns()
                if node.spin(2) != 2:
                    raise RuntimeError("the ROS 2 node did not hand over both messages")
                spent += time.thread_time_ns() - start
            medians.append(spent / pairs / 1e3)
    return float(np.median(medians[1:]))


def measure(model, rows, Y, n_messages: int, batches: int) -> dict:
    scenario = ChainConfig()  # the defaults: bias tracker and detector on
    states = rows[:, :2 * N]
    stations, messages = lcm_stations(model, scenario, states, Y)
    ros2 = ros2_stations(model, scenario, states, Y)
    diagram_chain = DiagramChain(CompensationChain(model, scenario, n_joints=N))
    step_chain = ChainStep(CompensationChain(model, scenario, n_joints=N))
    comp = step_chain.chain.compensator
    times = {key: [] for key in ("station_diagram", "station_step", "station_floor",
                                 "chain_diagram", "chain_step", "compensator")}
    size = n_messages // batches
    warm = slice(0, min(200, size))  # compile the kernels, fill the caches
    station_batch(stations["diagram"], messages[warm])
    station_batch(stations["step"], messages[warm])
    with floor():
        station_batch(stations["floor"], messages[warm])
    if ros2 is not None:
        for path in ("diagram", "step"):
            times[f"ros2_station_{path}"] = []
            ros2_station_batch(ros2[0][path], ros2[1][warm])
        times["ros2_station_floor"] = []
    for b in range(batches):
        part = slice(b * size, (b + 1) * size)
        times["station_diagram"].append(station_batch(stations["diagram"], messages[part]))
        times["station_step"].append(station_batch(stations["step"], messages[part]))
        with floor():
            times["station_floor"].append(station_batch(stations["floor"], messages[part]))
        if ros2 is not None:
            for path in ("diagram", "step"):
                times[f"ros2_station_{path}"].append(ros2_station_batch(ros2[0][path],
                                                                        ros2[1][part]))
            with floor():
                times["ros2_station_floor"].append(ros2_station_batch(ros2[0]["floor"],
                                                                      ros2[1][part]))
        times["chain_diagram"].append(chain_batch(diagram_chain.update, Y[part], states[part]))
        times["chain_step"].append(step_batch(step_chain, b * size, Y[part], states[part]))
        times["compensator"].append(compensator_batch(comp, Y[part], states[part]))
    assert stations["step"].published == stations["diagram"].published > 0
    if ros2 is not None:
        assert ros2[0]["step"].published == ros2[0]["diagram"].published > 0
        for station in ros2[0].values():
            station.close()
    return {key: float(np.median(v)) for key, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=7000)
    parser.add_argument("--batches", type=int, default=7)
    args = parser.parse_args()
    models, rows, Y = models_and_stream(args.messages)
    results = {}
    load = os.getloadavg()[0]
    receive = ros2_receive(args.messages // args.batches, args.batches)
    for name, model in models.items():
        results[name] = r = measure(model, rows, Y, args.messages, args.batches)
        r["station_ratio_diagram_to_step"] = r["station_diagram"] / r["station_step"]
        r["station_step_to_compensator"] = r["station_step"] / r["compensator"]
        r["station_diagram_to_compensator"] = r["station_diagram"] / r["compensator"]
    print(f"CPU µs per message (median of {args.batches} batches of "
          f"{args.messages // args.batches}); load {load:.2f} → {os.getloadavg()[0]:.2f}")
    print(f"{'model':<8} {'path':<8} {'LCM station':>12} {'ROS 2 station':>14} "
          f"{'chain update':>13} {'compensator':>12} {'LCM station / compensator':>26}")
    for name, r in results.items():
        for path in ("diagram", "step"):
            ros2 = r.get(f"ros2_station_{path}", float("nan"))
            print(f"{name:<8} {path:<8} {r[f'station_{path}']:12.1f} {ros2:14.1f} "
                  f"{r[f'chain_{path}']:13.1f} {r['compensator']:12.1f} "
                  f"{r[f'station_{path}'] / r['compensator']:26.1f}")
        print(f"{name:<8} {'floor':<8} {r['station_floor']:12.1f} "
              f"{r.get('ros2_station_floor', np.nan):14.1f}")
        print(f"{name:<8} {'step − floor':<12} {r['station_step'] - r['station_floor']:8.1f} "
              f"{r.get('ros2_station_step', np.nan) - r.get('ros2_station_floor', np.nan):14.1f}")
        print(f"{name:<8} {'diagram / step':<23} {r['station_ratio_diagram_to_step']:5.1f} "
              f"{r.get('ros2_station_diagram', np.nan) / r.get('ros2_station_step', np.nan):14.1f}"
              f" {r['chain_diagram'] / r['chain_step']:13.1f}")
    if receive is not None:
        print(f"ROS 2 node's receive (spin: a joint state and a wrench from another participant "
              f"in this process): {receive:.1f} µs per pair")
    for key, what in (("station_step", "LCM station by the step"),
                      ("ros2_station_step", "ROS 2 station by the step (DDS receive not in)")):
        if all(key in r for r in results.values()):
            met = all(r[key] <= GOAL_US for r in results.values())
            print(f"goal <= {GOAL_US:.0f} µs per message, {what}: "
                  f"{'met' if met else 'NOT met'}")
    print(json.dumps({"benchmark": "live_step", "messages": args.messages,
                      "batches": args.batches, "goal_us": GOAL_US, "results": results,
                      "ros2_receive_us": receive,
                      "load": [load, os.getloadavg()[0]],
                      "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                  "python": platform.python_version()}}))


if __name__ == "__main__":
    main()
