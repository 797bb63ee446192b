"""Generators with a known truth, shared by the tests and the benchmarks (as ``numpy.testing``
is): the same payload, motions and readings, so a test and the benchmark it is the cheap
version of measure the same thing.

A rigid payload on ftdrake's arm (the scenario's tool, ``models/ft_sensor_tool.sdf``):
  :data:`MASS`, :data:`COM`, :data:`INERTIA_COM`, :data:`TRUE_PAYLOAD` (a ``PayloadPrior``),
  :data:`THETA` (the physics model's 16 parameters: payload and sensor biases), :data:`SIGMA`
  (the sensor's noise σ per axis), :data:`HOME` (a pose of the 7 joints).
Joint-state rows ``[q (7), q̇ (7), q̈ (7)]`` in rad, rad/s, rad/s²:
  :func:`sinusoids` (motion), :func:`static_poses`.
What the sensor reads for them: :func:`readings`, :func:`pose_tables` (static poses as tables of
joint angles and of sensor orientations, the way ``ftdrake calibrate`` reads them).
Simulated scenarios and models: :func:`push_scenario`, :func:`fit_forest`, :func:`demo_models`.
A live station whose outputs are kept: :func:`listening_station`.
Summaries: :func:`identification_spread` and its goals, :func:`split_by_trajectory`.

Everything is deterministic for a given seed or generator. Units: SI throughout; wrenches in
``[Fx Fy Fz Tx Ty Tz]`` order (N, N·m) in the sensor frame S.
"""

from __future__ import annotations

import time
import warnings

import numpy as np
import pandas as pd

from .compensation.estimators.forest import RandomForestCompensator
from .compensation.estimators.hybrid import HybridCompensator
from .compensation.estimators.physics import PhysicsPayloadCompensator
from .compensation.identification.consistent import PayloadPrior
from .config import ScenarioConfig
from .conventions import MEASURED, QD, QDD, Q, joint_columns, wrench_columns
from .data.dataset import joint_state_layout, wrench_targets
from .sim.collection import collect
from .sim.simulate import simulate
from .sim.station import build_station

__all__ = [
    "COM",
    "COM_SPREAD_GOAL_MM",
    "HOME",
    "INERTIA_COM",
    "MASS",
    "MASS_SPREAD_GOAL",
    "SIGMA",
    "THETA",
    "TRUE_PAYLOAD",
    "demo_models",
    "fit_forest",
    "identification_spread",
    "listening_station",
    "median_us_per_row",
    "pose_tables",
    "push_scenario",
    "readings",
    "sine_path",
    "sinusoids",
    "split_by_trajectory",
    "static_poses",
]

# -- A rigid payload and its sensor ----------------------------------------------------------
SIGMA = np.array([1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800])  # ati_gamma noise σ
MASS = 1.5  # kg, from ft_sensor_tool.sdf
COM = np.array([0.02, 0.0067, 0.0867])  # m, in S, from ft_sensor_tool.sdf
_BOX_DIMS = np.array([0.06, 0.08, 0.17])  # a box of the tool's size, m
# Rotational inertia about the centre of mass [Ixx Ixy Ixz Iyy Iyz Izz], kg·m² (the box's).
INERTIA_COM = MASS / 12 * np.array([_BOX_DIMS[1] ** 2 + _BOX_DIMS[2] ** 2, 0, 0,
                                    _BOX_DIMS[0] ** 2 + _BOX_DIMS[2] ** 2, 0,
                                    _BOX_DIMS[0] ** 2 + _BOX_DIMS[1] ** 2])
TRUE_PAYLOAD = PayloadPrior(MASS, tuple(COM), tuple(INERTIA_COM))
# The physics model's parameters: the payload's 10 (mass, first moment, inertia about So) and
# the sensor's 6 biases (N, N·m).
THETA = np.r_[TRUE_PAYLOAD.phi(), [0.6, -0.4, 1.2, 0.02, -0.015, 0.01]]
HOME = np.array([0.0, 0.4, 0.0, -1.2, 0.0, 0.8, 0.0])  # rad

# The payload identification's repeatability goals across sensor-noise seeds (max − min):
# the mass within 1 % of its mean, each centre-of-mass coordinate within 2 mm.
MASS_SPREAD_GOAL = 0.01
COM_SPREAD_GOAL_MM = 2.0


# -- Joint states ----------------------------------------------------------------------------
def sine_path(seconds: float, seed: int, rate_hz: float = 1000.0, n_joints: int = 7):
    """[q, q̇, q̈] (N × 3n) of a sum of three sines per joint (0.1–0.4 Hz, 0.1–0.5 rad), sampled
    at `rate_hz`: the desired state a feedforward benchmark steps through."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate_hz)[:, None]
    w = 2 * np.pi * rng.uniform(0.1, 0.4, (3, n_joints))
    a = rng.uniform(0.1, 0.5, (3, n_joints))
    phase = rng.uniform(0, 2 * np.pi, (3, n_joints))
    q = sum(a[k] * np.sin(w[k] * t + phase[k]) for k in range(3))
    qd = sum(a[k] * w[k] * np.cos(w[k] * t + phase[k]) for k in range(3))
    qdd = sum(-a[k] * w[k] ** 2 * np.sin(w[k] * t + phase[k]) for k in range(3))
    return np.hstack([q, qd, qdd])


def median_us_per_row(f, rows, repeat: int = 3) -> float:
    """The median over `repeat` passes of the mean wall time of ``f(row)`` per row, in µs (a
    benchmark's figure; timing goals are never asserted in tests)."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        for x in rows:
            f(x)
        times.append((time.perf_counter() - start) / len(rows) * 1e6)
    return float(np.median(times))


def sinusoids(rng, joints, n=1500, duration=20.0, amplitude=0.6):
    """[q, q̇, q̈] rows of a sum of three sinusoids on `joints`, the others held at HOME.

    `n` rows over `duration` s; each sinusoid's frequency (0.05–0.4 Hz), amplitude (up to
    `amplitude` rad, falling with its order) and phase are drawn from `rng`.
    """
    t = np.linspace(0, duration, n)
    q, qd, qdd = np.tile(HOME, (n, 1)), np.zeros((n, 7)), np.zeros((n, 7))
    for j in joints:
        for k in range(3):
            w = 2 * np.pi * rng.uniform(0.05, 0.4)
            a, phase = amplitude * rng.uniform(0.2, 1) / (k + 1), rng.uniform(0, 2 * np.pi)
            q[:, j] += a * np.sin(w * t + phase)
            qd[:, j] += a * w * np.cos(w * t + phase)
            qdd[:, j] -= a * w * w * np.sin(w * t + phase)
    return np.hstack([q, qd, qdd])


def static_poses(rng, n, joints=range(7)):
    """`n` i.i.d. static poses around HOME (q̇ = q̈ = 0), `joints` moved by up to ±0.8 rad:
    held-out rows are in-domain."""
    q = np.tile(HOME, (n, 1))
    q[:, list(joints)] += rng.uniform(-0.8, 0.8, (n, len(joints)))
    return np.hstack([q, np.zeros((n, 14))])


# -- Sensor readings -------------------------------------------------------------------------
def readings(X, rng, theta=THETA):
    """What the sensor reads for a rigid payload `theta` (the model's regressor) + noise σ."""
    return PhysicsPayloadCompensator().regressor(X) @ theta + rng.normal(size=(len(X), 6)) * SIGMA


# A temperature sensitivity per axis (N/°C, N·m/°C) about 30 °C, for pose_tables.
_TEMPERATURE_GAIN = np.array([0.02, -0.01, 0.05, 0.001, 0.0, -0.002])


def pose_tables(seed, n, temperature=False):
    """The same `n` static poses of ftdrake's arm as two tables a calibration reads, and the
    noise-free truth.

    Returns ``(joints, rotation, truth)``: ``joints`` has columns ``q_0..q_6`` (rad) and the
    reading ``meas_Fx..meas_Tz``; ``rotation`` the quaternion ``qw qx qy qz`` of R_WS and the
    same reading; ``truth`` (n × 6) is the reading without noise. With `temperature`, both
    tables carry a ``temperature`` column (25–35 °C) and the reading a linear drift with it.
    """
    rng = np.random.default_rng(seed)
    X = static_poses(rng, n)
    physics = PhysicsPayloadCompensator(mode="static", features="q")
    Y = physics.regressor(X) @ THETA + rng.normal(size=(n, 6)) * SIGMA
    R = physics._kinematics().evaluate(X[:, :7], X[:, 7:14], X[:, 14:]).R_WS
    w = np.sqrt(np.maximum(1 + R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2], 1e-12)) / 2
    quat = np.column_stack([w, (R[:, 2, 1] - R[:, 1, 2]) / (4 * w),
                            (R[:, 0, 2] - R[:, 2, 0]) / (4 * w),
                            (R[:, 1, 0] - R[:, 0, 1]) / (4 * w)])
    extra = {}
    if temperature:
        T = 25 + 10 * rng.uniform(size=n)
        Y = Y + np.outer(T - 30, _TEMPERATURE_GAIN)
        extra["temperature"] = T
    wrench = dict(zip(wrench_columns(MEASURED), Y.T, strict=True))
    joints = pd.DataFrame({**{f"q_{j}": X[:, j] for j in range(7)}, **wrench, **extra})
    rotation = pd.DataFrame({**dict(zip(("qw", "qx", "qy", "qz"), quat.T, strict=True)),
                             **wrench, **extra})
    truth = physics.regressor(X) @ THETA
    if temperature:
        truth = truth + np.outer(T - 30, _TEMPERATURE_GAIN)
    return joints, rotation, truth


# -- Simulated scenarios and models ----------------------------------------------------------
def push_scenario(duration: float = 3.0, push_at: float = 1.0) -> ScenarioConfig:
    """Free (Fourier) motion for `duration` s with a push at the tool tip from `push_at` s
    (0.3 s ramp, 0.4 s hold) that the detector sees."""
    scenario = ScenarioConfig()
    scenario.trajectory.kind = "fourier"
    scenario.trajectory.duration_s = duration
    scenario.events.push_at_s = push_at
    scenario.events.push_ramp_s = 0.3
    scenario.events.push_hold_s = 0.4
    return scenario.validate()


def fit_forest(scenario: ScenarioConfig, duration: float = 1.0, seed: int = 0):
    """A 5-tree forest (features q, q̇, q̈) on the first `duration` s of the scenario's
    simulated motion, the plant's joint states against the sensor's reading."""
    log = simulate(build_station(scenario), progress=False, duration=duration).log
    columns = [*joint_columns(Q, 7), *joint_columns(QD, 7), *joint_columns(QDD, 7)]
    X = log[columns].to_numpy()
    Y = log[wrench_columns(MEASURED)].to_numpy()
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=5, n_jobs=1,
                                   random_state=seed).fit(X, Y)


def demo_models():
    """(forest, hybrid) trained on two simulated 8 s Fourier trajectories: the demo's layouts,
    a multi-output forest of 100 trees on q and the hybrid as the demo's (mounting rotation
    and weight carried without inertia identified, 20 parameters) with its default residual
    (``hybrid.default_residual``: 50 trees on q)."""
    data = collect(ScenarioConfig(), 2, kind="fourier", duration=8.0, progress=False)
    X, Y = joint_state_layout(data)[::4], wrench_targets(data)[::4]
    forest = RandomForestCompensator(features="q", per_output=False, random_state=0).fit(X, Y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hybrid = HybridCompensator(physics=PhysicsPayloadCompensator(
            identify_mounting=True, weight_without_inertia=True)).fit(X, Y)
    return forest, hybrid


# -- Summaries -------------------------------------------------------------------------------
def listening_station(model, chain, config, clock):
    """A :class:`~ftdrake.hardware.station.HardwareStation` on `config` (its ``lcm_url``,
    e.g. ``memq://``) with the station's `clock`, and what it publishes: returns (station,
    contact states, compensated wrenches), two lists that grow as its outputs are handled
    (``ContactState``, ``WrenchSample`` of ``wrench_compensated``)."""
    from .hardware import HardwareStation  # noqa: PLC0415 (LCM only for the stations)
    from .hardware.messages import decode_contact_state, decode_wrench  # noqa: PLC0415

    station = HardwareStation(config, model, chain, config.lcm_url, clock=clock)
    contacts, wrenches = [], []
    station.lcm.subscribe(config.output_channel("contact"),
                          lambda data: contacts.append(decode_contact_state(data)))
    station.lcm.subscribe(config.output_channel("wrench_compensated"),
                          lambda data: wrenches.append(decode_wrench(data)))
    return station, contacts, wrenches


def identification_spread(masses, coms) -> dict:
    """The spread of identified masses (kg) and centres of mass (m, n × 3) across runs: the
    mean mass, the range (max − min) and std relative to it, and per coordinate the range and
    std in mm, and the largest distance of a run's centre of mass from their mean (mm).
    Compare with :data:`MASS_SPREAD_GOAL` and :data:`COM_SPREAD_GOAL_MM`."""
    masses, coms = np.asarray(masses), np.asarray(coms)
    return {
        "mass_mean_kg": float(masses.mean()),
        "mass_range_rel": float(np.ptp(masses) / masses.mean()),
        "mass_std_rel": float(masses.std(ddof=1) / masses.mean()),
        "com_range_mm": (1e3 * np.ptp(coms, axis=0)).tolist(),
        "com_std_mm": (1e3 * coms.std(axis=0, ddof=1)).tolist(),
        "com_max_dev_mm": float(1e3 * np.linalg.norm(coms - coms.mean(0), axis=1).max()),
    }


def split_by_trajectory(frame: pd.DataFrame, test_ids):
    """(train, test): the rows of a dataset whose ``trajectory`` is not / is in `test_ids`."""
    test = frame["trajectory"].isin(test_ids).to_numpy()
    return frame[~test], frame[test]
