"""The loop contract: what the runtime chain needs of a fitted model, declared once.

:class:`LoopModel` is the protocol (every :class:`~ftdrake.compensation.estimators.base.Compensator`
follows it; the base class declares each member's default). :func:`loop_view` checks a model
against it once, when a chain or a ``CompensatorSystem`` is built, and resolves what the loop
reads into a :class:`LoopView`: the runtime reads the view and never probes the model.
"""

from __future__ import annotations

import dataclasses as dc
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigError
from .features import check_feature_set


@runtime_checkable
class LoopModel(Protocol):
    """A fitted wrench compensator as the loop uses it (see :mod:`.estimators.base` for each
    member).

    features: the feature set (``"q"``, ``"q,qd"``, ``"q,qd,qdd"``).
    n_joints_, n_outputs_ (6): the fitted layout. temperature_in_: the sensor temperature
    (°C) is its last input. input_min_, input_max_: the training range of every input.
    provides_std, std_includes_noise: whether ``predict_std`` is a std, and of a reading.
    input_min_, input_max_: the training range of every input column (set by ``fit``).
    wrench_delay_s_: s, how long the wrench stream lagged the joint states in training.
    """

    features: str
    n_joints_: int
    n_outputs_: int
    temperature_in_: bool
    provides_std: bool
    std_includes_noise: bool
    wrench_delay_s_: float
    input_min_: object
    input_max_: object

    def predict(self, X): ...

    def predict_std(self, X): ...

    def row_predictor(self): ...

    def fused_loop_update(self): ...

    def reading_to_model_frame(self): ...

    def payload_reading_map(self): ...

    def robot_description(self): ...


#: The members :class:`LoopModel` declares, in the order an error lists them.
LOOP_MEMBERS = ("features", "n_joints_", "n_outputs_", "temperature_in_", "provides_std",
                "std_includes_noise", "wrench_delay_s_", "input_min_", "input_max_", "predict",
                "predict_std", "row_predictor", "fused_loop_update", "reading_to_model_frame",
                "payload_reading_map", "robot_description")


@dc.dataclass(frozen=True)
class LoopView:
    """What the loop reads of one model, resolved once (:func:`loop_view`).

    n_joints, features: the layout. needs_temperature: the temperature is an input.
    needs_imu: the rows continue with an IMU's nine columns (``[f_S, ω_S, α_S]``).
    has_std: the model gives a std. reading_std: that std is of a reading (the χ² test's).
    to_S: None, or T (6 × 6) turning ``measured − predicted`` into S. lo, hi: the training
    range of the inputs the model uses (empty: unknown). payload_map: None (identity) or K
    (6 × 6), how a wrench at the sensor shows in the compensated wrench. wrench_delay_s: s.
    robot: the RobotDescription the model was trained on, or None (a model without one).
    """

    model: object
    n_joints: int
    features: str
    needs_temperature: bool
    needs_imu: bool
    has_std: bool
    reading_std: bool
    to_S: np.ndarray | None
    lo: np.ndarray
    hi: np.ndarray
    payload_map: np.ndarray | None
    wrench_delay_s: float
    robot: object


def loop_view(model, n_joints: int | None = None) -> LoopView:
    """`model` checked against :class:`LoopModel` (a ConfigError lists what it lacks) and
    against `n_joints` (when given), resolved for the loop."""
    if isinstance(model, LoopView):
        model = model.model
    if not isinstance(model, LoopModel):
        missing = [name for name in LOOP_MEMBERS if not hasattr(model, name)]
        raise ConfigError(
            f"{type(model).__name__} is not a fitted ftdrake compensator: it lacks "
            f"{', '.join(missing)} (the loop contract, ftdrake.compensation.contract."
            "LoopModel; load a model with ftdrake.load_model or fit a compensator first)")
    used = check_feature_set(model.features)
    if int(model.n_outputs_) != 6:
        raise ConfigError(f"the model predicts {model.n_outputs_} outputs; a wrench needs 6 "
                          "(a joint-torque model cannot compensate a wrench sensor)")
    n = int(model.n_joints_)
    if n_joints is not None and n != int(n_joints):
        raise ConfigError(f"the model was trained for {n} joints; this robot has {n_joints}")
    lo, hi = _training_box(model, used * n)
    to_S = model.reading_to_model_frame()
    payload_map = model.payload_reading_map()
    return LoopView(
        model=model, n_joints=n, features=model.features,
        needs_temperature=bool(model.temperature_in_),
        needs_imu=bool(getattr(model, "needs_imu", False)), has_std=bool(model.provides_std),
        reading_std=bool(model.provides_std and model.std_includes_noise),
        to_S=None if to_S is None else np.ascontiguousarray(to_S, dtype=float),
        lo=lo, hi=hi, payload_map=None if payload_map is None else np.asarray(payload_map),
        wrench_delay_s=float(model.wrench_delay_s_ or 0.0), robot=model.robot_description())


def _training_box(model, used: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower/upper training range of the `used` inputs the model uses (empty when the model
    recorded none: None)."""
    lo, hi = model.input_min_, model.input_max_
    if lo is None or hi is None:
        return np.empty(0), np.empty(0)
    return np.asarray(lo[:used], dtype=float), np.asarray(hi[:used], dtype=float)
