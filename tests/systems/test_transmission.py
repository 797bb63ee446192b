"""Compliant transmissions: the two-mass joint model's physics, checked in the station's plant.

(a) With the links held, each motor oscillates against its gearbox spring at √(k/J)
    (J = J_m N², damped: ω√(1 − ζ²)).
(b) Under a static load the gearbox twists by τ/k (τ: the load's torque at the joint, here
    gravity, computed independently from a rigid copy of the plant).
(c) The angle the controller reads (motor angle / N) differs from the link angle by exactly
    that twist.
"""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput
from pydrake.trajectories import PiecewisePolynomial

from ftdrake.config import ScenarioConfig
from ftdrake.config.transmission import TransmissionConfig
from ftdrake.errors import ConfigError
from ftdrake.sim.scene import add_scene
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.systems.transmission import MotorSide


def _scenario(**transmission) -> ScenarioConfig:
    base = ScenarioConfig()
    return dc.replace(
        base, cable=dc.replace(base.cable, enabled=False),
        sensor=dc.replace(base.sensor, imperfections=False),
        transmission=dc.replace(base.transmission, enabled=True, **transmission))


def _frequency(t, x) -> float:
    """Angular frequency (rad/s) from the mean period between upward zero crossings."""
    x = x - x.mean()
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    # Linear interpolation of each crossing time.
    tc = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    return 2 * np.pi / np.diff(tc).mean()


def test_motor_against_held_link_oscillates_at_sqrt_k_over_J():
    config = _scenario()
    tr = config.transmission
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant, n = scene.plant, len(tr.stiffness)
    dut = builder.AddSystem(MotorSide(tr, config.time_step))
    builder.Connect(plant.get_state_output_port(scene.arm), dut.get_input_port_link_state())
    builder.Connect(dut.get_output_port_motor_state(),
                    plant.get_desired_state_input_port(scene.arm))
    torque = builder.AddSystem(ConstantVectorSource(np.zeros(n)))
    builder.Connect(torque.get_output_port(), dut.get_input_port_motor_torque())
    log = LogVectorOutput(dut.get_output_port_motor_state(), builder, config.time_step)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    root = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(root)
    q0 = np.asarray(config.home_q)
    plant.SetPositions(plant_context, scene.arm, q0)
    for index in plant.GetJointIndices(scene.arm):  # hold every arm link where it is
        if plant.get_joint(index).num_velocities() == 1:
            plant.get_joint(index).Lock(plant_context)
    amplitude = 1e-3  # rad: the motors start twisted against the held links
    dut.set_motor_state(dut.GetMyMutableContextFromRoot(root),
                        np.concatenate([q0 + amplitude, np.zeros(n)]))
    simulator.AdvanceTo(0.4)
    data = log.FindLog(simulator.get_context())
    t, phi = data.sample_times(), data.data()[:n].T
    q_end = plant.GetPositions(plant.GetMyContextFromRoot(simulator.get_context()), scene.arm)
    np.testing.assert_allclose(q_end, q0, atol=1e-12)  # the links were held
    omega = np.sqrt(np.asarray(tr.stiffness) / np.asarray(tr.reflected_inertia()))
    expected = omega * np.sqrt(1 - tr.damping_ratio**2)
    measured = np.array([_frequency(t, phi[:, j] - q0[j]) for j in range(n)])
    # The explicit step's own frequency error at ω·dt ≤ 0.3 is < 0.4 %.
    np.testing.assert_allclose(measured, expected, rtol=0.01)
    assert np.ptp(phi[:, 0]) > amplitude  # it did oscillate


@pytest.fixture(scope="module")
def held_pose():
    """The arm commanded to stay at home for 1.5 s with compliant joints, no cable."""
    config = _scenario()
    home = np.asarray(config.home_q, dtype=float).reshape(-1, 1)
    trajectory = PiecewisePolynomial.FirstOrderHold([0.0, 1.5], np.hstack([home, home]))
    station = build_station(config, trajectory=trajectory)
    result = simulate(station, progress=False)
    return config, station, result


def _gravity_torque(config, q) -> np.ndarray:
    """Gravity's generalized force on the links at q, from a rigid copy of the plant (N·m)."""
    rigid = dc.replace(config, transmission=dc.replace(config.transmission, enabled=False))
    scene = add_scene(DiagramBuilder(), rigid)
    context = scene.plant.CreateDefaultContext()
    scene.plant.SetPositions(context, scene.arm, q)
    return scene.plant.GetVelocitiesFromArray(
        scene.arm, scene.plant.CalcGravityGeneralizedForces(context))


def test_static_load_deflects_by_torque_over_stiffness(held_pose):
    config, station, result = held_pose
    context = result.context
    plant, arm = station.plant, station.scene.arm
    q = plant.GetPositions(plant.GetMyContextFromRoot(context), arm)
    deflection = station.transmission.get_output_port_deflection().Eval(
        station.transmission.GetMyContextFromRoot(context))
    tau = _gravity_torque(config, q)
    k = np.asarray(config.transmission.stiffness)
    # The gearbox holds the load: k (φ − q) = −τ_g.
    np.testing.assert_allclose(deflection, -tau / k, rtol=2e-3, atol=1e-8)
    assert np.abs(deflection).max() > 1e-4  # rad: a deflection the tool feels


def test_controller_reads_motor_angle_offset_by_the_deflection(held_pose):
    config, station, result = held_pose
    context = result.context
    plant, arm = station.plant, station.scene.arm
    q = plant.GetPositions(plant.GetMyContextFromRoot(context), arm)
    read = station.controller.get_input_port_estimated_state().Eval(
        station.controller.GetMyContextFromRoot(context))[:len(q)]
    tau = _gravity_torque(config, q)
    np.testing.assert_allclose(read - q, -tau / np.asarray(config.transmission.stiffness),
                               rtol=2e-3, atol=1e-8)
    assert np.abs(read - q).max() > 1e-4  # rad: the encoders miss what the tool feels


def test_too_stiff_for_the_step_is_refused_with_the_fix():
    with pytest.raises(ConfigError, match=r"stiffness\[4\].*time_step"):
        MotorSide(dc.replace(TransmissionConfig(), stiffness=[1.7e5] * 7), 1e-3)


def test_per_joint_lists_must_agree():
    with pytest.raises(ConfigError, match="rotor_inertia"):
        TransmissionConfig(rotor_inertia=[1e-4] * 6).validate()


def test_transmission_error_moves_the_springs_link_end():
    """φ + e·sin(c·N·φ) and its rate φ̇·(1 + e·c·N·cos(c·N·φ)); none without an error."""
    config = _scenario().transmission
    motor_state = np.r_[np.linspace(-0.4, 0.5, 7), np.linspace(0.3, -0.6, 7)]
    plain = MotorSide(config, 1e-3)
    context = plain.CreateDefaultContext()
    plain.set_motor_state(context, motor_state)
    np.testing.assert_array_equal(plain.get_output_port_link_reference().Eval(context),
                                  motor_state)
    errors = [1e-4, 2e-4, 3e-4, 1e-4, 2e-4, 3e-4, 5e-5]
    rippled = MotorSide(dc.replace(config, transmission_error=errors,
                                   transmission_error_cycles=2.0), 1e-3)
    context = rippled.CreateDefaultContext()
    rippled.set_motor_state(context, motor_state)
    end = rippled.get_output_port_link_reference().Eval(context)
    phi, phid = motor_state[:7], motor_state[7:]
    e, N = np.asarray(errors), np.asarray(config.gear_ratio)
    np.testing.assert_allclose(end[:7], phi + e * np.sin(2 * N * phi), rtol=0, atol=1e-15)
    # The rate is the derivative of the angle along the motion (central difference).
    h = 1e-7
    ahead = phi + h * phid + e * np.sin(2 * N * (phi + h * phid))
    behind = phi - h * phid + e * np.sin(2 * N * (phi - h * phid))
    np.testing.assert_allclose(end[7:], (ahead - behind) / (2 * h), rtol=1e-6, atol=1e-9)
    # The spring pulls the link towards that end, not towards φ.
    link = np.r_[phi, phid]
    np.testing.assert_allclose(rippled.spring_torque(motor_state, link),
                               rippled.k * (end[:7] - phi) + rippled.d * (end[7:] - phid))


def test_the_loop_reads_the_motors_when_asked():
    """chain_reads_motors: the log's q, q̇ are the motors' [φ, φ̇] and q̈ their steps'."""
    config = _scenario(chain_reads_motors=True)
    config = dc.replace(config, trajectory=dc.replace(config.trajectory, kind="fourier",
                                                      duration_s=0.4))
    station = build_station(config)
    result = simulate(station, progress=False)
    log = result.log
    motors = station.motor_state_log.FindLog(result.context)
    keep = motors.sample_times() > 0.5 * config.time_step
    x = motors.data().T[keep]
    q = log[[f"q_{i}" for i in range(7)]].to_numpy()
    qd = log[[f"qd_{i}" for i in range(7)]].to_numpy()
    qdd = log[[f"qdd_{i}" for i in range(7)]].to_numpy()
    np.testing.assert_array_equal(q, x[:, :7])
    np.testing.assert_array_equal(qd, x[:, 7:])
    np.testing.assert_allclose(qdd[1:], np.diff(qd, axis=0) / config.time_step, rtol=1e-9,
                               atol=1e-9)
    # The links are elsewhere: by the gearboxes' twist.
    plain = simulate(build_station(dc.replace(config, transmission=dc.replace(
        config.transmission, chain_reads_motors=False))), progress=False).log
    twist = np.abs(plain[[f"q_{i}" for i in range(7)]].to_numpy() - q).max()
    assert twist > 1e-5


def test_config_refuses_motor_reading_without_transmissions_and_bad_errors():
    with pytest.raises(ConfigError, match="chain_reads_motors: needs"):
        TransmissionConfig(chain_reads_motors=True).validate()
    with pytest.raises(ConfigError, match=r"transmission_error: must be empty or have one"):
        TransmissionConfig(enabled=True, transmission_error=[1e-4] * 3).validate()
    with pytest.raises(ConfigError, match=r"transmission_error\[2\]"):
        TransmissionConfig(enabled=True, transmission_error=[0, 0, -1e-4, 0, 0, 0, 0]).validate()
