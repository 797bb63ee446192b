"""Running a built diagram and turning its loggers into one table.

Log columns (one row per sensor sample; units SI; wrenches in S about So):

==================  ============================================================
``t``               time, s
``q_i``             joint i position, rad (plant state)
``qd_i``            joint i velocity, rad/s (plant state)
``qdd_i``           joint i acceleration, rad/s² (the plant's step)
``qd_est_i``        velocity as a real robot gets it: central difference of sampled q
``qdd_est_i``       acceleration likewise, from ``qd_est``
``ideal_*``         ideal sensor wrench (rigid-body reaction at the weld)
``meas_*``          noisy sensor reading
``internal_*``      true internal wrench: what the sensor would read without contact, with
                    its cross-talk and bias but without white noise, drift, filter and
                    quantization (``C·(ideal − external) + bias``)
``external_*``      true contact wrench on the tool from ContactResults
``contact``         1 while the tool touches the environment
``saturated``       1 while any sensor axis is at its range limit
==================  ============================================================

The plant's sampled output ports read zero before its first step, so the row at t = 0 is
dropped (and only that row): every log starts at the first sensor sample after t = 0.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
from pydrake.systems.analysis import Simulator
from tqdm.auto import tqdm

from . import columns as col
from .diagram import Simulation


def run(sim: Simulation, *, progress: bool = True, duration: float | None = None,
        realtime_rate: float = 0.0) -> tuple[pd.DataFrame, dict]:
    """Simulates `sim` for its trajectory's duration; returns (log, timing summary)."""
    duration = sim.trajectory.end_time() if duration is None else float(duration)
    simulator = Simulator(sim.diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    set_initial_state(sim, simulator.get_mutable_context())
    simulator.Initialize()
    chunk = 0.25  # s between progress updates
    start = time.perf_counter()
    with tqdm(total=round(duration, 3), unit="sim s", disable=not progress,
              desc="simulating", leave=False) as bar:
        t = 0.0
        while t < duration - 1e-9:
            t = min(duration, t + chunk)
            simulator.AdvanceTo(t)
            bar.update(round(t - bar.n, 3))
    wall = time.perf_counter() - start
    sim.simulator = simulator  # keeps the final context alive for further logs
    log = assemble_log(sim, simulator.get_context())
    return log, {
        "duration_s": duration,
        "wall_time_s": wall,
        "real_time_factor": duration / wall if wall > 0 else float("inf"),
        "samples": len(log),
    }


def set_initial_state(sim: Simulation, root_context) -> None:
    """Puts the arm at the trajectory's start, moving with its start velocity."""
    plant = sim.scene.plant
    plant_context = plant.GetMyMutableContextFromRoot(root_context)
    t0 = sim.trajectory.start_time()
    plant.SetPositions(plant_context, sim.scene.arm, sim.trajectory.value(t0).ravel())
    plant.SetVelocities(
        plant_context, sim.scene.arm, sim.trajectory.derivative(1).value(t0).ravel()
    )


def assemble_log(sim: Simulation, root_context) -> pd.DataFrame:
    """The loggers' contents as one DataFrame with the documented columns."""
    n = sim.scene.plant.num_positions(sim.scene.arm)

    def data(logger):
        log = logger.FindLog(root_context)
        return log.sample_times(), log.data().T

    t, x = data(sim.loggers.state)
    keep = t > 0.5 * sim.config.time_step  # see module docstring: drop the t = 0 row
    series = {"t": t, "x": x}
    for name in ("acceleration", "ideal", "measured", "saturated", "external", "contact"):
        ti, values = data(getattr(sim.loggers, name))
        if len(ti) != len(t) or not np.allclose(ti, t):
            raise RuntimeError(f"logger {name!r} is not sampled with the state logger")
        series[name] = values
    frame = {col.TIME: t[keep]}
    q, qd = x[keep, :n], x[keep, n:]
    qd_est, qdd_est = differentiate(t[keep], q)
    for prefix, values in (
        (col.Q, q), (col.QD, qd), (col.QDD, series["acceleration"][keep]),
        (col.QD_EST, qd_est), (col.QDD_EST, qdd_est),
    ):
        frame.update(zip(col.joint_columns(prefix, n), values.T))
    internal_physical = series["ideal"] - series["external"]
    internal = sim.noisy_sensor.deterministic_reading(internal_physical)
    for prefix, values in (
        (col.IDEAL, series["ideal"]), (col.MEASURED, series["measured"]),
        (col.INTERNAL, internal), (col.EXTERNAL, series["external"]),
    ):
        frame.update(zip(col.wrench_columns(prefix), values[keep].T))
    frame[col.CONTACT] = series["contact"][keep, 0].astype(np.int8)
    frame[col.SATURATED] = series["saturated"][keep, 0].astype(np.int8)
    return pd.DataFrame(frame)


def differentiate(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration from sampled positions by central differences (as the study
    did: "the joints velocities and accelerations have been numerically differentiated")."""
    if len(t) < 3:
        return np.zeros_like(q), np.zeros_like(q)
    qd = np.gradient(q, t, axis=0)
    return qd, np.gradient(qd, t, axis=0)
