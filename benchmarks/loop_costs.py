"""Where a 1 kHz step goes: each Python system's update, timed inside the simulation, and the
same update timed hot (tight loop) and cold (caches flushed).

Prints a table and one JSON line. The per-call times inside the simulation come from timers
wrapped around each system's update method for one run; "hot" repeats a call on a frozen
context; "cold" sums a 16 MB array before each call, as a plant step evicts the caches.

Default: the free-motion diagram (no compensation). ``--compensation``: the contact scenario
with the demo's forest and hybrid in the loop (``ftdrake.testing.demo_models``), timing the
compensator, bias tracker and detector too, interleaved runs per model; "rest" is the step
minus the timed updates (plant, controller, loggers, Drake's event handling).

    python benchmarks/loop_costs.py [--duration 5] [--compensation [--repeats 2]]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector

from ftdrake import ScenarioConfig, build_station
from ftdrake.runtime.bias_tracker import OnlineBiasTracker
from ftdrake.runtime.compensator import CompensatorSystem
from ftdrake.runtime.detector import ContactDetector
from ftdrake.sim.simulate import set_initial_state
from ftdrake.sim.station import plan_trajectory
from ftdrake.systems.contact_truth import ContactTruth
from ftdrake.systems.ft_sensor import ForceTorqueSensor
from ftdrake.systems.noisy_sensor import NoisyForceTorqueSensor
from ftdrake.testing import demo_models

UPDATES = {  # system class → the method Drake calls at every sample
    "ideal sensor": (ForceTorqueSensor, "_calc_wrench"),
    "noisy sensor": (NoisyForceTorqueSensor, "_sample"),
    "contact truth": (ContactTruth, "_sample"),
}
COMPENSATION_UPDATES = {
    "compensator": (CompensatorSystem, "_update"),
    "bias tracker": (OnlineBiasTracker, "_update"),
    "detector": (ContactDetector, "_update"),
}


def timed_simulation(config, trajectory, duration, compensator=None):
    """µs per call of each update inside a simulation, and µs per simulated step."""
    updates = UPDATES if compensator is None else {**UPDATES, **COMPENSATION_UPDATES}
    totals = {name: [0, 0] for name in updates}
    originals = {name: getattr(cls, method) for name, (cls, method) in updates.items()}

    def timer(name, original):
        def update(self, *args):
            start = time.perf_counter_ns()
            original(self, *args)
            totals[name][0] += time.perf_counter_ns() - start
            totals[name][1] += 1
        return update

    for name, (cls, method) in updates.items():
        setattr(cls, method, timer(name, originals[name]))
    try:
        sim = build_station(config, compensator, trajectory=trajectory)
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
        for name, (cls, method) in updates.items():
            setattr(cls, method, originals[name])
    per_call = {name: ns / max(n, 1) / 1e3 for name, (ns, n) in totals.items()}
    # The noisy sensor's update evaluates its input, so it includes the ideal sensor's call.
    per_call["noisy sensor"] -= per_call["ideal sensor"]
    return per_call, step_us, sim, simulator


def _time_hot_and_cold(calls_of, calls):
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


def _update_call(system, root, method):
    """The update `method` of `system` on its context in `root`, into a scratch copy of its
    discrete state (so the timings hold no allocation of ours)."""
    context = system.GetMyContextFromRoot(root)
    scratch = context.get_discrete_state().Clone()
    update = getattr(system, method)
    return lambda: update(context, scratch)


def hot_and_cold(sim, simulator, calls=2000):
    """µs per call of each update on the simulation's final context, hot and cold."""
    root = simulator.get_context()
    wrench = BasicVector(6)
    sensor_context = sim.sensor.GetMyContextFromRoot(root)
    calls_of = {
        "ideal sensor": lambda: sim.sensor._calc_wrench(sensor_context, wrench),
        "noisy sensor": _update_call(sim.noisy_sensor, root, "_sample"),
        "contact truth": _update_call(sim.truth, root, "_sample"),
    }
    if sim.compensation is not None:
        calls_of["compensator"] = _update_call(sim.compensation.compensator, root, "_update")
        if sim.compensation.tracker is not None:
            calls_of["bias tracker"] = _update_call(sim.compensation.tracker, root, "_update")
        calls_of["detector"] = _update_call(sim.compensation.detector, root, "_update")
    return _time_hot_and_cold(calls_of, calls)


def free_motion(duration):
    config = ScenarioConfig()
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = duration + 1.0
    trajectory = plan_trajectory(config)
    per_call, step_us, sim, simulator = timed_simulation(config, trajectory, duration)
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
        "load_average_1min": os.getloadavg()[0],
    }))


def compensation(duration, repeats):
    """The contact scenario with the forest and the hybrid, interleaved runs, medians."""
    models = dict(zip(("forest", "hybrid"), demo_models(), strict=True))
    config = ScenarioConfig()
    trajectory = plan_trajectory(config)  # once: the same motion for every run
    runs = {name: [] for name in models}
    for _ in range(repeats):
        for name, model in models.items():
            per_call, step_us, sim, simulator = timed_simulation(config, trajectory, duration,
                                                                 model)
            outside = hot_and_cold(sim, simulator)
            runs[name].append((per_call, step_us, outside))
    names = list(UPDATES) + list(COMPENSATION_UPDATES)
    table = {}
    for model, samples in runs.items():
        per_call = {k: float(np.median([s[0][k] for s in samples])) for k in names}
        step = float(np.median([s[1] for s in samples]))
        table[model] = {
            "step_us": step, "in_simulation_us": per_call,
            "rest_us": step - sum(per_call.values()),
            "hot_us": {k: float(np.median([s[2][k][0] for s in samples])) for k in names},
            "cold_us": {k: float(np.median([s[2][k][1] for s in samples])) for k in names},
        }
    print(f"contact scenario, 1 kHz, medians of {repeats} interleaved runs of {duration:g} s "
          f"(load average {os.getloadavg()[0]:.2f})")
    header = "".join(f"{m + ' ' + c:>16}" for m in models for c in ("in sim", "hot"))
    print(f"{'µs per step':<22}{header}")
    for name in names:
        print(f"{name:<22}" + "".join(
            f"{table[m]['in_simulation_us'][name]:>16.1f}{table[m]['hot_us'][name]:>16.1f}"
            for m in models))
    print(f"{'rest of the step':<22}" + "".join(f"{table[m]['rest_us']:>16.1f}{'':>16}"
                                              for m in models))
    print(f"{'whole step':<22}" + "".join(f"{table[m]['step_us']:>16.1f}{'':>16}"
                                        for m in models))
    print(json.dumps({"benchmark": "loop_costs_compensation", "repeats": repeats,
                      "load_average_1min": os.getloadavg()[0], **table}))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--compensation", action="store_true",
                        help="the contact scenario with the forest and the hybrid in the loop")
    parser.add_argument("--repeats", type=int, default=2,
                        help="interleaved runs per model with --compensation")
    args = parser.parse_args()
    if args.compensation:
        compensation(args.duration, args.repeats)
    else:
        free_motion(args.duration)


if __name__ == "__main__":
    main()
