"""ftdrake: learned compensation of wrist force/torque sensors, on Drake's systems framework.

Everything a user needs is importable from here; examples never import a submodule. Each
name loads its module on first use (PEP 562): ``import ftdrake`` alone loads nothing else,
and importing one part (``ftdrake.hardware.station`` on a live robot) loads only what that
part imports. The layers, from the bottom up (a module imports only from its own layer or
those below):

1. ``conventions``, ``errors``, ``config``, ``signals``, ``io``, ``assets``: names, units, the
   typed YAML tree, shared signal processing.
2. ``physics``: rigid-body kinematics and dynamics, robot descriptions.
3. ``data``: datasets and robot logs (tables, bags, LCM logs).
4. ``compensation``: the input layout and loop contract; compiled predictors, the payload's
   identification and the metrics; the estimators with their registry; the static-pose
   calibration and the model files (persistence, ONNX), in that order.
5. ``runtime``: the product, :class:`CompensationChain` (compensator → bias tracker →
   detector) that both stations add; ``training``: :func:`train`, the training pipeline.
6. ``offline``: tools around the product: the recorder of the chain's signals
   (:func:`add_recorder`), the chain replayed over a log, the detector's thresholds from a
   false-positive budget, the residual budget.
7. ``systems``: the simulation rig's LeafSystems (sensor model, contact truth, controller, ...).
8. ``sim`` (scene, trajectories, station, simulate, evaluation, collection) and ``hardware``
   (live LCM transport around the runtime chain; imports nothing of ``sim`` or ``systems``).
9. ``experiments`` (demo, study, feedforward) and ``cli``.
"""

import importlib
import importlib.util

from .version import ftdrake_version

__version__ = ftdrake_version()

# Each public name → the module (below ``ftdrake``) that defines it: imported on first use
# (PEP 562), so that importing one part of the package loads only what that part imports.
_EXPORTS = {
    "RobotOptions": "compensation.estimators.build",
    "calibrate_table": "compensation.calibration.calibration",
    "DomainCalibratedHybrid": "compensation.estimators.domain_calibrated",
    "evaluate_model": "compensation.evaluation.evaluation",
    "target_ranges": "compensation.evaluation.evaluation",
    "RandomForestCompensator": "compensation.estimators.forest",
    "GPRCompensator": "compensation.estimators.gpr",
    "HybridCompensator": "compensation.estimators.hybrid",
    "load_model": "compensation.files.persistence",
    "save_model": "compensation.files.persistence",
    "PhysicsPayloadCompensator": "compensation.estimators.physics",
    "ImuPayloadCompensator": "compensation.estimators.imu_physics",
    "MotionNoiseModel": "compensation.estimators.motion_std",
    "MotionStdCompensator": "compensation.estimators.motion_std",
    "make_estimator": "compensation.estimators.registry",
    "SVRCompensator": "compensation.estimators.svr",
    "BiasTrackerConfig": "config",
    "CableConfig": "config",
    "ChainConfig": "config",
    "CompensatorConfig": "config",
    "ConfigLayoutWarning": "config",
    "ControllerConfig": "config",
    "DetectorConfig": "config",
    "EventsConfig": "config",
    "RobotConfig": "config",
    "ScenarioConfig": "config",
    "SensorConfig": "config",
    "SensorStreamConfig": "config",
    "TaskConfig": "config",
    "TrajectoryConfig": "config",
    "load_chain_config": "config",
    "load_config": "config",
    "save_config": "config",
    "WRENCH_AXES": "conventions",
    "WRENCH_UNITS": "conventions",
    "joint_state_layout": "data.dataset",
    "load_dataset": "data.dataset",
    "save_dataset": "data.dataset",
    "wrench_targets": "data.dataset",
    "ReadOptions": "data.training",
    "load_training_data": "data.training",
    "ConfigError": "errors",
    "FtdrakeError": "errors",
    "LogError": "errors",
    "ModelFileError": "errors",
    "RobotModelError": "errors",
    "TrajectoryError": "errors",
    "HardwareConfig": "hardware.config",
    "HardwareStation": "hardware.station",
    "Recorder": "offline.recorder",
    "add_recorder": "offline.recorder",
    "replay": "offline.replay",
    "thresholds_for_false_positive_rate": "offline.thresholds",
    "OnlineBiasTracker": "runtime.bias_tracker",
    "CompensationChain": "runtime.chain",
    "CompensatorSystem": "runtime.compensator",
    "ContactDetector": "runtime.detector",
    "JointStateGravity": "runtime.joint_gravity",
    "collect": "sim.collection",
    "evaluate_detection": "sim.evaluation",
    "Scene": "sim.scene",
    "add_scene": "sim.scene",
    "make_control_plant": "sim.scene",
    "SimResult": "sim.simulate",
    "simulate": "sim.simulate",
    "Station": "sim.station",
    "build_station": "sim.station",
    "ContactTruth": "systems.contact_truth",
    "DiscreteInverseDynamicsController": "systems.controller",
    "ForceTorqueSensor": "systems.ft_sensor",
    "NoisyForceTorqueSensor": "systems.noisy_sensor",
    "TrainOptions": "training",
    "TrainResult": "training",
    "train": "training",
}

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
    "DomainCalibratedHybrid",
    "EventsConfig",
    "ForceTorqueSensor",
    "FtdrakeError",
    "GPRCompensator",
    "HardwareConfig",
    "HardwareStation",
    "HybridCompensator",
    "ImuPayloadCompensator",
    "JointStateGravity",
    "LogError",
    "ModelFileError",
    "MotionNoiseModel",
    "MotionStdCompensator",
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
    "TrainOptions",
    "TrainResult",
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
    "train",
    "wrench_targets",
]


def __getattr__(name: str):
    """A public name (its module imported on first use, then kept), or a submodule
    (``ftdrake.sim`` after a bare ``import ftdrake``)."""
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(importlib.import_module(f".{module}", __name__), name)
    elif not name.startswith("_") and importlib.util.find_spec(f"{__name__}.{name}"):
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
