"""Column names shared by simulated logs, datasets and real-robot logs.

One place defines them so that `simulate`, `collect`, `train` and `evaluate` agree.

Units: time in s, joint positions in rad, velocities in rad/s, accelerations in rad/s²,
forces in N, torques in N·m. Wrenches are ordered ``[Fx, Fy, Fz, Tx, Ty, Tz]`` and are
expressed in the sensor frame S about its origin So (see :mod:`ftdrake.systems.ft_sensor`).
"""

from __future__ import annotations

N_JOINTS = 7
WRENCH_AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
WRENCH_UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")

TIME = "t"
TRAJECTORY = "trajectory"
CONTACT = "contact"
SATURATED = "saturated"
TEMPERATURE = "temperature"  # the sensor's temperature, °C (many sensors report it)

# Wrench column prefixes.
MEASURED = "meas"  # what the noisy sensor outputs
IDEAL = "ideal"  # rigid-body reaction at the sensor weld (no sensor imperfections)
INTERNAL = "internal"  # what the sensor would read without contact, white noise and drift aside
EXTERNAL = "external"  # true contact wrench on the tool, about So, in S


def joint_columns(prefix: str, n: int = N_JOINTS) -> list[str]:
    """``q`` → ``["q_0", ..., "q_{n-1}"]``."""
    return [f"{prefix}_{i}" for i in range(n)]


def wrench_columns(prefix: str) -> list[str]:
    """``meas`` → ``["meas_Fx", ..., "meas_Tz"]``."""
    return [f"{prefix}_{a}" for a in WRENCH_AXES]


# Joint-state prefixes. `q`, `qd`, `qdd` are what the plant knows; the `_est` versions are
# what a real robot would have: velocities and accelerations differentiated numerically from
# sampled joint positions.
Q, QD, QDD = "q", "qd", "qdd"
QD_EST, QDD_EST = "qd_est", "qdd_est"
