"""Real-time factor of the contact scenario with compensator and detector in the loop at 1 kHz
(goal >= 10x), for a compiled forest and for the hybrid (physics + forest residual), each with
the bias tracker (the default) and without it, and the hybrid with the tracker also
estimating a payload (``bias_tracker.track_payload``). Interleaved repeats (``--repeats``,
default 3), medians; the per-system cost of a step is printed by
``loop_costs.py --compensation``.

Trains small models on a little simulated data first (not timed). In the same run it times
the same scenario without compensation, so the cost of the loop shows as a ratio.

    python benchmarks/closed_loop_rtf.py
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import os
import platform
import time

import numpy as np
from pydrake.systems.analysis import Simulator

from ftdrake import ScenarioConfig, build_station
from ftdrake.sim.simulate import set_initial_state
from ftdrake.testing import demo_models

REPEATS = 3


def rtf(config, compensator=None, duration=6.0, detections=None):
    """Real-time factor of `duration` s after a warm-up; appends to `detections` (if given) the
    fraction of samples the detector reported a contact the truth did not have (a false
    contact freezes the bias tracker, which then does less work per sample)."""
    sim = build_station(config, compensator)
    simulator = Simulator(sim.diagram)
    set_initial_state(sim, simulator.get_mutable_context())
    simulator.Initialize()
    simulator.AdvanceTo(0.05)  # warm-up
    start = time.perf_counter()
    simulator.AdvanceTo(0.05 + duration)
    factor = duration / (time.perf_counter() - start)
    if detections is not None and sim.compensation is not None:
        context = simulator.get_context()
        detected = sim.compensation.loggers["contact"].FindLog(context).data()[0]
        truth = sim.loggers.contact_true.FindLog(context).data()[0]
        n = min(len(detected), len(truth))
        detections.append(float(np.mean((detected[:n] > 0.5) & (truth[:n] < 0.5))))
    return factor


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=REPEATS)
    args = parser.parse_args()
    forest, hybrid = demo_models()
    load_before = os.getloadavg()[0]
    config = ScenarioConfig()
    untracked = config.with_chain(bias_tracker=dc.replace(config.chain.bias_tracker, enabled=False))
    payload = config.with_chain(bias_tracker=dc.replace(config.chain.bias_tracker,
                                                         track_payload=True))
    cases = {
        "no_compensation": (config, None),
        "forest": (config, forest),
        "hybrid": (config, hybrid),
        "forest_without_tracker": (untracked, forest),
        "hybrid_without_tracker": (untracked, hybrid),
        # The tracker also estimating a payload (the grasp experiment's setting): it reads
        # SensorGravity (body poses and accelerations from the plant) every sample.
        "hybrid_payload_tracking": (payload, hybrid),
    }
    # Interleaved repeats, median: the machine's load drifts during a run.
    samples = {name: [] for name in cases}
    detected = {name: [] for name in cases}
    for _ in range(args.repeats):
        for name, (c, model) in cases.items():
            samples[name].append(rtf(c, model, detections=detected[name]))
    result = {
        "benchmark": "closed_loop_realtime_factor",
        **{f"rtf_{name}": float(np.median(v)) for name, v in samples.items()},
        "repeats": args.repeats,
        "goal_rtf": 10.0,
        "machine": f"{platform.machine()} {os.cpu_count()} cpus, {platform.python_version()}",
        "load_average_1min": [load_before, os.getloadavg()[0]],  # before, after the runs
        "false_contact_fraction": {name: float(np.mean(v)) for name, v in detected.items() if v},
    }
    for suffix in ("", "_without_tracker"):
        forest_rtf, hybrid_rtf = result[f"rtf_forest{suffix}"], result[f"rtf_hybrid{suffix}"]
        result[f"hybrid_over_forest{suffix}"] = hybrid_rtf / forest_rtf
        # What the hybrid costs more (or less) than the forest per simulated 1 ms step.
        result[f"hybrid_minus_forest_us_per_step{suffix}"] = 1e3 * (1 / hybrid_rtf
                                                                     - 1 / forest_rtf)
    print(f"{'diagram (contact scenario, 1 kHz)':<40}{'real-time factor':>18}"
          f"{'false contact':>15}")
    for name in cases:
        share = result["false_contact_fraction"].get(name)
        print(f"{name:<40}{result[f'rtf_{name}']:>18.2f}"
              + (f"{share:>15.0%}" if share is not None else ""))
    for suffix in ("", "_without_tracker"):
        print(f"{'hybrid / forest' + suffix.replace('_', ' '):<40}"
              f"{result['hybrid_over_forest' + suffix]:>18.2f}"
              f"   ({result['hybrid_minus_forest_us_per_step' + suffix]:+.1f} µs per step)")
    print(f"goal hybrid >= forest: {'met' if result['hybrid_over_forest'] >= 1 else 'NOT met'}"
          f" (load average {load_before:.2f} before, {os.getloadavg()[0]:.2f} after)")
    print(json.dumps(result))


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
