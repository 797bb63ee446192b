"""Real-time factor of the contact scenario with compensator and detector in the loop at 1 kHz
(goal >= 10x), for a compiled forest and for the hybrid (physics + forest residual).

Trains small models on a little simulated data first (not timed). In the same run it times
the same scenario without compensation, so the cost of the loop shows as a ratio.

    python benchmarks/closed_loop_rtf.py
"""

from __future__ import annotations

import json
import os
import platform
import time
import warnings

import numpy as np
from pydrake.systems.analysis import Simulator

from ftdrake import HybridCompensator, RandomForestCompensator, ScenarioConfig, build_station
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.sim.collection import collect
from ftdrake.sim.simulate import set_initial_state


def rtf(config, compensator=None, duration=6.0):
    sim = build_station(config, compensator)
    simulator = Simulator(sim.diagram)
    set_initial_state(sim, simulator.get_mutable_context())
    simulator.Initialize()
    simulator.AdvanceTo(0.05)  # warm-up
    start = time.perf_counter()
    simulator.AdvanceTo(0.05 + duration)
    return duration / (time.perf_counter() - start)


def main():
    data = collect(ScenarioConfig(), 2, kind="fourier", duration=8.0, progress=False)
    X, Y = joint_state_layout(data)[::4], wrench_targets(data)[::4]
    forest = RandomForestCompensator(features="q", n_estimators=40, per_output=False,
                                     random_state=0).fit(X, Y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hybrid = HybridCompensator(residual=forest).fit(X, Y)
    config = ScenarioConfig()
    result = {
        "benchmark": "closed_loop_realtime_factor",
        "rtf_no_compensation": rtf(config),
        "rtf_forest_in_loop": rtf(config, forest),
        "rtf_hybrid_in_loop": rtf(config, hybrid),
        "goal_rtf": 10.0,
        "machine": f"{platform.machine()} {os.cpu_count()} cpus, {platform.python_version()}",
        "load_average_1min": os.getloadavg()[0],
    }
    result["forest_loop_cost_ratio"] = result["rtf_no_compensation"] / result["rtf_forest_in_loop"]
    print(f"{'diagram (contact scenario, 1 kHz)':<40}{'real-time factor':>18}")
    for key in ("rtf_no_compensation", "rtf_forest_in_loop", "rtf_hybrid_in_loop"):
        print(f"{key:<40}{result[key]:>18.1f}")
    print(json.dumps(result))


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
