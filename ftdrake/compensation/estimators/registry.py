"""Every compensator ftdrake ships, by the name commands and configs use.

One entry per compensator: its class, the defaults ``train`` builds it with, how it builds
itself for given targets and a robot description (:meth:`CompensatorEntry.make_for`), the
options it adds to ``train``, its tuning grids by preset, whether it needs a robot
description, and the extra types its model files may hold. ``train``, ``calibrate``,
``study``, the demo, tuning presets and the model-file loader all read this table, so adding
a compensator means one new module (a :class:`~.base.Compensator` subclass, with its own
``make`` and :class:`~.build.TrainOption` s if the defaults are not enough) and one entry in
:data:`REGISTRY` (``register``).

Python builds what ``train`` builds with :func:`make_estimator`.
"""

from __future__ import annotations

import dataclasses as dc
from collections.abc import Callable, Mapping
from typing import Any

from .arm import ArmDynamicsCompensator
from .base import Compensator
from .build import BuildRequest, RobotOptions, TrainOption, is_wrench, wrench_only_error
from .forest import RandomForestCompensator
from .gpr import GPRCompensator
from .hybrid import HybridCompensator
from .imu_physics import ImuPayloadCompensator
from .physics import PhysicsPayloadCompensator
from .robot_based import (
    ARM_DEFAULTS,
    DRIVE_GAINS,
    HYBRID_DEFAULTS,
    IMU_PAYLOAD_OPTIONS,
    PAYLOAD_OPTIONS,
    PHYSICS_DEFAULTS,
    make_arm_entry,
    make_hybrid,
    make_imu_physics,
    make_physics,
)
from .svr import SVRCompensator

# The study's grids. RF: integer max_features 2..21 (clipped to the number of used features).
# SVR: the linear kernel has no gamma, so it is not crossed with gamma (6 + 3·36 = 114
# distinct candidates instead of 144).
_C_DECADES = [1.0, 10.0, 100.0, 1e3, 1e4, 1e5]
_GAMMA_DECADES = [0.001, 0.01, 0.1, 1.0, 10.0, 100.0]
_RF_PRESETS = {
    "paper": [{"n_estimators": list(range(100, 2001, 100)),
               "max_features": list(range(2, 22)),
               "min_samples_leaf": list(range(2, 53, 10))}],
    # Everyday: a few candidates around what works on arm data, seconds per axis for a few
    # thousand rows. Fractional max_features suits every feature set.
    "quick": [{"n_estimators": [40], "max_features": [0.33, 1.0], "min_samples_leaf": [2, 12]}],
}
_SVR_PRESETS = {
    "paper": [{"kernel": ["linear"], "C": _C_DECADES},
              {"kernel": ["rbf", "poly", "sigmoid"], "C": _C_DECADES, "gamma": _GAMMA_DECADES}],
    # gamma by sklearn's rules, 1 / (n_inputs · var(inputs)) and 1 / n_inputs, so that the
    # kernel's width follows the number of inputs (fixed values suit one feature set only).
    "quick": [{"kernel": ["rbf"], "C": [1.0, 10.0, 100.0], "gamma": ["scale", "auto"]}],
}
# A GP keeps its fitted kernels (hyper-parameters only); skops does not trust them by default.
_GP_KERNELS = tuple(f"sklearn.gaussian_process.kernels.{k}"
                    for k in ("ConstantKernel", "Product", "RBF", "Sum", "WhiteKernel"))
# What a physics model keeps from its identification (the result and a prior).
_PHYSICS_TYPES = ("ftdrake.compensation.identification.consistent.ConsistentIdentification",
                  "ftdrake.compensation.identification.consistent.PayloadPrior")
#: A hybrid with its out-of-domain std calibrated (what ``train``'s domain options save).
_DOMAIN_CALIBRATED = "ftdrake.compensation.estimators.domain_calibrated.DomainCalibratedHybrid"


@dc.dataclass(frozen=True)
class CompensatorEntry:
    """How ftdrake builds, tunes and loads one kind of compensator.

    make: builds the unfitted compensator for a :class:`~.build.BuildRequest` (targets, robot
      description, options); None: :meth:`build` with the defaults, the request's features
      and its seed as ``random_state`` (when the class has one).
    train_options: the options `make` reads, which ``ftdrake train`` offers as flags.
    """

    name: str  # TrainOptions.kind, the command line's and configs' name of it
    cls: type[Compensator]
    summary: str
    defaults: Mapping[str, Any] = dc.field(default_factory=dict)  # ``train``'s arguments
    presets: Mapping[str, list[dict]] = dc.field(default_factory=dict)  # tuning grids
    needs_robot: bool = False  # identifies physics from a robot description
    wrench_only: bool = False  # predicts a 6-axis wrench only (not joint torques)
    trusted_types: tuple[str, ...] = ()  # types its files hold beyond skops's defaults
    make: Callable[[BuildRequest], Compensator] | None = None
    train_options: tuple[TrainOption, ...] = ()

    def build(self, **overrides) -> Compensator:
        """An unfitted compensator with the defaults, overridden by `overrides`."""
        return self.cls(**{**self.defaults, **overrides})

    def make_for(self, request: BuildRequest) -> Compensator:
        """The unfitted compensator for `request` (see `make`)."""
        if self.make is not None:
            return self.make(request)
        if self.wrench_only and not is_wrench(request.target_names):
            raise wrench_only_error(request.kind, request.target_names)
        overrides = {"features": request.features} if request.features else {}
        if "random_state" in self.cls().get_params():
            overrides["random_state"] = request.seed
        return self.build(**overrides)


REGISTRY: dict[str, CompensatorEntry] = {e.name: e for e in (
    # One thread per forest: a grid search runs fits in parallel, and a forest's own threads
    # would add its trees' predictions in a varying order (round-off differences).
    CompensatorEntry("rf", RandomForestCompensator, "random forest (the study's RF)",
                     {"features": "q,qd,qdd", "n_jobs": 1}, _RF_PRESETS),
    CompensatorEntry("svr", SVRCompensator, "support vector regression (the study's SVR)",
                     {"features": "q,qd,qdd"}, _SVR_PRESETS),
    CompensatorEntry("gpr", GPRCompensator, "Gaussian process with predictive std",
                     {"features": "q,qd,qdd"}, trusted_types=_GP_KERNELS),
    CompensatorEntry("physics", PhysicsPayloadCompensator,
                     "rigid payload + sensor biases, a physically possible body (SDP)",
                     PHYSICS_DEFAULTS, needs_robot=True, wrench_only=True,
                     trusted_types=_PHYSICS_TYPES, make=make_physics,
                     train_options=PAYLOAD_OPTIONS),
    CompensatorEntry("hybrid", HybridCompensator,
                     "physics + a forest on its residual (cable, cross-talk, the rest)",
                     HYBRID_DEFAULTS, needs_robot=True, wrench_only=True,
                     trusted_types=(*_PHYSICS_TYPES, _DOMAIN_CALIBRATED), make=make_hybrid,
                     train_options=PAYLOAD_OPTIONS),
    CompensatorEntry("arm", ArmDynamicsCompensator,
                     "joint torques: the arm's rigid-body dynamics + friction, physically "
                     "consistent", ARM_DEFAULTS, needs_robot=True, make=make_arm_entry,
                     train_options=(DRIVE_GAINS,)),
    CompensatorEntry("imu-physics", ImuPayloadCompensator,
                     "the physics payload model with ω, α and a − g from an IMU at the sensor "
                     "(the log's imu_* columns)",
                     {**PHYSICS_DEFAULTS, "features": "q,qd,qdd", "mode": "dynamic"},
                     needs_robot=True, wrench_only=True, trusted_types=_PHYSICS_TYPES,
                     make=make_imu_physics, train_options=IMU_PAYLOAD_OPTIONS),
)}
#: The model ``train`` fits when none is named: with a robot description, the hybrid
#: (physics extrapolates where a black box cannot); without one, the random forest.
DEFAULT_KIND = "rf"
DEFAULT_KIND_WITH_ROBOT = "hybrid"

#: Types a model file may hold beyond the registry's classes and skops's defaults.
COMMON_TRUSTED_TYPES: tuple[str, ...] = (
    "ftdrake.compensation.estimators.tuning.PerOutputCompensator",  # what per-axis tuning returns
    # calibrate's model of a table whose orientation is given directly (no robot).
    "ftdrake.compensation.calibration.orientation_model.OrientationPayloadCompensator",
    # scikit-learn's tree node storage. sklearn follows its node indices without bounds
    # checks, so every loaded tree is checked before the model is returned.
    "sklearn.tree._tree.Tree",
    # A std that grows with the motion, around any of the above (train --motion-std).
    "ftdrake.compensation.estimators.motion_std.MotionStdCompensator",
    "ftdrake.compensation.estimators.motion_std.MotionNoiseModel",
)


def register(new: CompensatorEntry) -> CompensatorEntry:
    """Adds `new` to :data:`REGISTRY` (a ValueError if its name is taken); returns it."""
    if new.name in REGISTRY:
        raise ValueError(f"a compensator named {new.name!r} is registered already")
    REGISTRY[new.name] = new
    return new


def names() -> list[str]:
    """The registered compensator names, in registration order."""
    return list(REGISTRY)


def entry(name: str) -> CompensatorEntry:
    """The entry named `name`; a ValueError listing the names otherwise."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown compensator {name!r}; expected one of {names()}") from None


def entry_for(estimator) -> CompensatorEntry:
    """The entry of an estimator instance, class, or class name."""
    cls = estimator if isinstance(estimator, type) else type(estimator)
    for e in REGISTRY.values():
        if cls is e.cls or (isinstance(estimator, str) and estimator == e.cls.__name__):
            return e
    label = estimator if isinstance(estimator, str) else cls.__name__
    raise ValueError(f"{label} is not a registered compensator; registered: {names()}")


def trusted_types() -> tuple[str, ...]:
    """Every type a model file may hold beyond skops's defaults."""
    own = [f"{e.cls.__module__}.{e.cls.__qualname__}" for e in REGISTRY.values()]
    extra = [t for e in REGISTRY.values() for t in e.trusted_types]
    return tuple(dict.fromkeys([*own, *COMMON_TRUSTED_TYPES, *extra]))


def train_options() -> list[TrainOption]:
    """Every registered entry's train options, each once, in registration order (what
    ``ftdrake train`` adds as flags)."""
    found: dict[str, TrainOption] = {}
    for e in REGISTRY.values():
        for option in e.train_options:
            found.setdefault(option.name, option)
    return list(found.values())


def option_owners(name: str) -> list[str]:
    """The names of the entries that take train option `name`."""
    return [e.name for e in REGISTRY.values() if any(o.name == name for o in e.train_options)]


def default_kind(robot: RobotOptions | None = None) -> str:
    """The compensator ``train`` fits when none is named (:data:`DEFAULT_KIND`)."""
    if robot is not None and robot.robot is not None:
        return DEFAULT_KIND_WITH_ROBOT
    return DEFAULT_KIND


def make_estimator(kind: str, *, features: str | None = None, seed: int = 0, target_names=(),
                   robot: RobotOptions | None = None,
                   options: Mapping[str, Any] | None = None) -> Compensator:
    """The unfitted compensator registered as `kind`, as ``ftdrake train`` builds it.

    Args:
      kind: a registry name (:func:`names`: ``rf``, ``svr``, ``gpr``, ``physics``,
        ``hybrid``, ``arm``, and any registered since).
      features: ``q``, ``q,qd`` or ``q,qd,qdd``; None: the entry's default (physics: q is
        static, q,qd,qdd dynamic; hybrid: the residual forest's, default q on a wrench and
        q,qd,qdd on joint torques).
      seed: random state of the models that have one.
      target_names: the data's targets; a wrench-only model refuses others, a robot-based
        one builds the arm's torque model on them.
      robot: the robot description of robot-based entries.
      options: values of train options (:func:`train_options`, by name); options `kind`
        does not take must be left at their defaults.

    Errors (:class:`~ftdrake.errors.ConfigError`, :class:`~ftdrake.errors.RobotModelError`)
    name the ``train`` flag that fixes them.
    """
    chosen = entry(kind)
    given = dict(options or {})
    known = {o.name: o for o in train_options()}
    unknown = sorted(set(given) - set(known))
    if unknown:
        raise ValueError(f"unknown train options {unknown}; registered: {sorted(known)}")
    for name, value in given.items():
        if known[name].given(value) and name not in {o.name for o in chosen.train_options}:
            raise known[name].misuse(option_owners(name))
    values = {o.name: given.get(o.name, o.default) for o in chosen.train_options}
    request = BuildRequest(kind, features, seed, tuple(target_names), robot or RobotOptions(),
                           values)
    return chosen.make_for(request)
