"""Names and constants every layer shares: gravity, the wrench order, every log column name.

One place defines them so that `simulate`, `collect`, `train`, `evaluate`, the plots and the
command line agree. The column strings are part of the saved datasets' format: renaming one
breaks reading older files.

Units: time in s, joint positions in rad, velocities in rad/s, accelerations in rad/s²,
forces in N, torques in N·m. Wrenches are ordered ``[Fx, Fy, Fz, Tx, Ty, Tz]`` and are
expressed in the sensor frame S about its origin So (see :mod:`ftdrake.systems.ft_sensor`).
"""

from __future__ import annotations

import dataclasses as dc

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
SATURATED = "saturated"  # 1 while any sensor axis is at its range limit
TEMPERATURE = "temperature"  # the sensor's temperature, °C (many sensors report it)
PUSH_FORCE = "push_force"  # ‖F‖ of a scenario's push at the tool tip, N

# -- Simulated truth (what only a simulation knows; marked ``_true``) -------------------------
CONTACT_TRUE = "contact_true"  # 1 while the tool touches the environment (the plant's truth)
INTERNAL_TRUE = "internal_true"  # what the sensor would read without contact, noise and drift aside
EXTERNAL_TRUE = "external_true"  # true contact wrench on the tool, about So, in S

# -- Wrench column prefixes of the sensor (six columns each, see wrench_columns) -----------------
MEASURED = "meas"  # what the noisy sensor outputs
IDEAL = "ideal"  # rigid-body reaction at the weld (a simulation's; no sensor imperfections)
OFFSET = "offset"  # the sensor driver's zero offset (a re-tare event)

# -- Joint-state prefixes (one column per joint, see joint_columns) -----------------------------
# `q`, `qd`, `qdd` are what the plant knows; the `_est` versions are what the loop's
# compensator gets: the joint state's velocity and its causal q̈ estimate
# (signals.causal_acceleration; the simulator's logs and the hardware recorder alike).
Q, QD, QDD = "q", "qd", "qdd"
QD_EST, QDD_EST = "qd_est", "qdd_est"
TORQUE = "tau"  # joint efforts read from a robot's JointState topic, N·m


# -- An IMU at the sensor (``scenario.imu``; three columns each, see imu_columns) --------------
# At So, axes along S. ``imu_acc``: the accelerometer's proper acceleration of So in S, m/s²
# (Drake's convention: a − g, so +9.81 *up* at rest); ``imu_gyro``: ω of S in S, rad/s;
# ``imu_alpha``: the angular acceleration of S in S, rad/s², the causal filtered derivative of
# imu_gyro (derived, as qdd_est is from qd).
IMU_ACC, IMU_GYRO, IMU_ALPHA = "imu_acc", "imu_gyro", "imu_alpha"
IMU_AXES = ("x", "y", "z")


def imu_columns(prefix: str) -> list[str]:
    """``imu_acc`` → ``["imu_acc_x", "imu_acc_y", "imu_acc_z"]``."""
    return [f"{prefix}_{a}" for a in IMU_AXES]


#: The nine IMU columns a compensator with an IMU takes after ``[q, q̇, q̈]``, in order.
IMU_INPUTS = (*imu_columns(IMU_ACC), *imu_columns(IMU_GYRO), *imu_columns(IMU_ALPHA))


def joint_columns(prefix: str, n: int = N_JOINTS) -> list[str]:
    """``q`` → ``["q_0", ..., "q_{n-1}"]``."""
    return [f"{prefix}_{i}" for i in range(n)]


def wrench_columns(prefix: str) -> list[str]:
    """``meas`` → ``["meas_Fx", ..., "meas_Tz"]``."""
    return [f"{prefix}_{a}" for a in WRENCH_AXES]


# -- The chain's outputs: one name per signal -----------------------------------------------------
@dc.dataclass(frozen=True)
class ChainOutput:
    """One output port of :class:`~ftdrake.runtime.chain.CompensationChain` and every name it
    has outside the diagram: its log column(s), where LCM carries it and its ROS 2 topic.

    `lcm`: ``"CHANNEL"`` (the whole message on channel ``hardware.output_prefix + CHANNEL``)
    or ``"CHANNEL.field"`` (the value named `field` of an ``lcmt_drake_signal`` on that
    channel); `ros2`: the topic under ``ros2.output_namespace``, or ``"/diagnostics.key"``
    (a key of the DiagnosticStatus). None: not published. Both stations publish exactly the
    outputs that have both (:data:`PUBLISHED`)."""

    port: str
    size: int
    columns: tuple[str, ...]
    lcm: str | None
    ros2: str | None
    meaning: str
    unit: str
    flag: bool = False  # a 0/1 flag, logged as int8

    @property
    def lcm_channel(self) -> str | None:
        """The channel's name after ``hardware.output_prefix`` (None: not on LCM)."""
        return None if self.lcm is None else self.lcm.partition(".")[0]

    @property
    def lcm_field(self) -> str | None:
        """The value's name in the channel's ``lcmt_drake_signal`` (None: the whole message)."""
        return None if self.lcm is None else (self.lcm.partition(".")[2] or None)


def _wrench(port: str, lcm: str | None, ros2: str | None, meaning: str) -> ChainOutput:
    return ChainOutput(port, 6, tuple(wrench_columns(port)), lcm, ros2, meaning, "N, N·m")


def _flag(port: str, ros2: str | None, meaning: str) -> ChainOutput:
    return ChainOutput(port, 1, (port,), f"CONTACT_STATE.{port}", ros2, meaning, "0/1", True)


#: Every output port of the chain with its names (see ChainOutput), in the order of the log's
#: columns and of the values in the LCM contact state. Estimates carry the port's name; the
#: simulation's truth is marked ``_true`` (above).
CHAIN_OUTPUTS = (
    _wrench("wrench_internal", None, None,
            "the model's internal wrench as the sensor reads it"),
    _wrench("wrench_compensated", "WRENCH_COMPENSATED", "wrench_compensated",
            "measured − internal, in S: the compensator's own output"),
    _wrench("wrench_contact", "WRENCH_CONTACT", "wrench_contact",
            "the contact wrench the detector judges: compensated − the tracker's bias and "
            "payload wrench (= wrench_compensated without the tracker)"),
    _wrench("wrench_std", None, None, "the model's predictive std (0 where it gives none)"),
    _flag("contact", "contact", "the detector's contact flag"),
    ChainOutput("contact_force", 1, ("contact_force",), "CONTACT_STATE.contact_force",
                "contact_force", "‖F‖ of wrench_contact while in contact, else 0", "N"),
    _flag("fault", "/diagnostics.fault", "1 while the compensator's inputs held NaN/inf "
          "(published live: also while an input stream is faulted)"),
    _flag("out_of_domain", "/diagnostics.out_of_domain",
          "1 while a joint input is outside the training range"),
    _wrench("bias", "BIAS", "bias", "the bias tracker's published bias (with the tracker)"),
    _wrench("tracker_std", None, None,
            "the std of what the tracker subtracts, bias and payload wrench (with the tracker)"),
    ChainOutput("payload", 4, ("payload_dm", "payload_mcx", "payload_mcy", "payload_mcz"),
                "PAYLOAD", "payload", "the tracker's payload estimate [Δm, Δ(m·c)] about So in S "
                "(with bias_tracker.track_payload)", "kg, kg·m"),
    _flag("payload_change", "/diagnostics.payload_change",
          "1 for a while after an unsignalled payload change (with "
          "bias_tracker.payload_change.enabled)"),
    ChainOutput("payload_state", 1, ("payload_state",), None, None,
                "the payload-change monitor's decision on a change of the contact wrench: 0 none, "
                "1 undecided (the tool has not turned enough to tell a weight from a press), "
                "2 payload change (not reported as contact), 3 contact (with "
                "bias_tracker.payload_change.enabled)", "0–3 code"),
)
OUTPUTS = {o.port: o for o in CHAIN_OUTPUTS}
#: The ports both live stations publish (LCM and ROS 2 alike).
PUBLISHED = tuple(o.port for o in CHAIN_OUTPUTS if o.lcm is not None and o.ros2 is not None)

# Column names of the chain's outputs (the table's, for the code that reads logs).
WRENCH_INTERNAL, WRENCH_COMPENSATED, WRENCH_CONTACT, WRENCH_STD, BIAS, TRACKER_STD = (
    "wrench_internal", "wrench_compensated", "wrench_contact", "wrench_std", "bias",
    "tracker_std")  # wrench prefixes (wrench_columns)
OUT_OF_DOMAIN, FAULT, CONTACT, CONTACT_FORCE, PAYLOAD_CHANGE, PAYLOAD_STATE = (
    "out_of_domain", "fault", "contact", "contact_force", "payload_change", "payload_state")
PAYLOAD = OUTPUTS["payload"].columns  # Δm (kg) and Δ(m·c) (kg·m, about So in S)


# -- The log format and the names older logs used -------------------------------------------------
#: The version of the log layout (the Parquet metadata key ``ftdrake.log_format``). 1: the
#: names before :data:`CHAIN_OUTPUTS` (``pred_*``, ``est_external_*``, ``detected``, and
#: ``contact``/``internal_*``/``external_*`` for the truth); 2: the names above.
LOG_FORMAT = 2
#: Format-1 column → its name now (applied when a log or dataset is read).
LEGACY_COLUMNS = {
    **{old: new for old_prefix, new_prefix in (
        ("pred", WRENCH_INTERNAL), ("comp_external", WRENCH_COMPENSATED),
        ("est_external", WRENCH_CONTACT), ("pred_std", WRENCH_STD), ("bias_est", BIAS),
        ("internal", INTERNAL_TRUE), ("external", EXTERNAL_TRUE))
       for old, new in zip(wrench_columns(old_prefix), wrench_columns(new_prefix), strict=True)},
    **dict(zip(("payload_est_dm", "payload_est_mcx", "payload_est_mcy", "payload_est_mcz"),
               PAYLOAD, strict=True)),
    "detected": CONTACT, "detected_force": CONTACT_FORCE, "contact": CONTACT_TRUE,
}


def legacy_renames(columns, log_format: int | None = None) -> dict[str, str]:
    """The renames that bring a log with `columns` to :data:`LOG_FORMAT` (empty: already
    there). `log_format`: the version the file says (None: unknown, e.g. a CSV file; then the
    log is format 1 when it has a column only format 1 has, such as ``pred_Fx`` or
    ``detected`` — ``contact`` alone does not tell, since both formats have it)."""
    columns = [str(c) for c in columns]
    if log_format is None:
        legacy_only = set(LEGACY_COLUMNS) - set(LEGACY_COLUMNS.values())
        log_format = 1 if legacy_only.intersection(columns) else LOG_FORMAT
    if log_format >= LOG_FORMAT:
        return {}
    return {c: LEGACY_COLUMNS[c] for c in columns if c in LEGACY_COLUMNS}


def signal_table_markdown() -> str:
    """:data:`CHAIN_OUTPUTS` as a Markdown table (the docs render it from here)."""
    rows = ["| port | size | log column(s) | LCM | ROS 2 | meaning | unit |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    for o in CHAIN_OUTPUTS:
        columns = (f"`{o.port}_Fx` … `{o.port}_Tz`" if o.columns == tuple(wrench_columns(o.port))
                   else ", ".join(f"`{c}`" for c in o.columns))
        lcm = "–" if o.lcm is None else (
            f"`{o.lcm_channel}` (`lcmt_force_torque`)" if o.size == 6 else
            f"`{o.lcm_channel}` (`lcmt_drake_signal`: `{o.lcm_field}`)" if o.lcm_field else
            f"`{o.lcm_channel}` (`lcmt_drake_signal`: " + ", ".join(o.columns) + ")")
        ros2 = "–" if o.ros2 is None else (
            f"`/diagnostics` key `{o.ros2.partition('.')[2]}`" if o.ros2.startswith("/")
            else f"`<ns>/{o.ros2}` (`{ROS2_TYPES[o.port]}`)")
        rows.append(f"| `{o.port}` | {o.size} | {columns} | {lcm} | {ros2} | {o.meaning} | "
                    f"{o.unit} |")
    return "\n".join(rows)


#: The ROS 2 message type of each output published on a topic of its own.
ROS2_TYPES = {"wrench_compensated": "geometry_msgs/msg/WrenchStamped",
              "wrench_contact": "geometry_msgs/msg/WrenchStamped",
              "bias": "geometry_msgs/msg/WrenchStamped",
              "contact": "std_msgs/msg/Bool", "contact_force": "std_msgs/msg/Float64",
              "payload": "geometry_msgs/msg/InertiaStamped"}
