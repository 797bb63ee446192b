"""What more than one test module uses, in one place: a test module imports from here (or from
:mod:`ftdrake.testing`, the generators the benchmarks share), never from another test module
(``tests/project/test_test_layout.py`` checks it).

- Paths: :data:`ROOT` (the checkout), :data:`DATA` (``tests/data``), :data:`UR3_URDF`,
  :data:`UR3_DATA` (the real UR3 logs).
- The command line in-process (with conftest's ``ftdrake`` fixture): :func:`train`,
  :func:`refused`, :func:`failure`.
- Signals at the scenario sensor's rate, with its noise: :data:`SENSOR`, :func:`times`,
  :func:`noise`; S's motion along brisk arm motion and a particle's wrench by Newton's law:
  :func:`brisk_arm_motion`, :func:`point_mass_wrench`.
- Static poses with a known truth: :func:`poses`, :func:`static_readings`; a calibration table
  read through the simulated sensor: :data:`LOADS`, :data:`WRENCH`, :func:`sensor_poses`.
- The whole arm's torques with known friction and gains: :data:`FRICTION`, :func:`arm_torques`.
- A chain's input stream and its configs: :data:`CHAIN_PERIOD`, :func:`chain_forest`,
  :func:`chain_stream`, :func:`chain_configs`.
- A tool's payload model on four arms and settings, with its truth: :data:`PAYLOAD_PHI`,
  :data:`CABLE_WEIGHT`, :data:`PAYLOAD_CASES`, :func:`payload_rows`; a compensator run on
  them: :func:`compensator_run`.

Units: SI; wrenches ``[Fx Fy Fz Tx Ty Tz]`` (N, N·m) in the sensor frame S.
"""

from __future__ import annotations

import dataclasses as dc
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import RandomForestCompensator, ScenarioConfig, SensorConfig
from ftdrake.cli.main import main as cli_main
from ftdrake.compensation.calibration.calibration import KNOWN_COM, KNOWN_MASS, true_wrench
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.files.persistence import read_manifest
from ftdrake.conventions import WRENCH_AXES
from ftdrake.physics.rigid_body import sensor_kinematics
from ftdrake.physics.scenario_robot import robot_description
from ftdrake.runtime.compensator import CompensatorSystem
from ftdrake.systems.noisy_sensor import NoisyForceTorqueSensor
from ftdrake.testing import HOME, SIGMA, THETA

# --- Paths ---------------------------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
UR3_URDF = str(ROOT / "models" / "ur3.urdf")
UR3_DATA = DATA / "ur3"

# --- The command line in-process -----------------------------------------------------------


def train(ftdrake, data, out, *options):
    """`ftdrake train --data DATA --out OUT OPTIONS…` through the ``ftdrake`` fixture; asserts
    it succeeded and returns the model file's manifest."""
    code, _, err = ftdrake("train", "--data", data, "--out", out, *options)
    assert code == 0, err
    return read_manifest(out)


def refused(capsys, *argv) -> str:
    """The error line of a command line argparse must refuse before running (exit code 2)."""
    with pytest.raises(SystemExit) as exit_:
        cli_main([str(a) for a in argv])
    assert exit_.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


def failure(ftdrake, *argv) -> str:
    """stderr of a command that must fail with exit code 2 and a one-line error."""
    code, _, err = ftdrake(*argv)
    assert code == 2
    lines = err.strip().splitlines()
    assert lines[-1].startswith(f"ftdrake {argv[0]}: error: "), err
    assert sum("error" in line for line in lines) == 1, err
    return lines[-1]


# --- Signals at the scenario sensor's rate -------------------------------------------------

SENSOR = ScenarioConfig().sensor
SENSOR_PERIOD = 1.0 / SENSOR.spec().rate_hz
SENSOR_SIGMA = np.asarray(SENSOR.spec().noise_std)


def times(duration):
    """Sample times 0, T, …, `duration` at the scenario sensor's period T (s)."""
    return np.arange(round(duration / SENSOR_PERIOD) + 1) * SENSOR_PERIOD


def noise(n, seed=0):
    """`n` samples of the scenario sensor's white noise (its σ per axis), seeded."""
    return np.random.default_rng(seed).normal(size=(n, 6)) * SENSOR_SIGMA


def brisk_arm_motion():
    """S's motion along 6 s of brisk multi-sine joint motion of the scenario's arm, from Drake
    (S's Jacobian and bias acceleration): g_S − a_So, [ω; α] (in S). |α| reaches ~10 rad/s²."""
    plant, frame_S = robot_description(ScenarioConfig().models).build_plant()
    t = times(6.0)
    rng = np.random.default_rng(11)
    q0 = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 1.0, 0.0])
    amp, freq, phase = (rng.uniform(0.3, 0.6, (2, 7)), np.array([[0.23], [0.61]]),
                        rng.uniform(0, 2 * np.pi, (2, 7)))
    arg = 2 * np.pi * freq[:, None] * t[None, :, None] + phase[:, None]  # (2, N, 7)
    w = 2 * np.pi * freq[:, None]
    q = q0 + (amp[:, None] * np.sin(arg)).sum(0)
    v = (amp[:, None] * w * np.cos(arg)).sum(0)
    vdot = -(amp[:, None] * w**2 * np.sin(arg)).sum(0)
    kin = sensor_kinematics(plant, plant.CreateDefaultContext(), frame_S, q, v, vdot)
    return t, kin


def point_mass_wrench(mass, p, kin):
    """What a particle `mass` at p (So to P, in S) adds to the reading, by Newton's law for the
    particle alone: F = m (g − a_P), a_P = a_So + α × p + ω × (ω × p); T = p × F (about So)."""
    w, alpha = kin.w_WS_S, kin.alpha_WS_S
    a_P = kin.a_WSo_S + np.cross(alpha, p) + np.cross(w, np.cross(w, p))
    force = mass * (kin.g_S - a_P)
    return np.hstack([force, np.cross(p, force)])


# --- Static poses with a known truth -------------------------------------------------------

_MOVED_JOINTS = [1, 3, 5]


def poses(rng, n, lo, hi):
    """`n` static poses, joints 1, 3, 5 moved from HOME by uniform offsets in [lo, hi] rad."""
    q = np.tile(HOME, (n, 1))
    q[:, _MOVED_JOINTS] += rng.uniform(lo, hi, (n, len(_MOVED_JOINTS)))
    return np.hstack([q, np.zeros((n, 14))])


def static_readings(X, rng):
    """Gravity on the payload + a smooth pose-dependent 'cable' term of 4σ + noise."""
    q = X[:, :7]
    cable = 4 * SIGMA * np.column_stack([
        np.sin(2 * q[:, 0] + q[:, 3]), np.cos(q[:, 1]), np.sin(2 * q[:, 5]),
        np.cos(q[:, 4] + q[:, 2]), np.sin(q[:, 3]), np.cos(2 * q[:, 6])])
    gravity = PhysicsPayloadCompensator(mode="static", features="q").regressor(X) @ THETA
    return gravity + cable + rng.normal(size=(len(X), 6)) * SIGMA


WRENCH = [f"meas_{a}" for a in WRENCH_AXES]
# A sensor whose calibration is off: 1.5–3 % gains and 2 % cross-talk (force to torque up to
# 0.4 N per N·m), no mounting rotation (the orientation is given as gravity in S).
_MISCALIBRATED = {"crosstalk": 0.02, "gain_error": [0.03, -0.02, 0.015, 0.025, -0.03, 0.02],
                  "mounting_rpy_deg": [0.0] * 3, "calibration_seed": 3, "temperature_rise_c": 0.0}
# Three loads whose centres of mass are not on one line (kg; m from So in S).
LOADS = [(1.5, (0.02, 0.0067, 0.0867)), (0.8, (-0.06, 0.04, 0.03)), (2.0, (0.05, -0.05, 0.12))]


def _gravity_directions(rng, n):
    v = rng.normal(size=(n, 3))
    return 9.81 * v / np.linalg.norm(v, axis=1, keepdims=True)


def sensor_poses(seed, n, load, hold=100, keep=50):
    """The simulated sensor (noise, bias, random walk, filter, quantization; 1.5–3 % gain
    errors and 2 % cross-talk) holding a load in `n` random orientations, 0.1 s each; a table
    row per pose: the mean of its last 50 samples (as a calibration averages a held pose),
    gravity in S, the known payload. Returns (table, the sensor's calibration matrix K:
    reading = K·W + bias)."""
    rng = np.random.default_rng(seed)
    mass, com = load
    g_S = _gravity_directions(rng, n)
    ideal = true_wrench(g_S, np.r_[mass, mass * np.asarray(com)])
    dt = 1e-3
    breaks = np.arange(n + 1) * hold * dt
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(
        PiecewisePolynomial.ZeroOrderHold(breaks, np.vstack([ideal, ideal[-1:]]).T)))
    dut = builder.AddSystem(NoisyForceTorqueSensor(SensorConfig(seed=seed, **_MISCALIBRATED)))
    builder.Connect(source.get_output_port(), dut.get_input_port_wrench_ideal())
    logger = LogVectorOutput(dut.get_output_port_wrench_measured(), builder, dt)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(breaks[-1] - dt / 2)
    log = logger.FindLog(simulator.get_context())
    sample = np.round(log.sample_times() / dt).astype(int)
    held = sample % hold >= hold - keep
    Y = np.array([log.data().T[held & (sample // hold == p)].mean(axis=0) for p in range(n)])
    frame = pd.DataFrame({"gx": g_S[:, 0], "gy": g_S[:, 1], "gz": g_S[:, 2],
                          **dict(zip(WRENCH, Y.T, strict=True)), KNOWN_MASS: mass,
                          **dict(zip(KNOWN_COM, com, strict=True))})
    return frame, dut.calibration_matrix


# --- The whole arm's torques ---------------------------------------------------------------

#: Viscous (N·m·s/rad) and Coulomb (N·m) friction per joint of a 6-joint arm.
FRICTION = (np.array([3.0, 3.0, 2.0, 0.8, 0.8, 0.5]), np.array([2.0, 2.0, 1.5, 0.6, 0.6, 0.4]))


def arm_torques(arm, rng, rows, truth, friction, gains, noise):
    """(X, Y): `rows` uniform random states [q, q̇, q̈] of a 6-joint `arm` (an ArmDynamics) and
    the joint torques its regressor gives for the parameters `truth`, plus viscous and
    Coulomb `friction` (tanh(q̇/0.02)), times the drive `gains`, plus white noise of σ
    `noise` (N·m)."""
    q = rng.uniform(-np.pi, np.pi, (rows, 6))
    v = rng.uniform(-2, 2, (rows, 6))
    vd = rng.uniform(-4, 4, (rows, 6))
    tau = arm.regressor(q, v, vd) @ truth + friction[0] * v + friction[1] * np.tanh(v / 0.02)
    Y = gains * tau + noise * rng.standard_normal(tau.shape)
    return np.hstack([q, v, vd]), Y


# --- A chain's input stream ----------------------------------------------------------------

_N = 7
_NOISE = np.array([0.3, 0.3, 0.3, 0.01, 0.01, 0.01])  # N, N·m: well below the detector's
CHAIN_PERIOD = 1e-3
_STEPS = 600  # 0.6 s


def chain_forest(temperature: bool):
    """A small forest on q, q̇, q̈ of 7 joints (and the temperature as its last input column),
    trained on [-1, 2] per input, predicting a wrench of the size of the stream's noise."""
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 2, (200, 3 * _N + temperature))
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=3, random_state=0).fit(
        X, rng.normal(size=(200, 6)) * _NOISE)


def chain_stream(seed: int = 3) -> dict:
    """Inputs of a 7-joint chain sample by sample over 0.6 s at CHAIN_PERIOD: q, v = q̇ and q̈
    within the training range (q out of it for one sample, at 0.1 s), a 20 N contact from 0.3
    to 0.4 s, a NaN reading at 0.2 s, a re-tare pulse at 0.15 s, a grasp at 0.45 s, noisy
    gravity and motion of S near rest, a warming sensor."""
    rng = np.random.default_rng(seed)
    k = np.arange(_STEPS + 1)
    t = k * CHAIN_PERIOD
    w = 1.0 + 0.5 * np.arange(_N)  # rad/s: |q̈| ≤ 0.1 w² < 2
    phase = rng.uniform(0, 2 * np.pi, _N)
    state = np.hstack([0.5 + 0.1 * np.sin(w * t[:, None] + phase),
                       0.1 * w * np.cos(w * t[:, None] + phase)])
    state[100, 2] = 5.0
    wrench = rng.normal(size=(len(k), 6)) * _NOISE
    wrench[(t >= 0.3) & (t < 0.4), 0] += 20.0
    wrench[200] = np.nan  # a fault

    def pulse(at):
        return ((t >= at) & (t < at + 3 * CHAIN_PERIOD)).astype(float)[:, None]

    gravity = np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.05, (len(k), 3))
    return {"t": t, "wrench_measured": wrench, "joint_state": state,
            "temperature": 25.0 + 5.0 * t[:, None], "tared": pulse(0.15),
            "payload_changed": pulse(0.45), "gravity_S": gravity,
            "motion_S": rng.normal(0.0, 0.2, (len(k), 6))}


def chain_configs():
    """Scenarios (with the input stream's temperature or not) for the tracker off, on, and on
    with payload tracking: name → (ScenarioConfig, temperature)."""
    base = ScenarioConfig()
    base.chain.compensator.acceleration_cutoff_hz = 10.0  # not the systems' default
    tracked = base.with_chain(bias_tracker=dc.replace(
        base.chain.bias_tracker, initial_bias=[0.5, -0.3, 0.2, 0.01, 0.0, -0.02]))
    untracked = base.with_chain(bias_tracker=dc.replace(base.chain.bias_tracker, enabled=False))
    payload = tracked.with_chain(bias_tracker=dc.replace(
        tracked.chain.bias_tracker, track_payload=True, track_payload_motion=True,
        start_settled=False))
    return {"tracker_off": (untracked, False), "tracker_on": (tracked, False),
            "track_payload": (payload, True)}


def wait_for(condition, what: str, timeout: float = 10.0) -> None:
    """Polls `condition()` every ms until it is true; AssertionError naming `what` after
    `timeout` s (the live tests' wait for messages over a transport)."""
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.001)


__all__ = [
    "CHAIN_PERIOD",
    "DATA",
    "FRICTION",
    "LOADS",
    "ROOT",
    "SENSOR",
    "SENSOR_PERIOD",
    "SENSOR_SIGMA",
    "UR3_DATA",
    "UR3_URDF",
    "WRENCH",
    "arm_torques",
    "brisk_arm_motion",
    "chain_configs",
    "chain_forest",
    "chain_stream",
    "failure",
    "noise",
    "point_mass_wrench",
    "poses",
    "refused",
    "sensor_poses",
    "static_readings",
    "times",
    "train",
    "wait_for",
]


def imu_rows(n: int = 300, seed: int = 0):
    """(X, Y): rows ``[q, q̇, q̈, f_S, ω_S, α_S]`` of the 7-joint arm at random IMU readings
    and the wrench a rigid 0.8 kg tool gives there (the IMU model's regressor times its
    parameters), for fitting an ImuPayloadCompensator without a simulation."""
    from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator

    rng = np.random.default_rng(seed)
    acc = rng.normal(0, 3, (n, 3)) + np.array([0, 0, 9.81])
    X = np.hstack([rng.uniform(-1, 1, (n, 21)), acc, rng.normal(0, 1, (n, 3)),
                   rng.normal(0, 5, (n, 3))])
    A = ImuPayloadCompensator().regressor(X)
    theta = np.zeros(A.shape[2])
    theta[:10] = [0.8, 0.0, 0.0, 0.04, 0.004, 0.004, 0.002, 0.0, 0.0, 0.0]
    return X, A @ theta


def imu_message(t, acc=(1.0, 2.0, 9.8), gyro=(0.1, -0.2, 0.3)):
    """A ``sensor_msgs/msg/Imu`` stamped `t` with specific force `acc` (m/s²) and `gyro`
    (rad/s) in the sensor frame (needs cyclonedds)."""
    from ftdrake.hardware.ros2.messages import header, ros2_type

    imu, vector = ros2_type("sensor_msgs/msg/Imu"), ros2_type("geometry_msgs/msg/Vector3")
    return imu(header=header(t, "ft_sensor"),
               orientation=ros2_type("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0),
               orientation_covariance=[0.0] * 9,
               angular_velocity=vector(**dict(zip("xyz", gyro, strict=True))),
               angular_velocity_covariance=[0.0] * 9,
               linear_acceleration=vector(**dict(zip("xyz", acc, strict=True))),
               linear_acceleration_covariance=[0.0] * 9)


class Press(LeafSystem):
    """A hand pressing on a body, as a user would write it in their own diagram: a constant
    world-frame force `force_W` (N) on the body's origin from `start` to `end` (s); output
    ``applied`` for the plant's applied_spatial_force input."""

    def __init__(self, body, force_W, start, end):
        super().__init__()
        self._body, self._f = body.index(), np.asarray(force_W, float)
        self._start, self._end = start, end
        value = AbstractValue.Make([ExternallyAppliedSpatialForce()])
        self.DeclareAbstractOutputPort("applied", lambda: value.Clone(), self._calc)

    def _calc(self, context, output):
        forces = []
        if self._start <= context.get_time() < self._end:
            push = ExternallyAppliedSpatialForce()
            push.body_index = self._body
            push.p_BoBq_B = np.zeros(3)
            push.F_Bq_W = SpatialForce(np.zeros(3), self._f)
            forces.append(push)
        output.set_value(forces)


_USER_ARM = str(DATA / "prismatic_arm.urdf")  # 6 joints, one prismatic
# [m, m·c, I_So, biases] of a tool, in S.
PAYLOAD_PHI = np.array([1.5, 0.03, 0.01, 0.13, 0.012, 0.0, 0.001, 0.012, 0.0, 0.004,
                        0.6, -0.4, 1.2, 0.01, -0.02, 0.005])
# and a weight carried without inertia [m_w, m_w·c_w] (a hanging cable), in S.
CABLE_WEIGHT = np.array([0.12, -0.005, 0.0, 0.005])


def payload_rows(n, count, seed):
    """`count` rows [q, q̇, q̈] (3n) drawn uniformly, within the arms' ranges."""
    X = np.random.default_rng(seed).uniform(-1, 1, (count, 3 * n))
    X[:, 2 * n:] *= 4  # q̈ up to 4 rad/s²
    if n == 6:
        X[:, 1] /= 6  # the user arm's prismatic joint within its travel (m)
    return X


PAYLOAD_CASES = {
    "ftdrake arm": (lambda: PhysicsPayloadCompensator(), 7),
    "static payload, rotated mounting": (
        lambda: PhysicsPayloadCompensator(mode="static", features="q"), 7),
    "weight without inertia, rotated mounting": (
        lambda: PhysicsPayloadCompensator(weight_without_inertia=True), 7),
    "user URDF, other gravity": (
        lambda: PhysicsPayloadCompensator(robot=_USER_ARM, sensor_frame="ft_sensor",
                                          gravity=(0.5, -0.3, -9.7)), 6),
}


def compensator_run(model, n, wrench, outputs, fast=True):
    """CompensatorSystem on `model` (n joints) over 15 ms of moving joints (two of
    :func:`payload_rows`, linear between them: the q̈ estimate is not zero) and a constant
    `wrench` (6); (the system, {output: its log at 1 kHz} for the names in `outputs`)."""
    X = payload_rows(n, 2, seed=4)
    state = PiecewisePolynomial.FirstOrderHold([0.0, 0.02], np.column_stack(
        [X[0, :2 * n], X[1, :2 * n]]))
    builder = DiagramBuilder()
    dut = builder.AddSystem(CompensatorSystem(model, 1e-3, fast=fast))
    builder.Connect(builder.AddSystem(ConstantVectorSource(wrench)).get_output_port(),
                    dut.get_input_port_wrench_measured())
    builder.Connect(builder.AddSystem(TrajectorySource(state)).get_output_port(),
                    dut.get_input_port_joint_state())
    loggers = {name: LogVectorOutput(dut.GetOutputPort(name), builder, 1e-3)
               for name in outputs}
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.015)
    return dut, {name: log.FindLog(simulator.get_context()).data().T
                 for name, log in loggers.items()}


def fused_forest():
    """A small forest on q, q̇, q̈ of 7 joints predicting about 1 N: a model the compiled
    per-message paths run (a fused loop update's kind)."""
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(300, 3 * _N))
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=3, random_state=0).fit(
        X, np.sin(X[:, :6]) + 0.1 * X[:, 7:13])


def fused_physics():
    """A physics payload model of 7 joints fitted on noisy rows of a known payload: the
    other kind of model the compiled per-message paths run."""
    make, n = PAYLOAD_CASES["weight without inertia, rotated mounting"]
    model = make()
    X = payload_rows(n, 300, seed=0)
    A = model.regressor(X)
    Y = A @ np.concatenate([PAYLOAD_PHI, CABLE_WEIGHT])
    return model.fit(X, Y + np.random.default_rng(1).normal(0, 0.02, Y.shape))


#: The counts a compiled path and its Python path must give alike (the twin-station tests).
TWIN_COUNTS = ("received", "accepted", "rejected", "processed", "published_wrench",
               "published_contact", "fault_episodes", "clock_restarts")


def twin_stream():
    """The twin-station tests' stream: (k, t, q, v, w) for 1.7 s at 1 kHz of 7 joints, the
    F/T rate measured over the first second (by Python), then the unusual samples: five lost
    (k 1200–1204, not yielded: a gap of the stamps), NaN in the wrench at k 1100 and a 30 N
    press along z from k 1400 to 1499. Each transport's test adds its own unusual messages
    at the other k."""
    rng = np.random.default_rng(2)
    joints = 1.0 + np.arange(_N)
    for k in range(1700):
        t = 0.001 * (k + 1)
        q = 0.5 * np.sin(t * joints)
        v = 0.5 * joints * np.cos(t * joints)
        w = np.sin(q[:6]) + 0.02 * rng.normal(size=6)
        if 1400 <= k < 1500:
            w[2] += 30.0
        if 1200 <= k < 1205:
            continue
        if k == 1100:
            w[0] = np.nan
        yield k, t, q, v, w


def assert_twins_count_alike(on: dict, off: dict) -> None:
    """The two stations' summaries give the same TWIN_COUNTS."""
    for key in TWIN_COUNTS:
        assert on[key] == off[key], key
