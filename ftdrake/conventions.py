"""Names and constants every layer shares: gravity, the wrench order, every log column name.

One place defines them so that `simulate`, `collect`, `train`, `evaluate`, the plots and the
command line agree. The column strings are part of the saved datasets' format: renaming one
breaks reading older files.

Units: time in s, joint positions in rad, velocities in rad/s, accelerations in rad/s²,
forces in N, torques in N·m. Wrenches are ordered ``[Fx, Fy, Fz, Tx, Ty, Tz]`` and are
expressed in the sensor frame S about its origin So (see :mod:`ftdrake.systems.ft_sensor`).
"""

from __future__ import annotations

#: m/s²: the magnitude of gravity. Drake's MultibodyPlant simulates with
#: ``UniformGravityFieldElement.kDefaultStrength`` (9.81), so every model of the simulated
#: arm (physics compensators, calibration, the tracker's payload scale) uses the same value.
STANDARD_GRAVITY = 9.81
#: m/s²: gravity in the world frame W (z up), as the plant has it.
GRAVITY_W = (0.0, 0.0, -STANDARD_GRAVITY)

#: The loop's default cut-off for its q̈ estimate (Hz; ``compensator.acceleration_cutoff_hz``):
#: the white-noise gain of the first-order low-pass at 25 Hz it replaced, without its lag on a
#: q̈ ramp (the figures: docs/results/demo.md).
DEFAULT_ACCELERATION_CUTOFF_HZ = 12.0

N_JOINTS = 7
WRENCH_AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
WRENCH_UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")

# -- Scalar columns ----------------------------------------------------------------------------
TIME = "t"
TRAJECTORY = "trajectory"  # the run's id in a dataset of several runs
CONTACT = "contact"  # 1 while the tool touches the environment (the plant's truth)
SATURATED = "saturated"  # 1 while any sensor axis is at its range limit
TEMPERATURE = "temperature"  # the sensor's temperature, °C (many sensors report it)
PUSH_FORCE = "push_force"  # ‖F‖ of a scenario's push at the tool tip, N
OUT_OF_DOMAIN = "out_of_domain"  # 1 while a joint input is outside the training range
FAULT = "fault"  # 1 while the compensator's inputs held NaN/inf
DETECTED = "detected"  # the detector's contact flag
DETECTED_FORCE = "detected_force"  # the detector's ‖F‖ while in contact, N
PAYLOAD_CHANGE = "payload_change"  # an unsignalled payload change was recognised (0/1)

# -- Wrench column prefixes (six columns each, see wrench_columns) ------------------------------
MEASURED = "meas"  # what the noisy sensor outputs
IDEAL = "ideal"  # rigid-body reaction at the sensor weld (no sensor imperfections)
INTERNAL = "internal"  # what the sensor would read without contact, white noise and drift aside
EXTERNAL = "external"  # true contact wrench on the tool, about So, in S
OFFSET = "offset"  # the sensor driver's zero offset (a re-tare event)
PREDICTED = "pred"  # the compensator's predicted internal wrench
PREDICTED_STD = "pred_std"  # the model's predictive std (0 where it gives none)
COMPENSATED = "comp_external"  # measured − predicted: the compensator's own output
ESTIMATED = "est_external"  # the contact wrench the detector reads (after the bias tracker)
BIAS_ESTIMATE = "bias_est"  # the bias tracker's published bias

#: The bias tracker's payload estimate: Δm (kg) and Δ(m·c) (kg·m, about So in S).
PAYLOAD_ESTIMATE = ("payload_est_dm", "payload_est_mcx", "payload_est_mcy", "payload_est_mcz")

# -- Joint-state prefixes (one column per joint, see joint_columns) -----------------------------
# `q`, `qd`, `qdd` are what the plant knows; the `_est` versions are what the loop's
# compensator gets: the joint state's velocity and its causal q̈ estimate
# (signals.causal_acceleration; the simulator's logs and the hardware recorder alike).
Q, QD, QDD = "q", "qd", "qdd"
QD_EST, QDD_EST = "qd_est", "qdd_est"
TORQUE = "tau"  # joint efforts read from a robot's JointState topic, N·m


def joint_columns(prefix: str, n: int = N_JOINTS) -> list[str]:
    """``q`` → ``["q_0", ..., "q_{n-1}"]``."""
    return [f"{prefix}_{i}" for i in range(n)]


def wrench_columns(prefix: str) -> list[str]:
    """``meas`` → ``["meas_Fx", ..., "meas_Tz"]``."""
    return [f"{prefix}_{a}" for a in WRENCH_AXES]
