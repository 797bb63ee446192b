"""Real-time factor of the free-motion diagram at 1 kHz (goal: >= 10x real time on 2 cores).

Prints a small table and one JSON line. In the same run it also times the diagram without
ftdrake's Python systems (plant + controller only), so the cost of the sensor, cable and
contact-truth systems shows as a ratio that does not depend on the machine's load; and the
core plus one Python system whose 1 kHz update only reads a constant input and writes
nothing: the least any Python system in the loop can cost, i.e. the ceiling for a diagram
that runs any Python code every step.

    python benchmarks/realtime_factor.py [--duration 10] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource

from ftdrake import ScenarioConfig, build_station
from ftdrake.sim.scene import add_scene, make_control_plant
from ftdrake.sim.simulate import set_initial_state
from ftdrake.sim.station import plan_trajectory
from ftdrake.systems.controller import DiscreteInverseDynamicsController


def time_full(config, trajectory, duration):
    sim = build_station(config, trajectory=trajectory)
    simulator = Simulator(sim.diagram)
    set_initial_state(sim, simulator.get_mutable_context())
    simulator.Initialize()
    simulator.AdvanceTo(0.05)  # warm-up (numba, caches)
    start = time.perf_counter()
    simulator.AdvanceTo(0.05 + duration)
    return duration / (time.perf_counter() - start)


class EmptyUpdate(LeafSystem):
    """A Python system whose periodic update reads its 6-vector input and does nothing else."""

    def __init__(self, period):
        super().__init__()
        self._input = self.DeclareVectorInputPort("u", 6)
        self.DeclareDiscreteState(6)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)

    def _update(self, context, discrete_state):
        del discrete_state  # Drake's update callback signature; this system writes no state
        self._input.Eval(context)


def time_plant_and_controller(config, trajectory, duration, python_floor=False):
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant
    q = builder.AddSystem(TrajectorySource(trajectory, output_derivative_order=1))
    vd = builder.AddSystem(TrajectorySource(trajectory.derivative(2)))
    c = config.controller
    controller = builder.AddSystem(DiscreteInverseDynamicsController(
        make_control_plant(config, scene), c.kp, c.ki, c.kd, config.time_step))
    builder.Connect(plant.get_state_output_port(scene.arm),
                    controller.get_input_port_estimated_state())
    builder.Connect(q.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(vd.get_output_port(), controller.get_input_port_desired_acceleration())
    builder.Connect(controller.get_output_port_control(), plant.get_actuation_input_port(scene.arm))
    if python_floor:
        source = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
        empty = builder.AddSystem(EmptyUpdate(config.time_step))
        builder.Connect(source.get_output_port(), empty.get_input_port())
    simulator = Simulator(builder.Build())
    plant.SetPositions(plant.GetMyMutableContextFromRoot(simulator.get_mutable_context()),
                       scene.arm, trajectory.value(0).ravel())
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration)
    return duration / (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    config = ScenarioConfig()
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = args.duration + 1.0
    trajectory = plan_trajectory(config)
    full = [time_full(config, trajectory, args.duration) for _ in range(args.repeats)]
    # The same diagram with the sensor (and so every Python system) sampled at 500 Hz.
    config_500 = ScenarioConfig()
    config_500.sensor.rate_hz = 500.0
    half = [time_full(config_500, trajectory, args.duration) for _ in range(args.repeats)]
    core, floor = [], []
    for _ in range(args.repeats):  # interleaved, so both see the same machine load
        core.append(time_plant_and_controller(config, trajectory, args.duration))
        floor.append(time_plant_and_controller(config, trajectory, args.duration, True))
    result = {
        "benchmark": "free_motion_realtime_factor",
        "plant_rate_hz": 1.0 / config.time_step,
        "sensor_rate_hz": config.sensor.spec().rate_hz,
        "simulated_s": args.duration,
        "rtf_full_median": float(np.median(full)),
        "rtf_plant_controller_only_median": float(np.median(core)),
        "rtf_full_sensor_500hz_median": float(np.median(half)),
        "rtf_core_plus_one_empty_python_update_median": float(np.median(floor)),
        "python_systems_cost_ratio": float(np.median(core) / np.median(full)),
        "goal_rtf": 10.0,
        "machine": f"{platform.machine()} {os.cpu_count()} cpus, {platform.python_version()}",
    }
    print(f"{'diagram':<36}{'real-time factor (median)':>28}")
    print(f"{'full (sensor, cable, truth, loggers)':<36}{result['rtf_full_median']:>28.1f}")
    print(f"{'full, sensor at 500 Hz':<36}{result['rtf_full_sensor_500hz_median']:>28.1f}")
    print(f"{'plant + controller only':<36}{result['rtf_plant_controller_only_median']:>28.1f}")
    print(f"{'  + one empty Python update':<36}"
          f"{result['rtf_core_plus_one_empty_python_update_median']:>28.1f}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
