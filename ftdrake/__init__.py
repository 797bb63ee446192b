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
from .diagram import Simulation, build_diagram  # noqa: E402
from .sensor import ForceTorqueSensor, NoisyForceTorqueSensor  # noqa: E402
from .simulation import run  # noqa: E402
from .trajectories import TrajectoryError  # noqa: E402

__all__ = [
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
