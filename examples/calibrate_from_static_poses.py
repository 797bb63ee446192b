"""Calibrate a wrist F/T sensor from static poses: the tool's mass and centre of mass and the
sensor's six biases, each with its standard error.

A calibration log is a table: one row per pose held still, the sensor's orientation and the
wrench read there. Here the orientation is given as gravity in the sensor frame S (columns
``gx, gy, gz``, m/s²; ``qw..qz``, ``r00..r22``, ``roll, pitch, yaw`` or joint angles with a
robot work too) and the readings are made from a known tool, so the result can be checked.
With your robot, write your poses and readings in the same columns (``meas_Fx`` .. ``meas_Tz``,
N and N·m: the load the tool applies to the sensor, in S).

Run:  python examples/calibrate_from_static_poses.py        (the command: ftdrake calibrate)
"""

import numpy as np
import pandas as pd

import ftdrake

MASS = 1.2  # kg
COM_S = np.array([0.010, -0.005, 0.060])  # m, from the sensor origin, in S
BIAS = np.array([0.8, -0.4, 1.5, 0.02, -0.01, 0.005])  # N, N·m
NOISE = np.array([0.05, 0.05, 0.05, 0.002, 0.002, 0.002])  # N, N·m (one reading's σ)


def static_poses(n: int = 40, seed: int = 0) -> pd.DataFrame:
    """Readings of the tool held still in `n` random orientations."""
    rng = np.random.default_rng(seed)
    g_S = rng.normal(size=(n, 3))
    g_S *= 9.81 / np.linalg.norm(g_S, axis=1, keepdims=True)  # gravity in S, m/s²
    force = MASS * g_S  # at rest the sensor reads the tool's weight ...
    torque = np.cross(COM_S, force)  # ... and its moment about the sensor origin
    reading = np.hstack([force, torque]) + BIAS + rng.normal(size=(n, 6)) * NOISE
    table = pd.DataFrame(g_S, columns=["gx", "gy", "gz"])
    for k, axis in enumerate(ftdrake.WRENCH_AXES):
        table[f"meas_{axis}"] = reading[:, k]
    return table


def main():
    table = static_poses()
    calibration = ftdrake.calibrate_table(table)
    print(calibration.summary())
    com = calibration.com
    print(f"identified mass: {calibration.parameters[0]:.4f} kg (true {MASS})")
    print(f"identified centre of mass: {np.round(1e3 * com, 2)} mm (true {1e3 * COM_S} mm)")

    held_out = static_poses(n=100, seed=1)  # new poses: predict what the sensor reads there
    reading = held_out[[f"meas_{a}" for a in ftdrake.WRENCH_AXES]].to_numpy()
    rms = np.sqrt(np.mean((calibration.predict(held_out) - reading) ** 2, axis=0))
    print(f"held-out residual / noise σ per axis: {np.round(rms / NOISE, 2)}")


if __name__ == "__main__":
    main()
