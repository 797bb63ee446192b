"""Typed configuration of a scenario, loadable and writable as YAML.

Every dataclass here can be read with :func:`load_config` / written with :func:`save_config`
(Drake's ``yaml_load_typed`` / ``yaml_dump_typed``). Errors name the offending field, e.g.
``scenario.sensor.noise_std: must have 6 entries, got 5``.

A scenario is validated where it is loaded: :func:`load_config` and :func:`parse_config`
check every field. A config built or edited in Python is checked by its ``validate()``
(it returns the config: ``build_station(config.validate())``); the stations and planners do
not check it again. The LeafSystems a user may build on their own from one section
(``NoisyForceTorqueSensor``, ``JointFriction``, ``ContactDetector``, ``OnlineBiasTracker``)
validate that section.

Units: SI throughout (s, m, kg, N, N·m, rad). Wrench vectors are ``[Fx, Fy, Fz, Tx, Ty, Tz]``.

The sections, one module each:

* :mod:`.sensor` — :class:`SensorConfig` and the presets of real sensors.
* :mod:`.plant` — the simulated arm: :class:`ModelsConfig`, :class:`ControllerConfig`,
  :class:`CableConfig`, :class:`FrictionConfig`.
* :mod:`.task` — what a run does: :class:`TrajectoryConfig`, :class:`TaskConfig`,
  :class:`EventsConfig`.
* :mod:`.runtime` — the product's sections: :class:`CompensatorConfig`,
  :class:`BiasTrackerConfig`, :class:`DetectorConfig`, :class:`PayloadChangeConfig`.
* :mod:`.chain` — :class:`ChainConfig`, the product's own root (those sections, the sensor
  stream :class:`SensorStreamConfig` and the robot :class:`RobotConfig`): what a
  ``CompensationChain``, the live stations and ``replay`` are built from.
* :mod:`.transmission` — compliant joints (motor, gearbox spring and damper):
  :class:`TransmissionConfig`, off by default.
* :mod:`.encoders` — the joint encoders' zero offsets and gravity sag:
  :class:`EncoderConfig`, off by default.
* :mod:`.imu` — an accelerometer and gyroscope at the sensor: :class:`ImuConfig`, off by
  default.
* :mod:`.contour` — the hole-cutting task and its tool-side measurements (the two-part
  feedforward experiment).
* :mod:`.scenario` — :class:`ScenarioConfig`, the simulation's root (it contains a
  :class:`ChainConfig`).
* :mod:`.files` — YAML in and out.
"""

from ..errors import ConfigError
from .chain import ChainConfig, RobotConfig, SensorStreamConfig
from .encoders import EncoderConfig
from .files import (
    ConfigLayoutWarning,
    default_scenario_path,
    dump_config,
    load_chain_config,
    load_config,
    parse_config,
    save_config,
)
from .imu import ImuConfig
from .plant import CableConfig, ControllerConfig, FrictionConfig, ModelsConfig
from .runtime import (
    PAYLOAD_INERTIA_PRIOR_STD,
    BiasTrackerConfig,
    CompensatorConfig,
    DetectorConfig,
    PayloadChangeConfig,
    model_has_reading_std,
)
from .scenario import ScenarioConfig
from .sensor import SENSOR_PRESETS, SensorConfig, SensorSpec
from .task import TRAJECTORY_KINDS, EventsConfig, TaskConfig, TrajectoryConfig
from .transmission import TransmissionConfig

__all__ = [
    "PAYLOAD_INERTIA_PRIOR_STD",
    "SENSOR_PRESETS",
    "TRAJECTORY_KINDS",
    "BiasTrackerConfig",
    "CableConfig",
    "ChainConfig",
    "CompensatorConfig",
    "ConfigError",
    "ConfigLayoutWarning",
    "ControllerConfig",
    "DetectorConfig",
    "EncoderConfig",
    "EventsConfig",
    "FrictionConfig",
    "ImuConfig",
    "ModelsConfig",
    "PayloadChangeConfig",
    "RobotConfig",
    "ScenarioConfig",
    "SensorConfig",
    "SensorSpec",
    "SensorStreamConfig",
    "TaskConfig",
    "TrajectoryConfig",
    "TransmissionConfig",
    "default_scenario_path",
    "dump_config",
    "load_chain_config",
    "load_config",
    "model_has_reading_std",
    "parse_config",
    "save_config",
]
