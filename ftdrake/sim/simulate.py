"""Running a built station and turning its loggers into one table.

Log columns (one row per sensor sample; units SI; wrenches in S about So):

======================  ============================================================
``t``                   time, s
``q_i``                 joint i position, rad (plant state; the motors' φ with
                        ``transmission.chain_reads_motors``, see :func:`motor_acceleration`)
``qd_i``                joint i velocity, rad/s (plant state, or the motors' φ̇)
``qdd_i``               joint i acceleration, rad/s² (the plant's step, or the motors')
``qd_est_i``            the velocity the loop uses: the joint state's own ``qd_i``
``qdd_est_i``           the loop's own q̈ estimate: :func:`ftdrake.signals.causal_acceleration`
                        of ``qd`` at ``compensator.acceleration_cutoff_hz``, row by row, as
                        the :class:`~ftdrake.runtime.compensator.CompensatorSystem` computes it
                        (the recorder's columns, :mod:`ftdrake.offline.recorder`)
``ideal_*``             ideal sensor wrench (rigid-body reaction at the weld)
``meas_*``              noisy sensor reading
``internal_true_*``     true internal wrench: what the sensor would read without contact, with
                        its mounting rotation, cross-talk, bias and thermal zero drift but
                        without white noise, random-walk drift, filter and quantization
                        (``C·R·(ideal − external) + bias + k·(T − T_ambient)``), in the
                        frame the sensor measures in
``external_true_*``     true contact wrench on the tool from ContactResults
``contact_true``        1 while the tool touches the environment
``saturated``           1 while any sensor axis is at its range limit
``temperature``         the sensor's temperature, °C
``offset_*``            the sensor driver's zero offset (with a ``events.retare_at_s``)
``push_force``          ‖F‖ of the ``events`` push at the tool tip, N (with a push)
``imu_acc_*``           with ``imu.enabled``: the IMU's proper acceleration of So in S,
                        m/s² (+9.81 up at rest; :mod:`ftdrake.systems.imu`), x, y, z
``imu_gyro_*``          with ``imu.enabled``: its angular velocity of S in S, rad/s
``imu_alpha_*``         with ``imu.enabled``: the causal derivative of ``imu_gyro_*``
                        (:func:`ftdrake.signals.causal_acceleration` at
                        ``imu.alpha_cutoff_hz``), rad/s²
======================  ============================================================

``meas_*`` is the reading the compensator gets (after a re-tare's offset); ``external_true_*``
includes an ``events`` push (as the sensor sees it) and ``internal_true_*`` the offset. The
columns marked ``_true`` are the simulation's truth, which no robot log has.

With a compensator in the station, also (same rows): the columns of every output port of the
runtime chain, named as :data:`ftdrake.conventions.CHAIN_OUTPUTS` says (``wrench_internal_*``,
``wrench_compensated_*``, ``wrench_contact_*``, ``wrench_std_*``, ``out_of_domain``,
``fault``, ``contact``, ``contact_force``, and with the bias tracker ``bias_*``,
``tracker_std_*``, ``payload_dm`` …, ``payload_change``), recorded by
:mod:`ftdrake.offline.recorder` as :func:`~ftdrake.offline.replay.replay` records them.

The plant's sampled output ports read zero before its first step, so the row at t = 0 is
dropped (and only that row): every log starts at the first sensor sample after t = 0.
"""

from __future__ import annotations

import dataclasses as dc
import time
import warnings

import numpy as np
import pandas as pd
from pydrake.systems.analysis import Simulator
from tqdm.auto import tqdm

from .. import conventions as col
from ..offline.recorder import logged_values, output_columns
from ..signals import causal_acceleration
from .events import apply_grasp
from .station import Station


@dc.dataclass
class SimResult:
    """What a simulation returns: its log, timing, and the final context (loggers, state)."""

    log: pd.DataFrame
    timing: dict  # duration_s, wall_time_s, real_time_factor, samples
    context: object  # the root Context at the end; keeps the simulator alive


def simulate(station: Station, *, progress: bool = True, duration: float | None = None,
             realtime_rate: float = 0.0, monitor=None) -> SimResult:
    """Simulates `station` for its trajectory's duration (or `duration` s). `monitor`: the
    Simulator's monitor, called after every step (e.g. a publisher of the robot's messages)."""
    duration = station.trajectory.end_time() if duration is None else float(duration)
    simulator = Simulator(station.diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    set_initial_state(station, simulator.get_mutable_context())
    if monitor is not None:
        simulator.set_monitor(monitor)
    simulator.Initialize()
    chunk = 0.25  # s between progress updates
    grasp_at = station.config.events.grasp_at_s
    start = time.perf_counter()
    with tqdm(total=round(duration, 3), unit="sim s", disable=not progress,
              desc="simulating", leave=False) as bar:
        t = 0.0
        while t < duration - 1e-9:
            t = min(duration, t + chunk)
            if grasp_at is not None and simulator.get_context().get_time() < grasp_at <= t:
                simulator.AdvanceTo(grasp_at)
                _grasp(station, simulator.get_mutable_context())
            simulator.AdvanceTo(t)
            bar.update(round(t - bar.n, 3))
    wall = time.perf_counter() - start
    context = simulator.get_context()
    log = assemble_log(station, context)
    timing = {
        "duration_s": duration,
        "wall_time_s": wall,
        "real_time_factor": duration / wall if wall > 0 else float("inf"),
        "samples": len(log),
    }
    return SimResult(log, timing, context)


def _grasp(station: Station, root_context) -> None:
    plant = station.scene.plant
    apply_grasp(station.config.events, station.scene,
                plant.GetMyMutableContextFromRoot(root_context))


def set_initial_state(station: Station, root_context) -> None:
    """Puts the arm where the controller holds it at the trajectory's start, moving with its
    start velocity (:func:`controller_equilibrium`), and starts the bias tracker as
    ``bias_tracker.start_settled`` says."""
    t0 = station.trajectory.start_time()
    q_d = station.trajectory.value(t0).ravel()
    v_d = station.trajectory.derivative(1).value(t0).ravel()
    _set_arm_state(station, root_context, q_d, v_d)
    _set_arm_state(station, root_context, controller_equilibrium(station, root_context), v_d)
    if station.compensation is not None:
        station.compensation.chain.initialize(root_context)


#: How close (rad/s²) the arm's first step must come to the trajectory's start acceleration
#: for :func:`controller_equilibrium`, and the most Newton steps it takes to get there.
EQUILIBRIUM_TOLERANCE = 1e-6
EQUILIBRIUM_STEPS = 10


def controller_equilibrium(station: Station, root_context) -> np.ndarray:
    """The arm's q (n, rad) at which its first step under the controller accelerates as the
    trajectory's start asks, for the velocity already in `root_context`.

    The controller's model of the tool is wrong (``controller.tool_mass_error``), so a PD law
    holds the arm a little off its desired pose: by ~0.03 rad at the wrist with the defaults.
    A real controller has been holding the arm for a while when a log starts; started at the
    desired pose instead, the simulated arm drops for ~50 ms at up to 8 rad/s², a transient
    that every run repeats at the same pose and that a learned residual learns as if it were
    the pose's. Found by Newton steps on a finite-difference Jacobian of one simulated step;
    warns when they do not reach :data:`EQUILIBRIUM_TOLERANCE`.

    With compliant transmissions (``transmission.enabled``) the links' first step follows
    the springs, not the controller: the motors' static state (:func:`set_initial_state`)
    already holds the links, and q stays as it is."""
    plant, arm = station.scene.plant, station.scene.arm
    if station.transmission is not None:
        return plant.GetPositions(plant.GetMyContextFromRoot(root_context), arm).copy()
    t0 = station.trajectory.start_time()
    target = station.trajectory.derivative(2).value(t0).ravel()
    v0 = plant.GetVelocities(plant.GetMyContextFromRoot(root_context), arm).copy()
    q = plant.GetPositions(plant.GetMyContextFromRoot(root_context), arm).copy()

    def miss(q_try):  # the first step's acceleration − the trajectory's, rad/s²
        context = root_context.Clone()
        _set_arm_state(station, context, q_try, v0)
        step = Simulator(station.diagram, context)
        step.AdvanceTo(t0 + station.scene.plant.time_step())
        v1 = plant.GetVelocities(plant.GetMyContextFromRoot(context), arm)
        return (v1 - v0) / plant.time_step() - target

    error = miss(q)
    if np.max(np.abs(error)) <= EQUILIBRIUM_TOLERANCE:
        return q
    h = 1e-6  # rad; the step is linear in q over far more than this
    jacobian = np.column_stack([(miss(q + h * e) - error) / h for e in np.eye(len(q))])
    for _ in range(EQUILIBRIUM_STEPS):
        q = q - np.linalg.lstsq(jacobian, error, rcond=None)[0]
        error = miss(q)
        if np.max(np.abs(error)) <= EQUILIBRIUM_TOLERANCE:
            return q
    warnings.warn(f"controller_equilibrium: the arm's first step still misses the trajectory's "
                  f"start acceleration by {np.max(np.abs(error)):.2g} rad/s² after "
                  f"{EQUILIBRIUM_STEPS} steps; the run starts with that transient", stacklevel=2)
    return q


def _set_arm_state(station: Station, root_context, q, v) -> None:
    """The arm's q, v, and with compliant transmissions the motors where they hold the links
    still at q."""
    plant = station.scene.plant
    plant_context = plant.GetMyMutableContextFromRoot(root_context)
    plant.SetPositions(plant_context, station.scene.arm, q)
    plant.SetVelocities(plant_context, station.scene.arm, v)
    if station.transmission is not None:
        motors = station.transmission
        load = plant.GetVelocitiesFromArray(
            station.scene.arm, plant.CalcGravityGeneralizedForces(plant_context))
        state = motors.static_motor_state(np.asarray(q, dtype=float), load)
        state[motors.n:] = v
        motors.set_motor_state(motors.GetMyMutableContextFromRoot(root_context), state)


def assemble_log(station: Station, root_context) -> pd.DataFrame:
    """The loggers' contents as one DataFrame with the documented columns."""
    n = station.scene.plant.num_positions(station.scene.arm)
    t, x = _log_data(station.loggers.state, root_context)
    keep = t > 0.5 * station.config.time_step  # see module docstring: drop the t = 0 row
    series = _sampled_with_state(station.loggers, root_context, t)
    if station.config.transmission.chain_reads_motors:
        series["acceleration"] = motor_acceleration(x[:, n:], t)
    frame = {col.TIME: t[keep]}
    _add_joint_columns(frame, x[keep], series["acceleration"][keep], n, station.period,
                       station.config.chain.compensator.acceleration_cutoff_hz)
    _add_sensor_columns(frame, station, root_context, t, keep, series)
    if station.loggers.imu is not None:
        _add_imu_columns(frame, station, root_context, t, keep)
    if station.compensation is not None:
        try:
            outputs = logged_values(station.compensation.loggers, root_context, t)
        except RuntimeError as e:
            raise RuntimeError(f"compensation: {e}") from None
        frame.update(output_columns({port: values[keep] for port, values in outputs.items()}))
    return pd.DataFrame(frame)


def motor_acceleration(qd, t) -> np.ndarray:
    """(N, n) rad/s²: the motors' acceleration for the log's q̈ columns when the loop reads
    the motor side (``transmission.chain_reads_motors``): the backward difference of the
    logged φ̇, ``(φ̇_k − φ̇_{k−1}) / (t_k − t_{k−1})`` (the first row: 0). The motors step
    φ̇ once per plant step, so at a sensor rate equal to the plant rate this is the
    acceleration of the step that ended at sample k, as the plant's q̈ is; at a slower sensor
    rate, the mean over the sensor period."""
    out = np.zeros_like(qd)
    out[1:] = np.diff(qd, axis=0) / np.diff(t)[:, None]
    return out


def _log_data(logger, root_context):
    log = logger.FindLog(root_context)
    return log.sample_times(), log.data().T


def _sampled_with_state(loggers, root_context, t) -> dict:
    """The loggers every station has, each checked to be sampled with the state logger."""
    series = {}
    for name in ("acceleration", "ideal", "measured", "saturated", "wrench_contact_true",
                 "contact_true"):
        ti, values = _log_data(getattr(loggers, name), root_context)
        if len(ti) != len(t) or not np.allclose(ti, t):
            raise RuntimeError(f"logger {name!r} is not sampled with the state logger")
        series[name] = values
    return series


def _add_joint_columns(frame: dict, x, acceleration, n: int, period: float,
                       cutoff_hz: float) -> None:
    """q, q̇, q̈ from the plant, and q̇, q̈ as the loop's compensator gets them: the joint
    state's q̇ and its causal q̈ estimate. A model trained on central differences instead
    meets the estimate's own error (its transients where q̈ changes rate) only in the loop."""
    q, qd = x[:, :n], x[:, n:]
    qd_est, qdd_est = qd, causal_acceleration(qd, period, cutoff_hz)
    for prefix, values in (
        (col.Q, q), (col.QD, qd), (col.QDD, acceleration),
        (col.QD_EST, qd_est), (col.QDD_EST, qdd_est),
    ):
        frame.update(zip(col.joint_columns(prefix, n), values.T, strict=True))


def _add_imu_columns(frame: dict, station: Station, root_context, t, keep) -> None:
    """The IMU's reading (``imu_acc_*``, ``imu_gyro_*``) and the angular acceleration derived
    from it (``imu_alpha_*``: causal derivative of the gyroscope at ``imu.alpha_cutoff_hz``)."""
    ti, values = _log_data(station.loggers.imu, root_context)
    if len(ti) != len(t) or not np.allclose(ti, t):
        raise RuntimeError("logger 'imu' is not sampled with the state logger")
    values = values[keep]
    # From the first kept row on, as the loop's chain derives α from the samples it reads.
    alpha = causal_acceleration(values[:, 3:], station.period,
                                station.config.imu.alpha_cutoff_hz)
    for prefix, block in ((col.IMU_ACC, values[:, :3]), (col.IMU_GYRO, values[:, 3:]),
                          (col.IMU_ALPHA, alpha)):
        frame.update(zip(col.imu_columns(prefix), block.T, strict=True))


def _add_sensor_columns(frame: dict, station: Station, root_context, t, keep, series) -> None:
    """The sensor's wrenches and the truth: ideal, measured, internal, external (with an
    ``events`` push), contact, saturation; temperature, offset and push force when logged."""
    loggers = station.loggers
    external = series["wrench_contact_true"]
    push = offset = None
    if loggers.push is not None:
        push = _log_data(loggers.push, root_context)[1]
        external = external + push
    internal = station.noisy_sensor.deterministic_reading(series["ideal"] - external, t)
    if loggers.offset is not None:
        offset = _log_data(loggers.offset, root_context)[1]
        internal = internal + offset
    for prefix, values in (
        (col.IDEAL, series["ideal"]), (col.MEASURED, series["measured"]),
        (col.INTERNAL_TRUE, internal), (col.EXTERNAL_TRUE, external),
    ):
        frame.update(zip(col.wrench_columns(prefix), values[keep].T, strict=True))
    frame[col.CONTACT_TRUE] = series["contact_true"][keep, 0].astype(np.int8)
    frame[col.SATURATED] = series["saturated"][keep, 0].astype(np.int8)
    if loggers.temperature is not None:
        frame[col.TEMPERATURE] = _log_data(loggers.temperature, root_context)[1][keep, 0]
    if offset is not None:
        frame.update(zip(col.wrench_columns(col.OFFSET), offset[keep].T, strict=True))
    if push is not None:
        frame[col.PUSH_FORCE] = np.linalg.norm(push[keep, :3], axis=1)
