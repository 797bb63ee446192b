"""The LeafSystems users put in their own diagrams: CompensatorSystem and ContactDetector."""

from __future__ import annotations

import dataclasses as dc
import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from .compensation.features import check_feature_set


class CompensatorSystem(LeafSystem):
    """Runs a trained compensator in the loop: predicts the internal wrench, subtracts it.

    Input ports:
      wrench_measured (6): sensor reading ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m, sensor frame S.
      joint_state (2n): ``[q; v]`` in rad, rad/s, as a plant's (model instance) state port.
      joint_acceleration (n, optional): v̇ in rad/s². When not connected, it is estimated
        inside by a causal difference of v low-passed at ``acceleration_cutoff_hz`` (a real
        controller has no q̈ sensor).
    Output ports (held between samples; updated every `period` s):
      wrench_internal (6): predicted internal wrench, N, N·m, S.
      wrench_external (6): wrench_measured − wrench_internal, N, N·m, S.
      wrench_std (6): the model's predictive standard deviation; zeros where it gives none.
      out_of_domain (1): 1.0 when a used joint input lies outside the training range.
      fault (1): 1.0 when the latest inputs held NaN/inf; all other outputs then hold their
        last good values (never a NaN downstream).

    `model` is any fitted ftdrake compensator (or one loaded with ``load_model``): it must have
    ``predict``, ``features``, ``n_joints_`` and ``n_outputs_ == 6``. `n_joints`, if given,
    must match the model (e.g. ``plant.num_positions(arm)``).
    """

    def __init__(self, model, period: float, *, n_joints: int | None = None,
                 acceleration_cutoff_hz: float = 25.0, fast: bool = True):
        super().__init__()
        check_model_fits(model, n_joints)
        if not (period > 0 and math.isfinite(period)):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        self.model = model
        self.period = float(period)
        n = self.n = int(model.n_joints_)
        self._predict = _predictor(model, fast)
        self._has_std = bool(getattr(model, "provides_std", False))
        self._alpha = 1.0 - math.exp(-2 * math.pi * acceleration_cutoff_hz * self.period)
        self._lo, self._hi = _training_box(model)

        self._wrench_port = self.DeclareVectorInputPort("wrench_measured", 6)
        self._state_port = self.DeclareVectorInputPort("joint_state", 2 * n)
        self._accel_port = self.DeclareVectorInputPort("joint_acceleration", n)
        # Acceleration estimator: previous v (n), filtered v̇ (n), primed flag (1).
        self._estimator = self.DeclareDiscreteState(2 * n + 1)
        self._internal = self.DeclareDiscreteState(6)
        self._external = self.DeclareDiscreteState(6)
        self._std = self.DeclareDiscreteState(6)
        self._ood = self.DeclareDiscreteState(1)
        self._fault = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        for name, index in (("wrench_internal", self._internal), ("wrench_external", self._external),
                            ("wrench_std", self._std), ("out_of_domain", self._ood),
                            ("fault", self._fault)):
            self.DeclareStateOutputPort(name, index)

    def _update(self, context, state):
        # Drake starts `state` as a copy of the current state: only groups that change are
        # written (this runs at the sensor rate, so Python work here is the loop's cost).
        n = self.n
        wrench = self._wrench_port.Eval(context)
        x = self._state_port.Eval(context)
        measured_accel = (self._accel_port.Eval(context)
                          if self._accel_port.HasValue(context) else None)
        finite = np.isfinite(wrench).all() and np.isfinite(x).all() and (
            measured_accel is None or np.isfinite(measured_accel).all())
        fault = state.get_mutable_vector(self._fault)
        if not finite:
            fault.SetAtIndex(0, 1.0)
            return  # everything else keeps its last good value
        if fault.GetAtIndex(0) != 0.0:
            fault.SetAtIndex(0, 0.0)
        q, v = x[:n], x[n:]
        est = state.get_mutable_vector(self._estimator)
        previous = est.value()
        if measured_accel is not None:
            vdot = measured_accel
        elif previous[-1] == 0.0:
            vdot = np.zeros(n)  # first sample: no difference yet
        else:
            raw = (v - previous[:n]) / self.period
            vdot = previous[n:2 * n] + self._alpha * (raw - previous[n:2 * n])
        est.SetFromVector(np.concatenate([v, vdot, [1.0]]))
        row = np.concatenate([q, v, vdot])
        internal, std = self._predict(row)
        state.get_mutable_vector(self._internal).SetFromVector(internal)
        state.get_mutable_vector(self._external).SetFromVector(wrench - internal)
        if self._has_std:
            state.get_mutable_vector(self._std).SetFromVector(std)
        if self._lo.size:
            used = row[: self._lo.size]
            ood = float(((used < self._lo) | (used > self._hi)).any())
            state.get_mutable_vector(self._ood).SetAtIndex(0, ood)


def check_model_fits(model, n_joints: int | None) -> None:
    """Raises ValueError unless `model` is a fitted 6-output compensator for `n_joints`."""
    for attr in ("predict", "features", "n_joints_", "n_outputs_"):
        if not hasattr(model, attr):
            raise ValueError(f"model lacks {attr!r}: is it a fitted ftdrake compensator?")
    check_feature_set(model.features)
    if model.n_outputs_ != 6:
        raise ValueError(f"model predicts {model.n_outputs_} outputs; a wrench needs 6")
    if n_joints is not None and int(model.n_joints_) != int(n_joints):
        raise ValueError(
            f"model was trained for {model.n_joints_} joints; this robot has {n_joints}"
        )


def _predictor(model, fast: bool):
    """A function row (3n,) → (internal (6,), std (6,)); compiled or lean where possible.

    Forests and SVRs go through ftdrake's compiled predictors, the physics model through its
    per-row path, a hybrid through both; anything else through ``predict``. The per-row
    paths skip scikit-learn's input validation, which costs more than a compiled forest.
    """
    mean = _mean_predictor(model, fast)
    if not getattr(model, "provides_std", False):
        zeros = np.zeros(6)
        return lambda row: (mean(row), zeros)
    return lambda row: (mean(row), np.asarray(model.predict_std(row[None, :])[0], dtype=float))


def _mean_predictor(model, fast: bool):
    if fast and hasattr(model, "physics_") and hasattr(model, "residual_"):
        physics = _mean_predictor(model.physics_, fast)
        residual = _mean_predictor(model.residual_, fast)
        return lambda row: physics(row) + residual(row)
    if fast and hasattr(model, "predict_row"):
        return model.predict_row
    if fast:
        try:
            from .compensation.fast import fast_predictor

            compiled = fast_predictor(model)
            return lambda row: np.asarray(compiled.predict_one(row), dtype=float)
        except TypeError:  # not a forest or SVR: fall back to predict
            pass
    return lambda row: np.asarray(model.predict(row[None, :])[0], dtype=float)


def _training_box(model):
    """Lower/upper training range of the inputs the model uses (empty if unknown)."""
    lo, hi = getattr(model, "input_min_", None), getattr(model, "input_max_", None)
    if lo is None or hi is None:
        return np.empty(0), np.empty(0)
    used = check_feature_set(model.features) * int(model.n_joints_)
    return np.asarray(lo[:used], dtype=float), np.asarray(hi[:used], dtype=float)


# ----------------------------------------------------------------------------------------------
@dc.dataclass
class DetectorConfig:
    """Thresholds of the contact detector.

    Contact switches on when ‖F‖ > force_on (N) or ‖T‖ > torque_on (N·m) for `debounce_on`
    consecutive samples, and off when both are below ``release_ratio`` × those thresholds for
    `debounce_off` samples (hysteresis). With `std_gain` > 0 the thresholds grow by
    ``std_gain · ‖std‖`` of the model's predictive standard deviation.
    """

    force_on: float = 2.5
    torque_on: float = 0.25
    release_ratio: float = 0.6
    debounce_on: int = 3
    debounce_off: int = 25
    std_gain: float = 0.0
    # Detection is off for this long after start: the sensor chain and the compensator's
    # acceleration filter settle first (a real detector arms after the sensor is tared).
    arm_after_s: float = 0.05

    def validate(self) -> DetectorConfig:
        for name in ("force_on", "torque_on"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ValueError(f"detector.{name}: must be positive, got {value!r}")
        if not 0 < self.release_ratio <= 1:
            raise ValueError(f"detector.release_ratio: {self.release_ratio} not in (0, 1]")
        for name in ("debounce_on", "debounce_off"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"detector.{name}: must be >= 1")
        if self.std_gain < 0:
            raise ValueError(f"detector.std_gain: must be >= 0, got {self.std_gain}")
        if not self.arm_after_s >= 0:
            raise ValueError(f"detector.arm_after_s: must be >= 0, got {self.arm_after_s}")
        return self

    @classmethod
    def from_residuals(cls, residual, margin: float = 1.5, quantile: float = 0.999,
                       **overrides) -> DetectorConfig:
        """Thresholds from free-motion residuals (N × 6: measured − predicted wrench on
        held-out contact-free data): `margin` × the `quantile` of ‖F‖ and ‖T‖, floored at
        0.5 N and 0.02 N·m. A quantile, not k·RMS: a learned model's residuals are
        heavy-tailed (largest where the motion leaves the training data)."""
        r = np.asarray(residual, dtype=float)
        if r.ndim != 2 or r.shape[1] != 6 or len(r) < 100:
            raise ValueError(f"residual must be N × 6 with N >= 100; got shape {r.shape}")
        force = np.quantile(np.linalg.norm(r[:, :3], axis=1), quantile)
        torque = np.quantile(np.linalg.norm(r[:, 3:], axis=1), quantile)
        return cls(force_on=max(0.5, margin * force), torque_on=max(0.02, margin * torque),
                   **overrides).validate()


class ContactDetector(LeafSystem):
    """Detects contact from the external wrench, with hysteresis and debouncing.

    Input ports:
      wrench_external (6): ``[Fx Fy Fz Tx Ty Tz]`` N, N·m (e.g. CompensatorSystem's output).
      wrench_std (6, optional): the compensator's predictive std; raises the thresholds by
        ``std_gain · ‖std‖`` when connected.
    Output ports (updated every `period` s):
      contact (1): 1.0 while in contact.
      contact_force (1): ‖F‖ of the external wrench in N while in contact, else 0.
    State: contact flag, contact force, consecutive-sample counter. Disarmed (no contact)
    for the first ``arm_after_s`` seconds.
    """

    def __init__(self, config: DetectorConfig, period: float):
        super().__init__()
        self.config = config.validate()
        self.period = float(period)
        self._wrench_port = self.DeclareVectorInputPort("wrench_external", 6)
        self._std_port = self.DeclareVectorInputPort("wrench_std", 6)
        self._flag = self.DeclareDiscreteState(1)
        self._force = self.DeclareDiscreteState(1)
        self._counter = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareStateOutputPort("contact", self._flag)
        self.DeclareStateOutputPort("contact_force", self._force)

    def _update(self, context, state):
        if context.get_time() < self.config.arm_after_s:
            return  # not armed yet
        w = self._wrench_port.Eval(context)
        if not np.isfinite(w).all():
            return  # hold: a NaN is not evidence either way
        c = self.config
        grow_f = grow_t = 0.0
        if c.std_gain > 0 and self._std_port.HasValue(context):
            std = self._std_port.Eval(context)
            grow_f = c.std_gain * math.hypot(std[0], std[1], std[2])
            grow_t = c.std_gain * math.hypot(std[3], std[4], std[5])
        force, torque = math.hypot(w[0], w[1], w[2]), math.hypot(w[3], w[4], w[5])
        flag = state.get_mutable_vector(self._flag)
        counter = state.get_mutable_vector(self._counter)
        in_contact, count = flag.GetAtIndex(0) > 0.5, counter.GetAtIndex(0)
        if in_contact:
            quiet = (force < c.release_ratio * (c.force_on + grow_f)
                     and torque < c.release_ratio * (c.torque_on + grow_t))
            count = count + 1 if quiet else 0
            if count >= c.debounce_off:
                in_contact, count = False, 0
        else:
            loud = force > c.force_on + grow_f or torque > c.torque_on + grow_t
            count = count + 1 if loud else 0
            if count >= c.debounce_on:
                in_contact, count = True, 0
        flag.SetAtIndex(0, float(in_contact))
        counter.SetAtIndex(0, count)
        state.get_mutable_vector(self._force).SetAtIndex(0, force if in_contact else 0.0)
