"""ftdrake: learned compensation of wrist force/torque sensors, on Drake's systems framework.

Everything a user needs is importable from here.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ftdrake")
except PackageNotFoundError:  # running from a source tree without installing
    __version__ = "0.0.0+unknown"

from .compensation.forest import RandomForestCompensator
from .compensation.gpr import GPRCompensator
from .compensation.hybrid import HybridCompensator
from .compensation.persistence import ModelFileError, load_model, save_model
from .compensation.physics import PhysicsPayloadCompensator
from .compensation.svr import SVRCompensator
from .config import (
    CableConfig,
    ConfigError,
    ControllerConfig,
    ScenarioConfig,
    SensorConfig,
    TrajectoryConfig,
    load_config,
    save_config,
)
from .controller import DiscreteInverseDynamicsController
from .diagram import Simulation, build_diagram
from .sensor import ForceTorqueSensor, NoisyForceTorqueSensor
from .simulation import run
from .systems import CompensatorSystem, ContactDetector, DetectorConfig
from .trajectories import TrajectoryError

__all__ = [
    "CableConfig",
    "CompensatorSystem",
    "ConfigError",
    "ContactDetector",
    "ControllerConfig",
    "DetectorConfig",
    "DiscreteInverseDynamicsController",
    "ForceTorqueSensor",
    "GPRCompensator",
    "HybridCompensator",
    "ModelFileError",
    "NoisyForceTorqueSensor",
    "PhysicsPayloadCompensator",
    "RandomForestCompensator",
    "SVRCompensator",
    "ScenarioConfig",
    "SensorConfig",
    "Simulation",
    "TrajectoryConfig",
    "TrajectoryError",
    "__version__",
    "build_diagram",
    "load_config",
    "load_model",
    "run",
    "save_config",
    "save_model",
]
