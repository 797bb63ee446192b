"""Typed configuration of the simulated IMU at the F/T sensor (``scenario.imu``), off by default.

The IMU is mounted at the sensor's origin So with its axes along S: its accelerometer reads
the proper acceleration of So, its gyroscope the angular velocity of S (both in S; see
:mod:`ftdrake.systems.imu`). Noise and bias are per axis and per sample.

Where the default numbers come from: a tactical-grade MEMS IMU sampled at the sensor's
1 kHz with a 500 Hz bandwidth. Gyroscope: angular random walk 0.09 °/√h (ADIS16495-1
datasheet, "Features"), i.e. 2.6·10⁻⁵ rad/s/√Hz, σ = 2.6·10⁻⁵ · √500 ≈ 6·10⁻⁴ rad/s per
sample. Accelerometer: σ = 3·10⁻³ m/s² per sample (about 14 µg/√Hz; an assumption of that
grade's order, not a datasheet value). A consumer MEMS IMU is about ten times noisier
(e.g. about 175 µg/√Hz and 0.014 °/s/√Hz: 0.038 m/s² and 5.5·10⁻³ rad/s per sample); the
figures for both are in docs/results/imu.md. The biases are what is left after a
calibration (a few 10⁻⁴ g, a few 0.01 °/s; assumed).
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc

from .checks import non_negative, positive, vector


@dc.dataclass
class ImuConfig:
    """An accelerometer and a gyroscope at the sensor (Drake's ``Accelerometer`` and
    ``Gyroscope`` systems on the sensor's body), with white noise and a constant bias.

    Logged as the columns ``imu_acc_x`` … (m/s², proper acceleration of So in S: +9.81 up at
    rest), ``imu_gyro_x`` … (rad/s, ω of S in S) and ``imu_alpha_x`` … (rad/s², the causal,
    filtered derivative of the gyroscope's reading at ``alpha_cutoff_hz``).
    """

    enabled: bool = False
    accelerometer_noise_std: list[float] = dc.field(  # m/s² per sample
        default_factory=lambda: [0.003, 0.003, 0.003])
    accelerometer_bias: list[float] = dc.field(  # m/s²
        default_factory=lambda: [0.003, -0.002, 0.005])
    gyroscope_noise_std: list[float] = dc.field(  # rad/s per sample
        default_factory=lambda: [6.0e-4, 6.0e-4, 6.0e-4])
    gyroscope_bias: list[float] = dc.field(  # rad/s
        default_factory=lambda: [2.0e-4, -1.0e-4, 1.5e-4])
    # Hz: the cut-off of the causal derivative of the gyroscope (the angular acceleration
    # column; :func:`ftdrake.signals.causal_acceleration`, as the loop estimates q̈). Higher
    # follows faster vibration, lower lets less gyroscope noise into α; the default is the
    # best of benchmarks/imu_compensation.py's sweep with the default noise.
    alpha_cutoff_hz: float = 5.0
    seed: int = 0  # the noise of this run

    def validate(self, where: str = "scenario.imu") -> "ImuConfig":
        for name in ("accelerometer_noise_std", "accelerometer_bias", "gyroscope_noise_std",
                     "gyroscope_bias"):
            vector(getattr(self, name), 3, f"{where}.{name}")
        for name in ("accelerometer_noise_std", "gyroscope_noise_std"):
            for i, v in enumerate(getattr(self, name)):
                non_negative(v, f"{where}.{name}[{i}]")
        positive(self.alpha_cutoff_hz, f"{where}.alpha_cutoff_hz")
        return self

    def without_noise(self) -> "ImuConfig":
        """A copy with zero noise and bias (the ideal IMU)."""
        return dc.replace(self, accelerometer_noise_std=[0.0] * 3, accelerometer_bias=[0.0] * 3,
                          gyroscope_noise_std=[0.0] * 3, gyroscope_bias=[0.0] * 3)
