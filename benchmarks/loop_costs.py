"""Where a 1 kHz step of the free-motion diagram goes: each Python system's update, timed
inside the simulation, and the same update timed hot (tight loop) and cold (caches flushed).

Prints a table and one JSON line. The per-call times inside the simulation come from timers
wrapped around each system's update method for one run; "hot" repeats a call on a frozen
context; "cold" sums a 16 MB array before each call, as a plant step evicts the caches.

    python benchmarks/loop_costs.py [--duration 5]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector

from ftdrake import ScenarioConfig, build_station
from ftdrake.sim.simulate import set_initial_state
from ftdrake.sim.station import plan_trajectory
from ftdrake.systems.contact_truth import ContactTruth
from ftdrake.systems.ft_sensor import ForceTorqueSensor, NoisyForceTorqueSensor

UPDATES = {  # system class → the method Drake calls at every sample
    "ideal sensor": (ForceTorqueSensor, "_calc_wrench"),
    "noisy sensor": (NoisyForceTorqueSensor, "_sample"),
    "contact truth": (ContactTruth, "_sample"),
}


def timed_simulation(config, trajectory, duration):
    """µs per call of each update inside a simulation, and µs per simulated step."""
    totals = {name: [0, 0] for name in UPDATES}
    originals = {name: getattr(cls, method) for name, (cls, method) in UPDATES.items()}

    def timer(name, original):
        def update(self, *args):
            start = time.perf_counter_ns()
            original(self, *args)
            totals[name][0] += time.perf_counter_ns() - start
            totals[name][1] += 1
        return update

    for name, (cls, method) in UPDATES.items():
        setattr(cls, method, timer(name, originals[name]))
    try:
        sim = build_station(config, trajectory=trajectory)
        simulator = Simulator(sim.diagram)
        set_initial_state(sim, simulator.get_mutable_context())
        simulator.Initialize()
        simulator.AdvanceTo(0.05)  # warm-up (numba, caches)
        for total in totals.values():
            total[:] = [0, 0]
        start = time.perf_counter()
        simulator.AdvanceTo(0.05 + duration)
        step_us = (time.perf_counter() - start) / duration * config.time_step * 1e6
    finally:
        for name, (cls, method) in UPDATES.items():
            setattr(cls, method, originals[name])
    per_call = {name: ns / max(n, 1) / 1e3 for name, (ns, n) in totals.items()}
    # The noisy sensor's update evaluates its input, so it includes the ideal sensor's call.
    per_call["noisy sensor"] -= per_call["ideal sensor"]
    return per_call, step_us, sim, simulator


def hot_and_cold(sim, simulator, calls=2000):
    """µs per call of each update on the simulation's final context, hot and cold."""
    root = simulator.get_context()
    contexts = {
        "ideal sensor": sim.sensor.GetMyContextFromRoot(root),
        "noisy sensor": sim.noisy_sensor.GetMyContextFromRoot(root),
        "contact truth": sim.truth.GetMyContextFromRoot(root),
    }
    # Outputs are written into buffers made once, so the timings hold no allocation of ours.
    wrench = BasicVector(6)
    noisy_update = contexts["noisy sensor"].get_discrete_state().Clone()
    truth_update = contexts["contact truth"].get_discrete_state().Clone()
    calls_of = {
        "ideal sensor": lambda: sim.sensor._calc_wrench(contexts["ideal sensor"], wrench),
        "noisy sensor": lambda: sim.noisy_sensor._sample(contexts["noisy sensor"], noisy_update),
        "contact truth": lambda: sim.truth._sample(contexts["contact truth"], truth_update),
    }
    flush = np.ones(2_000_000)  # 16 MB, more than this machine's L2 cache
    result = {}
    for name, call in calls_of.items():
        call()
        start = time.perf_counter_ns()
        for _ in range(calls):
            call()
        hot = (time.perf_counter_ns() - start) / calls / 1e3
        cold = 0
        for _ in range(calls):
            flush.sum()
            start = time.perf_counter_ns()
            call()
            cold += time.perf_counter_ns() - start
        result[name] = (hot, cold / calls / 1e3)
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=5.0)
    args = parser.parse_args()
    config = ScenarioConfig()
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = args.duration + 1.0
    trajectory = plan_trajectory(config)
    per_call, step_us, sim, simulator = timed_simulation(config, trajectory, args.duration)
    outside = hot_and_cold(sim, simulator)
    print(f"simulated step: {step_us:.1f} µs (real-time factor {1e3 / step_us:.1f})")
    print(f"{'update (µs per call)':<22}{'in simulation':>15}{'hot':>10}{'cold':>10}")
    for name in UPDATES:
        hot, cold = outside[name]
        print(f"{name:<22}{per_call[name]:>15.1f}{hot:>10.1f}{cold:>10.1f}")
    print(json.dumps({
        "benchmark": "loop_costs", "step_us": step_us,
        "in_simulation_us": per_call,
        "hot_us": {k: v[0] for k, v in outside.items()},
        "cold_us": {k: v[1] for k, v in outside.items()},
    }))


if __name__ == "__main__":
    main()
