"""ftdrake: learned compensation of wrist force/torque sensors, on Drake's systems framework.

Everything a user needs is importable from here; examples never import a submodule. The
layers, from the bottom up (a module imports only from its own layer or those below):

1. ``conventions``, ``errors``, ``config``, ``signals``, ``io``, ``assets``: names, units, the
   typed YAML tree, shared signal processing.
2. ``physics``: rigid-body kinematics and dynamics, robot descriptions.
3. ``data``: datasets and robot logs (tables, bags, LCM logs).
4. ``compensation``: the input layout and loop contract; compiled predictors, the payload's
   identification and the metrics; the estimators with their registry; the static-pose
   calibration and the model files (persistence, ONNX), in that order.
5. ``runtime``: the product, :class:`CompensationChain` (compensator → bias tracker →
   detector) that both stations add.
   ``offline``: the one recorder of the chain's signals (:func:`add_recorder`), beside it.
6. ``systems``: the simulation rig's LeafSystems (sensor model, contact truth, controller, ...).
7. ``sim`` (scene, trajectories, station, simulate, evaluation, collection) and ``hardware``
   (live LCM transport around the runtime chain; imports nothing of ``sim`` or ``systems``).
8. ``experiments`` (demo, study, feedforward) and ``cli``.
"""

from .version import ftdrake_version

__version__ = ftdrake_version()

from .compensation.calibration.calibration import calibrate_table
from .compensation.estimators.build import RobotOptions
from .compensation.estimators.forest import RandomForestCompensator
from .compensation.estimators.gpr import GPRCompensator
from .compensation.estimators.hybrid import HybridCompensator
from .compensation.estimators.physics import PhysicsPayloadCompensator
from .compensation.estimators.registry import make_estimator
from .compensation.estimators.svr import SVRCompensator
from .compensation.evaluation.evaluation import evaluate_model, target_ranges
from .compensation.files.persistence import load_model, save_model
from .config import (
    BiasTrackerConfig,
    CableConfig,
    ChainConfig,
    CompensatorConfig,
    ConfigLayoutWarning,
    ControllerConfig,
    DetectorConfig,
    EventsConfig,
    RobotConfig,
    ScenarioConfig,
    SensorConfig,
    SensorStreamConfig,
    TaskConfig,
    TrajectoryConfig,
    load_chain_config,
    load_config,
    save_config,
)
from .conventions import WRENCH_AXES, WRENCH_UNITS
from .data.dataset import joint_state_layout, load_dataset, save_dataset, wrench_targets
from .data.training import ReadOptions, load_training_data
from .errors import (
    ConfigError,
    FtdrakeError,
    LogError,
    ModelFileError,
    RobotModelError,
    TrajectoryError,
)
from .hardware.config import HardwareConfig
from .hardware.station import HardwareStation
from .offline.recorder import Recorder, add_recorder
from .runtime.bias_tracker import OnlineBiasTracker
from .runtime.chain import CompensationChain
from .runtime.compensator import CompensatorSystem
from .runtime.detector import ContactDetector
from .runtime.joint_gravity import JointStateGravity
from .runtime.replay import replay
from .runtime.thresholds import thresholds_for_false_positive_rate
from .sim.collection import collect
from .sim.evaluation import evaluate_detection
from .sim.scene import Scene, add_scene, make_control_plant
from .sim.simulate import SimResult, simulate
from .sim.station import Station, build_station
from .systems.contact_truth import ContactTruth
from .systems.controller import DiscreteInverseDynamicsController
from .systems.ft_sensor import ForceTorqueSensor
from .systems.noisy_sensor import NoisyForceTorqueSensor

__all__ = [
    "WRENCH_AXES",
    "WRENCH_UNITS",
    "BiasTrackerConfig",
    "CableConfig",
    "ChainConfig",
    "CompensationChain",
    "CompensatorConfig",
    "CompensatorSystem",
    "ConfigError",
    "ConfigLayoutWarning",
    "ContactDetector",
    "ContactTruth",
    "ControllerConfig",
    "DetectorConfig",
    "DiscreteInverseDynamicsController",
    "EventsConfig",
    "ForceTorqueSensor",
    "FtdrakeError",
    "GPRCompensator",
    "HardwareConfig",
    "HardwareStation",
    "HybridCompensator",
    "JointStateGravity",
    "LogError",
    "ModelFileError",
    "NoisyForceTorqueSensor",
    "OnlineBiasTracker",
    "PhysicsPayloadCompensator",
    "RandomForestCompensator",
    "ReadOptions",
    "Recorder",
    "RobotConfig",
    "RobotModelError",
    "RobotOptions",
    "SVRCompensator",
    "ScenarioConfig",
    "Scene",
    "SensorConfig",
    "SensorStreamConfig",
    "SimResult",
    "Station",
    "TaskConfig",
    "TrajectoryConfig",
    "TrajectoryError",
    "__version__",
    "add_recorder",
    "add_scene",
    "build_station",
    "calibrate_table",
    "collect",
    "evaluate_detection",
    "evaluate_model",
    "joint_state_layout",
    "load_chain_config",
    "load_config",
    "load_dataset",
    "load_model",
    "load_training_data",
    "make_control_plant",
    "make_estimator",
    "replay",
    "save_config",
    "save_dataset",
    "save_model",
    "simulate",
    "target_ranges",
    "thresholds_for_false_positive_rate",
    "wrench_targets",
]
