"""An IMU at the F/T sensor: Drake's ideal ``Accelerometer`` and ``Gyroscope`` with our noise.

Convention (the columns ``imu_acc_*``, ``imu_gyro_*`` of :mod:`ftdrake.conventions`):

* The IMU sits at the sensor frame's origin So with its axes along S (the frame of the
  wrench), rigidly on the sensor's body.
* The accelerometer reads the **proper acceleration** of So, expressed in S, m/s²:
  ``f_S = R_SW (a_WSo_W − g_W)``, Drake's ``Accelerometer`` convention. At rest it reads
  +9.81 m/s² *upwards* (−g), e.g. ``[0, 0, +9.81]`` with S's z axis up. This is the ``a − g``
  of the payload regressor (:mod:`ftdrake.compensation.estimators.physics`).
* The gyroscope reads ω_WS expressed in S, rad/s (Drake's ``Gyroscope``).

:func:`add_imu` adds both to a diagram with a plant; :class:`ImuNoise` adds a constant bias
and white noise per axis (from :class:`~ftdrake.config.imu.ImuConfig`).
"""

from __future__ import annotations

import functools

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.sensors import Accelerometer, Gyroscope

from ..config.imu import ImuConfig

#: Samples per block of pre-drawn noise (the noise of sample k is a function of the seed and k).
_BLOCK = 1024


class ImuNoise(LeafSystem):
    """Bias and white noise on an ideal IMU's readings.

    ``acc = f_S + b_a + σ_a·n``, ``gyro = ω_S + b_g + σ_g·n`` with n standard normal, drawn
    per sample k = round(t / period) from the config's seed: the same run reads the same
    noise whoever evaluates the output and how often (no state; direct feedthrough).

    Input ports:
      acceleration (3): the ideal proper acceleration of So in S (m/s²; Accelerometer).
      angular_velocity (3): the ideal ω_WS in S (rad/s; Gyroscope).
    Output ports:
      imu (6): ``[acc_x, acc_y, acc_z, gyro_x, gyro_y, gyro_z]`` (m/s², rad/s; in S).
    """

    def __init__(self, config: ImuConfig, period: float):
        super().__init__()
        config.validate()
        self.period = float(period)
        self.seed = int(config.seed)
        self.bias = np.concatenate([config.accelerometer_bias, config.gyroscope_bias])
        self.std = np.concatenate([config.accelerometer_noise_std, config.gyroscope_noise_std])
        self._acc = self.DeclareVectorInputPort("acceleration", 3)
        self._gyro = self.DeclareVectorInputPort("angular_velocity", 3)
        self.DeclareVectorOutputPort("imu", 6, self._calc_imu)

    def get_input_port_acceleration(self):
        return self.GetInputPort("acceleration")

    def get_input_port_angular_velocity(self):
        return self.GetInputPort("angular_velocity")

    def get_output_port_imu(self):
        return self.GetOutputPort("imu")

    def noise(self, k: int) -> np.ndarray:
        """(6,) the noise of sample `k` (σ·n, without the bias)."""
        block, row = divmod(int(k), _BLOCK)
        return self.std * _noise_block(self.seed, block)[row]

    def _calc_imu(self, context, output: BasicVector):
        ideal = np.concatenate([self._acc.Eval(context), self._gyro.Eval(context)])
        k = round(context.get_time() / self.period)
        output.SetFromVector(ideal + self.bias + self.noise(k))


@functools.lru_cache(maxsize=4)
def _noise_block(seed: int, block: int) -> np.ndarray:
    """Standard normal draws (_BLOCK × 6) for samples [block·_BLOCK, (block+1)·_BLOCK)."""
    return np.random.default_rng([seed, 4099, block]).standard_normal((_BLOCK, 6))


def add_imu(builder, plant, frame_S, config: ImuConfig, period: float) -> ImuNoise:
    """Drake's Accelerometer and Gyroscope on `frame_S`'s body at S (gravity: the plant's),
    fed by `plant`'s body poses, velocities and accelerations, and an :class:`ImuNoise` after
    them (named ``imu``). Returns the ImuNoise (its ``imu`` port is the IMU's reading)."""
    body = frame_S.body()
    X_BS = frame_S.GetFixedPoseInBodyFrame()
    gravity = plant.gravity_field().gravity_vector()
    accelerometer = builder.AddNamedSystem("imu_accelerometer",
                                           Accelerometer(body, X_BS, gravity))
    gyroscope = builder.AddNamedSystem("imu_gyroscope", Gyroscope(body, X_BS))
    for sensor in (accelerometer, gyroscope):
        builder.Connect(plant.get_body_poses_output_port(),
                        sensor.get_body_poses_input_port())
        builder.Connect(plant.get_body_spatial_velocities_output_port(),
                        sensor.get_body_velocities_input_port())
    builder.Connect(plant.get_body_spatial_accelerations_output_port(),
                    accelerometer.get_body_accelerations_input_port())
    noise = builder.AddNamedSystem("imu", ImuNoise(config, period))
    builder.Connect(accelerometer.get_measurement_output_port(),
                    noise.get_input_port_acceleration())
    builder.Connect(gyroscope.get_measurement_output_port(),
                    noise.get_input_port_angular_velocity())
    return noise
