"""ftdrake: learned compensation of wrist force/torque sensors, on Drake's systems framework.

Everything a user needs is importable from here.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ftdrake")
except PackageNotFoundError:  # running from a source tree without installing
    __version__ = "0.0.0+unknown"

from .config import (  # noqa: E402
    CableConfig,
    ConfigError,
    ControllerConfig,
    ScenarioConfig,
    SensorConfig,
    TrajectoryConfig,
    load_config,
    save_config,
)
from .compensation.forest import RandomForestCompensator  # noqa: E402
from .compensation.gpr import GPRCompensator  # noqa: E402
from .compensation.hybrid import HybridCompensator  # noqa: E402
from .compensation.persistence import ModelFileError, load_model, save_model  # noqa: E402
from .compensation.physics import PhysicsPayloadCompensator  # noqa: E402
from .compensation.svr import SVRCompensator  # noqa: E402
from .diagram import Simulation, build_diagram  # noqa: E402
from .systems import CompensatorSystem, ContactDetector, DetectorConfig  # noqa: E402
from .sensor import ForceTorqueSensor, NoisyForceTorqueSensor  # noqa: E402
from .simulation import run  # noqa: E402
from .trajectories import TrajectoryError  # noqa: E402

__all__ = [
    "CompensatorSystem",
    "ContactDetector",
    "DetectorConfig",
    "GPRCompensator",
    "HybridCompensator",
    "ModelFileError",
    "PhysicsPayloadCompensator",
    "RandomForestCompensator",
    "SVRCompensator",
    "load_model",
    "save_model",
    "CableConfig",
    "ConfigError",
    "ControllerConfig",
    "ForceTorqueSensor",
    "NoisyForceTorqueSensor",
    "ScenarioConfig",
    "SensorConfig",
    "Simulation",
    "TrajectoryConfig",
    "TrajectoryError",
    "__version__",
    "build_diagram",
    "load_config",
    "run",
    "save_config",
]
