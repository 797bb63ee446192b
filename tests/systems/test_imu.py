"""The IMU at the sensor: Drake's Accelerometer/Gyroscope on the sensor body, our noise and bias.

The inertial wrench computed from the IMU's readings (the payload regressor with ω, α, f = a − g
from the IMU) is checked against Drake's own Newton–Euler: the reaction at the sensor weld of a
continuous-time plant, at random states under random joint torques (no contact).
"""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from ftdrake import conventions as col
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.config import ScenarioConfig
from ftdrake.config.imu import ImuConfig
from ftdrake.errors import ConfigError
from ftdrake.sim.scene import add_scene
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station
from ftdrake.systems.ft_sensor import ForceTorqueSensor
from ftdrake.systems.imu import ImuNoise, add_imu


def _continuous_rig(tau):
    config = ScenarioConfig()
    config.cable.enabled = False
    config.time_step = 0.0  # continuous: reactions and accelerations of one and the same state
    builder = DiagramBuilder()
    scene = add_scene(builder, config)
    plant = scene.plant
    imu = add_imu(builder, plant, scene.sensor_frame, ImuConfig().without_noise(), 1e-3)
    ft = builder.AddSystem(ForceTorqueSensor(plant, scene.sensor_joint))
    builder.Connect(plant.get_reaction_forces_output_port(), ft.get_input_port())
    torque = builder.AddSystem(ConstantVectorSource(tau))
    builder.Connect(torque.get_output_port(), plant.get_actuation_input_port(scene.arm))
    return config, scene, imu, ft, builder.Build()


def _inertial_parameters(plant, context, frame_S, bodies) -> np.ndarray:
    """θ = [m, m·c (3), I_So (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), biases 0 (6)] from Drake's
    spatial inertia of the tool about So in S."""
    M = plant.CalcSpatialInertia(context, frame_S, bodies)
    I = M.CalcRotationalInertia().CopyToFullMatrix3()
    return np.r_[M.get_mass(), M.get_mass() * M.get_com(),
                 I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2], np.zeros(6)]


@pytest.mark.parametrize("seed", range(3))
def test_inertial_wrench_from_imu_equals_drakes_newton_euler(seed):
    rng = np.random.default_rng(seed)
    config, scene, imu, ft, diagram = _continuous_rig(rng.normal(0.0, 20.0, 7))
    plant = scene.plant
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    q = np.asarray(config.home_q) + rng.uniform(-0.3, 0.3, 7)
    plant.SetPositions(plant_context, scene.arm, q)
    plant.SetVelocities(plant_context, scene.arm, rng.uniform(-1.5, 1.5, 7))
    assert plant.get_contact_results_output_port().Eval(plant_context) \
        .num_hydroelastic_contacts() + plant.get_contact_results_output_port() \
        .Eval(plant_context).num_point_pair_contacts() == 0
    reading = imu.get_output_port_imu().Eval(imu.GetMyContextFromRoot(context))
    # α of S in S: Drake's, for the derivative of the gyroscope's reading.
    frame_S = scene.sensor_frame
    body = frame_S.body()
    A_WB = plant.get_body_spatial_accelerations_output_port().Eval(plant_context)[body.index()]
    R_SW = frame_S.CalcPoseInWorld(plant_context).rotation().inverse()
    alpha_S = R_SW @ A_WB.rotational()
    X = np.r_[q, np.zeros(14), reading, alpha_S][None, :]
    theta = _inertial_parameters(plant, plant_context, frame_S, scene.tool_bodies)
    predicted = (ImuPayloadCompensator().regressor(X) @ theta)[0]
    expected = ft.get_output_port().Eval(ft.GetMyContextFromRoot(context))
    # The motion is really dynamic: the accelerometer reads far from gravity alone.
    assert np.linalg.norm(reading[:3] - R_SW @ [0, 0, 9.81]) > 0.5  # m/s²
    np.testing.assert_allclose(predicted, expected, rtol=0,
                               atol=1e-9 * np.abs(expected).max())


def test_accelerometer_reads_up_at_rest():
    """Drake's convention: proper acceleration, +9.81 m/s² against gravity (world z up)."""
    config, scene, _, _, diagram = _continuous_rig(np.zeros(7))
    plant_context = scene.plant.GetMyMutableContextFromRoot(diagram.CreateDefaultContext())
    scene.plant.SetPositions(plant_context, scene.arm, config.home_q)
    holding = -scene.plant.CalcGravityGeneralizedForces(plant_context)  # the arm at rest
    config, scene, imu, _, diagram = _continuous_rig(holding)
    context = diagram.CreateDefaultContext()
    plant_context = scene.plant.GetMyMutableContextFromRoot(context)
    scene.plant.SetPositions(plant_context, scene.arm, config.home_q)
    reading = imu.get_output_port_imu().Eval(imu.GetMyContextFromRoot(context))
    R_WS = scene.sensor_frame.CalcPoseInWorld(plant_context).rotation()
    np.testing.assert_allclose(R_WS @ reading[:3], [0.0, 0.0, 9.81], atol=1e-9)
    np.testing.assert_allclose(reading[3:], 0.0, atol=1e-12)


def test_noise_and_bias_have_their_configured_size_and_repeat():
    config = ImuConfig(accelerometer_noise_std=[0.1, 0.2, 0.3], accelerometer_bias=[1, 2, 3],
                       gyroscope_noise_std=[0.01, 0.02, 0.03], gyroscope_bias=[-1, 0, 1])
    dut = ImuNoise(config, 1e-3)
    context = dut.CreateDefaultContext()
    dut.get_input_port_acceleration().FixValue(context, [0.0, 0.0, 9.81])
    dut.get_input_port_angular_velocity().FixValue(context, [0.5, 0.0, 0.0])
    samples = []
    for k in range(4000):
        context.SetTime(k * 1e-3)
        samples.append(dut.get_output_port_imu().Eval(context).copy())
    samples = np.array(samples)
    ideal = np.r_[0.0, 0.0, 9.81, 0.5, 0.0, 0.0]
    bias = np.r_[config.accelerometer_bias, config.gyroscope_bias]
    std = np.r_[config.accelerometer_noise_std, config.gyroscope_noise_std]
    assert np.all(np.abs(samples.mean(axis=0) - ideal - bias) < 4 * std / np.sqrt(4000))
    np.testing.assert_allclose(samples.std(axis=0), std, rtol=0.06)
    context.SetTime(17e-3)  # the same sample reads the same noise
    np.testing.assert_array_equal(dut.get_output_port_imu().Eval(context), samples[17])


def test_config_names_a_bad_field():
    with pytest.raises(ConfigError, match=r"scenario.imu.gyroscope_bias: must have 3"):
        ImuConfig(gyroscope_bias=[0.0, 0.0]).validate()
    with pytest.raises(ConfigError, match=r"accelerometer_noise_std\[1\]"):
        ImuConfig(accelerometer_noise_std=[0.0, -1.0, 0.0]).validate()


def test_station_logs_the_imu_columns_only_when_enabled():
    config = ScenarioConfig()
    config.cable.enabled = False
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = 0.3
    log = simulate(build_station(config), progress=False).log
    assert not set(col.IMU_INPUTS) & set(log.columns)
    config.imu = dc.replace(config.imu.without_noise(), enabled=True, alpha_cutoff_hz=200.0)
    log = simulate(build_station(config), progress=False).log
    assert list(log[list(col.IMU_INPUTS)].columns) == list(col.IMU_INPUTS)
    gyro = log[col.imu_columns(col.IMU_GYRO)].to_numpy()
    assert np.abs(gyro).max() > 0.01  # the arm turns
    # imu_alpha is the gyroscope's causal derivative: at a high cut-off, its backward
    # difference (after the filter's first samples).
    alpha = log[col.imu_columns(col.IMU_ALPHA)].to_numpy()[20:]
    difference = np.diff(gyro, axis=0)[19:] / config.time_step
    assert np.abs(difference).max() > 0.1  # rad/s²
    np.testing.assert_allclose(alpha, difference, rtol=0, atol=0.05 * np.abs(difference).max())
