"""The F/T sensor's configuration: presets of real sensors and the simulated imperfections."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
from typing import Optional

from ..errors import ConfigError
from .checks import finite, non_negative, positive, six, vector


# ----------------------------------------------------------------------------------------------
# Sensor presets. Each number's source is in the comment beside it.
# ----------------------------------------------------------------------------------------------
@dc.dataclass(frozen=True)
class SensorSpec:
    """Resolved numbers of a sensor (no Optional fields)."""

    rate_hz: float
    range: tuple  # (6,) N, N·m: saturation limits (symmetric)
    resolution: tuple  # (6,) N, N·m: quantization step
    noise_std: tuple  # (6,) N, N·m: white noise per sample
    bandwidth_hz: float  # first-order low-pass cut-off


SENSOR_PRESETS: dict[str, SensorSpec] = {
    # ATI Gamma, calibration SI-130-10 (ATI F/T catalog, Gamma page): range Fx,Fy ±130 N,
    # Fz ±400 N, Tx,Ty,Tz ±10 N·m; resolution with Net F/T 1/40 N (Fx,Fy), 1/20 N (Fz),
    # 1/800 N·m (T). Net F/T streams up to 7 kHz; we sample at 1 kHz. ATI publishes no noise
    # σ; we assume σ ≈ one resolution step (typical of Net F/T readings at rest).
    "ati_gamma": SensorSpec(
        rate_hz=1000.0,
        range=(130.0, 130.0, 400.0, 10.0, 10.0, 10.0),
        resolution=(1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800),
        noise_std=(1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800),
        bandwidth_hz=400.0,  # assumption: DAQ low-pass set below the 500 Hz Nyquist limit
    ),
    # ATI Mini45, calibration SI-290-10 (ATI F/T catalog, Mini45 page): range Fx,Fy ±290 N,
    # Fz ±580 N, T ±10 N·m; resolution 1/8 N (Fx,Fy), 1/8 N (Fz), 1/376 N·m (T) as listed for
    # Net F/T. Check against your sensor's calibration certificate. Noise σ assumed = resolution.
    "ati_mini45": SensorSpec(
        rate_hz=1000.0,
        range=(290.0, 290.0, 580.0, 10.0, 10.0, 10.0),
        resolution=(1 / 8, 1 / 8, 1 / 8, 1 / 376, 1 / 376, 1 / 376),
        noise_std=(1 / 8, 1 / 8, 1 / 8, 1 / 376, 1 / 376, 1 / 376),
        bandwidth_hz=400.0,
    ),
    # Robotiq FT 300-S (instruction manual): range ±300 N, ±30 N·m; data stream at 100 Hz with
    # Fx·100 and Mx·1000 as 16-bit counts (so 0.01 N, 0.001 N·m steps); signal noise 0.1 N and
    # 0.005 N·m (Robotiq spec sheet).
    "robotiq_ft300": SensorSpec(
        rate_hz=100.0,
        range=(300.0, 300.0, 300.0, 30.0, 30.0, 30.0),
        resolution=(0.01, 0.01, 0.01, 0.001, 0.001, 0.001),
        noise_std=(0.1, 0.1, 0.1, 0.005, 0.005, 0.005),
        bandwidth_hz=40.0,  # assumption: the stream is filtered below its 50 Hz Nyquist limit
    ),
}


@dc.dataclass
class SensorConfig:
    """The noisy F/T sensor. Fields left unset (null) take the preset's value."""

    preset: str = "ati_gamma"
    rate_hz: Optional[float] = None
    range: Optional[list[float]] = dc.field(default=None, metadata={"entries": 6})
    resolution: Optional[list[float]] = dc.field(default=None, metadata={"entries": 6})
    noise_std: Optional[list[float]] = dc.field(default=None, metadata={"entries": 6})
    bandwidth_hz: Optional[float] = None
    # Constant offset of the reading (N, N·m); a real sensor is tared, never perfectly.
    bias: list[float] = dc.field(default_factory=lambda: [0.6, -0.4, 1.2, 0.02, -0.015, 0.01])
    # Thermal drift as a random walk: σ of its increment per √s (N/√s, N·m/√s).
    drift_std: list[float] = dc.field(
        default_factory=lambda: [2e-3, 2e-3, 3e-3, 5e-5, 5e-5, 5e-5]
    )
    # Calibration cross-talk: off-diagonal entries of the calibration error matrix are drawn
    # uniformly in ±crosstalk (relative, torque rows scaled by crosstalk_length_m).
    crosstalk: float = 0.01
    crosstalk_length_m: float = 0.05
    # Calibration gain error per axis, relative (0.01: the axis reads 1 % high); with the
    # cross-talk it makes the sensor's calibration matrix diag(1 + gain_error)·(I + E).
    gain_error: list[float] = dc.field(default_factory=lambda: [0.0] * 6)
    # Mounting error: the frame Sm the sensor measures in is S rotated by these roll, pitch,
    # yaw angles (deg, R_SSm = RollPitchYaw), about So; as a sensor mounted a bolt off or a
    # model's frame a little wrong. The controller's and compensators' models do not know it.
    mounting_rpy_deg: list[float] = dc.field(default_factory=lambda: [1.5, -2.0, 1.0])
    # Temperature (°C): ambient, plus the wrist's warm-up from t = 0, a first-order rise of
    # temperature_rise_c with time constant temperature_time_constant_s.
    temperature_ambient_c: float = 22.0
    temperature_rise_c: float = 10.0
    temperature_time_constant_s: float = 600.0
    # Zero drift per kelvin above temperature_ambient_c (N/K, N·m/K). Order of magnitude from
    # strain-gauge load-cell datasheets, which quote a zero temperature effect of about
    # 0.01–0.05 % of full scale per K; here ≈ 0.03 % of the ati_gamma ranges (130 N, 400 N,
    # 10 N·m), signs mixed. Not a value from an F/T sensor's datasheet.
    temperature_coefficients: list[float] = dc.field(
        default_factory=lambda: [0.039, -0.026, 0.12, 0.003, -0.0025, 0.002]
    )
    # How long the wrench stream lags the joint states (s, ≥ 0; rounded to whole samples):
    # a real robot's F/T driver and joint-state driver have different latencies, so a log
    # pairs each reading with a later joint state (ftdrake.data.stream_delay's convention,
    # d > 0: the wrench lags). 0: no delay (the simulation's streams are in step).
    stream_delay_s: float = 0.0
    # Vibration while the arm moves (a real wrist's, which the joint encoders do not see):
    # extra white noise per axis whose σ grows with the arm's motion,
    #   σ_vib = vibration_per_speed·‖q̇‖ + vibration_per_acceleration·‖q̈‖
    # (N, N·m per rad/s and per rad/s²; ‖·‖ over the arm's joints), added to the reading
    # beside noise_std and drawn from its own stream (the rest of the run's noise is unchanged).
    # Zeros (the default): off, the sensor takes no joint inputs and every reading is as before.
    vibration_per_speed: list[float] = dc.field(default_factory=lambda: [0.0] * 6)
    vibration_per_acceleration: list[float] = dc.field(default_factory=lambda: [0.0] * 6)
    # Set False to get an ideal sensor (no noise, bias, drift, cross-talk, quantization, filter,
    # saturation); the sample rate still applies.
    imperfections: bool = True
    seed: int = 0  # noise and drift of this run
    calibration_seed: int = 0  # the cross-talk matrix: a property of the physical sensor

    def spec(self, where: str = "sensor") -> SensorSpec:
        """The resolved numbers: preset values with this config's overrides applied (a
        ConfigError names an override that is not a list, as ``where.field``)."""
        for name in ("range", "resolution", "noise_std"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, (list, tuple)):
                raise ConfigError(f"{where}.{name}: must be a list of 6 numbers (one per "
                                  f"axis Fx..Tz), got {value!r}")
        if self.preset not in SENSOR_PRESETS:
            raise ConfigError(
                f"sensor.preset: unknown preset {self.preset!r}; "
                f"expected one of {sorted(SENSOR_PRESETS)}"
            )
        base = SENSOR_PRESETS[self.preset]
        return SensorSpec(
            rate_hz=base.rate_hz if self.rate_hz is None else float(self.rate_hz),
            range=tuple(base.range if self.range is None else self.range),
            resolution=tuple(base.resolution if self.resolution is None else self.resolution),
            noise_std=tuple(base.noise_std if self.noise_std is None else self.noise_std),
            bandwidth_hz=(
                base.bandwidth_hz if self.bandwidth_hz is None else float(self.bandwidth_hz)
            ),
        )

    @property
    def vibrates(self) -> bool:
        """Whether the reading carries motion-dependent vibration (the sensor then reads the
        arm's joint state and acceleration)."""
        return any(float(v) != 0.0 for v in (*self.vibration_per_speed,
                                              *self.vibration_per_acceleration))

    @property
    def drift(self) -> tuple:
        """`drift_std` as a tuple (as :attr:`SensorStreamConfig.drift` gives it)."""
        return tuple(self.drift_std)

    def validate(self, where: str = "sensor") -> None:
        spec = self.spec(where)
        positive(spec.rate_hz, f"{where}.rate_hz")
        positive(spec.bandwidth_hz, f"{where}.bandwidth_hz")
        for name, values, allow_zero in (
            ("range", spec.range, False),
            ("resolution", spec.resolution, True),
            ("noise_std", spec.noise_std, True),
            ("bias", self.bias, None),
            ("drift_std", self.drift_std, True),
            ("vibration_per_speed", self.vibration_per_speed, True),
            ("vibration_per_acceleration", self.vibration_per_acceleration, True),
        ):
            six(values, f"{where}.{name}")
            if allow_zero is not None:
                for v in values:
                    (non_negative if allow_zero else positive)(v, f"{where}.{name}")
        non_negative(self.crosstalk, f"{where}.crosstalk")
        six(self.gain_error, f"{where}.gain_error")
        if max(abs(float(v)) for v in self.gain_error) >= 0.2:
            raise ConfigError(f"{where}.gain_error: {self.gain_error} is implausibly large "
                              "(each within ±0.2)")
        if self.crosstalk >= 0.2:
            raise ConfigError(f"{where}.crosstalk: {self.crosstalk} is implausibly large (< 0.2)")
        vector(self.mounting_rpy_deg, 3, f"{where}.mounting_rpy_deg")
        if max(abs(v) for v in self.mounting_rpy_deg) > 30:
            raise ConfigError(f"{where}.mounting_rpy_deg: {self.mounting_rpy_deg} is not a "
                              "mounting error (each angle within ±30°)")
        finite([self.temperature_ambient_c, self.temperature_rise_c],
                f"{where}.temperature_ambient_c/temperature_rise_c")
        positive(self.temperature_time_constant_s, f"{where}.temperature_time_constant_s")
        non_negative(self.stream_delay_s, f"{where}.stream_delay_s")
        if self.stream_delay_s > 1.0:
            raise ConfigError(f"{where}.stream_delay_s: {self.stream_delay_s} s is not a "
                              "driver's latency (at most 1 s)")
        six(self.temperature_coefficients, f"{where}.temperature_coefficients")

