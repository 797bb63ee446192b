"""CPU per live message: the station's per-message path with the chain updated by the Drake
diagram (its Simulator advanced one update per message) and by the ChainStep, against the
compensator's own per-sample cost in the same run.

Two models of ftdrake's arm, trained on synthetic readings of a known payload
(``ftdrake.testing``: sums of sinusoids on all seven joints, 30 s at 100 Hz): the physics
payload model and the hybrid with its default residual (one forest of 50 trees on q). The
scenario is the default one: bias tracker and detector on.

Per message, three figures (CPU µs, ``time.process_time`` over a batch of messages, the
median over batches; the two paths' batches interleaved so that both see the same load):

* station: one joint-state and one F/T message, pre-encoded as a driver sends them, handed to
  an LCM ``HardwareStation``'s callbacks (decode, the stream checks, one chain update, encode
  and publish of the compensated wrench and the contact state on ``memq://``, nobody
  listening): ``serve``'s work per message except the transport's receive;
* chain: the chain's update alone (diagram: inputs fixed, ``Simulator.AdvanceTo``, the
  published outputs evaluated; step: ``ChainStep.update``);
* compensator: ``CompensatorSystem.compensate`` on arrays, the compiled compensator sample
  both paths run (input checks, q̈ estimate, the model's prediction and std, the
  compensated wrench).

The messages are consecutive samples of an unseen stretch of the same motion at 1 kHz. On a
shared machine only the ratios travel; the load average is printed with the numbers. The last
line is one JSON object.

    nice -n 5 python benchmarks/live_step.py [--messages 1000] [--batches 7]
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

from ftdrake import CompensationChain, ScenarioConfig
from ftdrake.compensation.hybrid import HybridCompensator
from ftdrake.compensation.physics import PhysicsPayloadCompensator
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


def measure(model, rows, Y, n_messages: int, batches: int) -> dict:
    scenario = ScenarioConfig()
    config = HardwareConfig(lcm_url="memq://", n_joints=N, sensor_timeout_s=1e6,
                            joint_state_timeout_s=1e6)
    stations = {"diagram": HardwareStation(config, model, scenario, "memq://"),
                "step": HardwareStation(config, model, scenario, "memq://")}
    stations["diagram"].use_diagram()
    states = rows[:, :2 * N]
    messages = [(encode_joint_state("iiwa_status", (k + 1) * 1e-3, x[:N], x[N:]),
                 encode_wrench((k + 1) * 1e-3, w))
                for k, (x, w) in enumerate(zip(states, Y, strict=True))]
    diagram_chain = DiagramChain(CompensationChain(model, scenario, n_joints=N))
    step_chain = ChainStep(CompensationChain(model, scenario, n_joints=N))
    comp = step_chain.chain.compensator
    times = {key: [] for key in ("station_diagram", "station_step", "chain_diagram",
                                 "chain_step", "compensator")}
    size = n_messages // batches
    warm = slice(0, min(200, size))  # compile the kernels, fill the caches
    station_batch(stations["diagram"], messages[warm])
    station_batch(stations["step"], messages[warm])
    for b in range(batches):
        part = slice(b * size, (b + 1) * size)
        times["station_diagram"].append(station_batch(stations["diagram"], messages[part]))
        times["station_step"].append(station_batch(stations["step"], messages[part]))
        times["chain_diagram"].append(chain_batch(diagram_chain.update, Y[part], states[part]))
        times["chain_step"].append(step_batch(step_chain, b * size, Y[part], states[part]))
        times["compensator"].append(compensator_batch(comp, Y[part], states[part]))
    assert stations["step"].published == stations["diagram"].published > 0
    return {key: float(np.median(v)) for key, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=7000)
    parser.add_argument("--batches", type=int, default=7)
    args = parser.parse_args()
    models, rows, Y = models_and_stream(args.messages)
    results = {}
    load = os.getloadavg()[0]
    for name, model in models.items():
        results[name] = r = measure(model, rows, Y, args.messages, args.batches)
        r["station_ratio_diagram_to_step"] = r["station_diagram"] / r["station_step"]
        r["station_step_to_compensator"] = r["station_step"] / r["compensator"]
        r["station_diagram_to_compensator"] = r["station_diagram"] / r["compensator"]
    print(f"CPU µs per message (median of {args.batches} batches of "
          f"{args.messages // args.batches}); load {load:.2f} → {os.getloadavg()[0]:.2f}")
    print(f"{'model':<8} {'station':>9} {'station':>9} {'chain':>8} {'chain':>8} "
          f"{'compen-':>8}   {'station step /':>14} {'diagram /':>9}")
    print(f"{'':<8} {'diagram':>9} {'step':>9} {'diagram':>8} {'step':>8} {'sator':>8}   "
          f"{'compensator':>14} {'step':>9}")
    for name, r in results.items():
        print(f"{name:<8} {r['station_diagram']:9.1f} {r['station_step']:9.1f} "
              f"{r['chain_diagram']:8.1f} {r['chain_step']:8.1f} {r['compensator']:8.1f}   "
              f"{r['station_step_to_compensator']:14.1f} "
              f"{r['station_ratio_diagram_to_step']:9.1f}")
    met = all(r["station_step"] <= GOAL_US for r in results.values())
    print(f"goal: station step <= {GOAL_US:.0f} µs per message: {'met' if met else 'NOT met'}")
    print(json.dumps({"benchmark": "live_step", "messages": args.messages,
                      "batches": args.batches, "goal_us": GOAL_US, "results": results,
                      "load": [load, os.getloadavg()[0]],
                      "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                  "python": platform.python_version()}}))


if __name__ == "__main__":
    main()
