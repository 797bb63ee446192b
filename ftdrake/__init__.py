"""ftdrake: learned compensation of wrist force/torque sensors, on Drake's systems framework.

Everything a user needs is importable from here; examples never import a submodule. The
layers, from the bottom up: ``conventions`` / ``errors`` / ``config`` / ``signals``,
``physics`` (rigid-body kinematics), ``systems`` (one LeafSystem a module), ``compensation``
(estimators, registry, compiled predictors), ``sim`` (scene, trajectories, station, simulate,
evaluation, collection), ``data`` (datasets and robot logs), ``experiments`` (demo, study) and
``cli``.
"""

from .version import ftdrake_version

__version__ = ftdrake_version()

from .compensation.forest import RandomForestCompensator
from .compensation.gpr import GPRCompensator
from .compensation.hybrid import HybridCompensator
from .compensation.persistence import load_model, save_model
from .compensation.physics import PhysicsPayloadCompensator
from .compensation.svr import SVRCompensator
from .config import (
    BiasTrackerConfig,
    CableConfig,
    CompensatorConfig,
    ControllerConfig,
    DetectorConfig,
    EventsConfig,
    ScenarioConfig,
    SensorConfig,
    TaskConfig,
    TrajectoryConfig,
    load_config,
    save_config,
)
from .conventions import WRENCH_AXES, WRENCH_UNITS
from .data.dataset import joint_state_layout, load_dataset, save_dataset, wrench_targets
from .errors import (
    ConfigError,
    FtdrakeError,
    LogError,
    ModelFileError,
    RobotModelError,
    TrajectoryError,
)
from .sim.collection import collect
from .sim.evaluation import evaluate_detection
from .sim.scene import Scene, add_scene, make_control_plant
from .sim.simulate import SimResult, simulate
from .sim.station import Station, build_station
from .systems.bias_tracker import OnlineBiasTracker
from .systems.compensator import CompensatorSystem
from .systems.contact_truth import ContactTruth
from .systems.controller import DiscreteInverseDynamicsController
from .systems.detector import ContactDetector
from .systems.ft_sensor import ForceTorqueSensor, NoisyForceTorqueSensor

__all__ = [
    "WRENCH_AXES",
    "WRENCH_UNITS",
    "BiasTrackerConfig",
    "CableConfig",
    "CompensatorConfig",
    "CompensatorSystem",
    "ConfigError",
    "ContactDetector",
    "ContactTruth",
    "ControllerConfig",
    "DetectorConfig",
    "DiscreteInverseDynamicsController",
    "EventsConfig",
    "ForceTorqueSensor",
    "FtdrakeError",
    "GPRCompensator",
    "HybridCompensator",
    "LogError",
    "ModelFileError",
    "NoisyForceTorqueSensor",
    "OnlineBiasTracker",
    "PhysicsPayloadCompensator",
    "RandomForestCompensator",
    "RobotModelError",
    "SVRCompensator",
    "ScenarioConfig",
    "Scene",
    "SensorConfig",
    "SimResult",
    "Station",
    "TaskConfig",
    "TrajectoryConfig",
    "TrajectoryError",
    "__version__",
    "add_scene",
    "build_station",
    "collect",
    "evaluate_detection",
    "joint_state_layout",
    "load_config",
    "load_dataset",
    "load_model",
    "make_control_plant",
    "save_config",
    "save_dataset",
    "save_model",
    "simulate",
    "wrench_targets",
]
