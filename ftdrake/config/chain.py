"""ChainConfig: the product's own configuration — what a :class:`CompensationChain` is built
from, on a live robot, over a log, or inside a simulated scenario (which contains one).

The sections: ``compensator`` (how the model runs in the loop), ``bias_tracker``,
``detector``, ``sensor`` (the wrench stream as the chain reads it: its rate, the noise the
tracker and the payload-change monitor weigh samples by, the drift that bounds the tracker's
rate, the delay between the wrench and the joint-state streams) and ``robot`` (the kinematics
that joint-state gravity needs; by default the robot embedded in the model).

A live config file (``ftdrake serve --config``) is this section plus its transport; a
scenario file has it as ``chain:``. Loaded with :func:`~ftdrake.config.load_config` /
:func:`~ftdrake.config.parse_config` (``schema=ChainConfig``), validated there; the chain
keeps its own copy, so editing the object afterwards changes no chain already built.
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import copy
import dataclasses as dc
from typing import Optional

from ..errors import ConfigError
from .checks import non_negative, positive, six
from .runtime import BiasTrackerConfig, CompensatorConfig, DetectorConfig
from .sensor import SENSOR_PRESETS, SensorConfig, SensorSpec

#: The sensor a stream without a preset is read as.
DEFAULT_PRESET = "ati_gamma"
#: N/√s, N·m/√s: the default drift of a sensor's zero (a random walk's increment per √s).
DEFAULT_DRIFT_STD = (2e-3, 2e-3, 3e-3, 5e-5, 5e-5, 5e-5)


@dc.dataclass
class SensorStreamConfig:
    """The F/T stream as the chain reads it. A field left unset (null) takes the preset's
    value (:data:`~ftdrake.config.SENSOR_PRESETS`; no preset: ``ati_gamma``); in a simulated
    scenario, the simulated sensor's (:meth:`~ftdrake.config.ScenarioConfig.chain_config`).

    preset: a sensor of :data:`~ftdrake.config.SENSOR_PRESETS`.
    rate_hz: the stream's sample rate (Hz): the chain's update period is its inverse.
    noise_std, resolution: per axis (N, N·m): the white noise of a reading at rest and its
      quantization step; the bias tracker and the payload-change monitor weigh samples by
      max(noise_std, resolution).
    drift_std: the zero's random walk per √s (N/√s, N·m/√s): it bounds how fast the tracker's
      published bias may move (``bias_tracker.rate_bound_sigmas``).
    wrench_delay_s: how long the wrench stream lags the joint states (s; negative: the joint
      states lag); the chain delays the stream that is ahead. Null: the model's own (set by
      training with a delay alignment), else 0.
    """

    preset: Optional[str] = None
    rate_hz: Optional[float] = None
    noise_std: Optional[list[float]] = None
    resolution: Optional[list[float]] = None
    drift_std: Optional[list[float]] = None
    wrench_delay_s: Optional[float] = None

    def filled_from(self, sensor: SensorConfig) -> "SensorStreamConfig":
        """This stream with every unset field taken from a simulated sensor (`sensor`):
        what the chain reads of the sensor a scenario simulates."""
        own = {"preset": sensor.preset, "rate_hz": sensor.rate_hz,
               "noise_std": sensor.noise_std, "resolution": sensor.resolution,
               "drift_std": sensor.drift_std}
        return dc.replace(self, **{name: copy.deepcopy(value) for name, value in own.items()
                                   if getattr(self, name) is None})

    def spec(self) -> SensorSpec:
        """The resolved numbers: the preset's with this config's overrides."""
        preset = self.preset if self.preset is not None else DEFAULT_PRESET
        if preset not in SENSOR_PRESETS:
            raise ConfigError(f"sensor.preset: unknown preset {preset!r}; expected one "
                              f"of {sorted(SENSOR_PRESETS)}")
        base = SENSOR_PRESETS[preset]
        return dc.replace(
            base,
            rate_hz=base.rate_hz if self.rate_hz is None else float(self.rate_hz),
            noise_std=tuple(base.noise_std if self.noise_std is None else self.noise_std),
            resolution=tuple(base.resolution if self.resolution is None else self.resolution))

    @property
    def drift(self) -> tuple:
        """`drift_std`, or the default (:data:`DEFAULT_DRIFT_STD`) when unset."""
        return tuple(DEFAULT_DRIFT_STD if self.drift_std is None else self.drift_std)

    @property
    def period(self) -> float:
        """s: one sample of the stream."""
        return 1.0 / self.spec().rate_hz

    def validate(self, where: str = "chain.sensor") -> "SensorStreamConfig":
        spec = self.spec()
        positive(spec.rate_hz, f"{where}.rate_hz")
        for name, values in (("noise_std", spec.noise_std), ("resolution", spec.resolution),
                             ("drift_std", self.drift)):
            six(values, f"{where}.{name}")
            for v in values:
                non_negative(v, f"{where}.{name}")
        if self.wrench_delay_s is not None:
            delay = self.wrench_delay_s
            if not (isinstance(delay, (int, float)) and abs(delay) <= 1.0):
                raise ConfigError(f"{where}.wrench_delay_s: {delay!r} is not a driver's "
                                  "latency (a number of seconds within ±1; null: the model's)")
        return self


@dc.dataclass
class RobotConfig:
    """The robot whose kinematics the chain computes gravity at the sensor on (bias tracking
    with a payload, payload-change detection).

    file: a URDF/SDF/model-directives file; empty: the robot embedded in the model (every
      physics or hybrid model file carries the robot it was trained on). ``ftdrake`` names
      ftdrake's simulated arm.
    sensor_frame: frame S in `file` (needed with `file`).
    base_frame: `file`'s frame welded to the world (empty: its root).
    """

    file: str = ""
    sensor_frame: str = ""
    base_frame: str = ""

    def validate(self, where: str = "chain.robot") -> "RobotConfig":
        if self.file and self.file != "ftdrake" and not self.sensor_frame:
            raise ConfigError(f"{where}.sensor_frame: {where}.file {self.file!r} needs the name "
                              "of the sensor's frame S in it (the frame the wrench is "
                              "measured in)")
        if (self.sensor_frame or self.base_frame) and not self.file:
            raise ConfigError(f"{where}.file: sensor_frame/base_frame are given without the "
                              "robot file they name frames of")
        return self


@dc.dataclass
class ChainConfig:
    """Compensator → bias tracker → contact detector, on a sensor stream and a robot: all a
    :class:`~ftdrake.runtime.chain.CompensationChain` is built from besides its model."""

    compensator: CompensatorConfig = dc.field(default_factory=CompensatorConfig)
    bias_tracker: BiasTrackerConfig = dc.field(default_factory=BiasTrackerConfig)
    detector: DetectorConfig = dc.field(default_factory=DetectorConfig)
    sensor: SensorStreamConfig = dc.field(default_factory=SensorStreamConfig)
    robot: RobotConfig = dc.field(default_factory=RobotConfig)

    def validate(self, where: str = "chain") -> "ChainConfig":
        self.compensator.validate(f"{where}.compensator")
        self.bias_tracker.validate(f"{where}.bias_tracker")
        self.detector.validate(f"{where}.detector")
        self.sensor.validate(f"{where}.sensor")
        self.robot.validate(f"{where}.robot")
        return self

    def replace(self, **sections) -> "ChainConfig":
        """A copy with the named sections replaced (``config.replace(detector=...)``)."""
        return dc.replace(self, **sections)
