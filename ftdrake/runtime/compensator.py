"""CompensatorSystem: a trained compensator in the loop that subtracts the internal wrench."""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem

from ..compensation.compiled.loop import (
    FAULT,
    FAULT_CHANGED,
    OOD,
    OOD_CHANGED,
    external_wrench,
    prepare_row,
)
from ..compensation.contract import loop_view
from ..compensation.estimators.base import generic_row_predictor
from ..errors import ConfigError
from ..signals import (
    DEFAULT_ACCELERATION_CUTOFF_HZ,
    acceleration_filter_gains,
    causal_acceleration_step,
    estimator_size,
)

#: The columns an IMU adds to a row after [q, q̇, q̈]: f_S, ω_S, α_S.
IMU_WIDTH = 9


class CompensatorSystem(LeafSystem):
    """Runs a trained compensator in the loop: predicts the internal wrench, subtracts it.

    Input ports:
      wrench_measured (6): sensor reading ``[Fx Fy Fz Tx Ty Tz]`` in N, N·m, sensor frame S.
      joint_state (2n): ``[q; v]`` in rad, rad/s, as a plant's (model instance) state port.
      joint_acceleration (n, optional): v̇ in rad/s². When not connected, it is estimated
        inside from v (:func:`ftdrake.signals.causal_acceleration` at
        ``acceleration_cutoff_hz``; a real controller has no q̈ sensor).
      temperature (1, optional): the sensor's temperature in °C (the noisy sensor's
        ``temperature`` port). Read only by a model trained with the temperature
        (``model.temperature_in_``; ``needs_temperature``), which then requires it: a
        ConfigError names the port at the first sample if it is not connected. A NaN/inf
        temperature is a fault like any other input.
      imu (6, only for a model that takes an IMU, ``needs_imu``): ``[f_S; ω_S]``, the
        accelerometer's proper acceleration of So in S (m/s², +9.81 up at rest) and the
        gyroscope's ω of S in S (rad/s), of an IMU at So with its axes along S. The angular
        acceleration α of S (rad/s²) is derived here, the causal tracker of q̈ on ω at
        `imu_alpha_cutoff_hz` (as a log's ``imu_alpha_*`` columns are). Required when the
        model needs it (a ConfigError names the port); NaN/inf is a fault (a missing or
        stale IMU sample must be given as NaN, never as the last value).
    Output ports (held between samples; updated every `period` s):
      wrench_internal (6): predicted internal wrench as the sensor reads it, N, N·m (in S,
        or in the sensor's own frame Sm for a model that identified its mounting).
      wrench_compensated (6): the compensated wrench, N, N·m, about So in S: wrench_measured −
        wrench_internal, times the model's ``reading_to_model_frame()`` T when it has one
        (a physics or hybrid model that identified the sensor's mounting rotation or a
        gain/cross-talk matrix: the reading is then in the sensor's own frame Sm, and T
        turns it into S; without T the output is in the frame the sensor measures in).
      wrench_std (6): the model's predictive standard deviation; zeros where it gives none.
      out_of_domain (1): 1.0 when a used joint input lies outside the training range.
      fault (1): 1.0 when the latest inputs held NaN/inf; all other outputs then hold their
        last good values (never a NaN downstream).

    `model` is any fitted ftdrake compensator (or one loaded with ``load_model``), or its
    :class:`~ftdrake.compensation.contract.LoopView`: it follows the loop contract
    (:class:`~ftdrake.compensation.contract.LoopModel`; a ConfigError lists what it lacks)
    and predicts 6 outputs. `n_joints`, if given, must match the model (e.g.
    ``plant.num_positions(arm)``). Each sample runs the model's ``row_predictor()`` (the
    compensator protocol, :mod:`ftdrake.compensation.estimators.base`); a model whose
    ``fused_loop_update()`` gives a compiled update (a forest, the physics payload model, a
    hybrid with a forest residual) runs the input checks, the acceleration estimate and its
    prediction in that one compiled call (:mod:`ftdrake.compensation.compiled.loop`).
    ``fast=False`` goes through ``predict``/``predict_std`` instead (for checking the
    compiled paths). The q̈ estimate is :func:`ftdrake.signals.causal_acceleration`, row by
    row.
    """

    def __init__(self, model, period: float, *, n_joints: int | None = None,
                 acceleration_cutoff_hz: float = DEFAULT_ACCELERATION_CUTOFF_HZ,
                 fast: bool = True, imu_alpha_cutoff_hz: float = 5.0):
        super().__init__()
        view = self.view = loop_view(model, n_joints)  # the loop contract, checked once
        if not (period > 0 and math.isfinite(period)):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        self.model = model = view.model
        self.period = float(period)
        n = self.n = view.n_joints
        #: Whether the model takes the sensor temperature as its last input (°C).
        self.needs_temperature = view.needs_temperature
        #: Whether the model takes an IMU's columns after [q, q̇, q̈] (the ``imu`` input).
        self.needs_imu = view.needs_imu
        # The fused update takes the 3n joint row only; a temperature model runs its
        # own row predictor (compiled too, see Compensator.row_predictor).
        self._fused = (model.fused_loop_update()
                       if fast and not (self.needs_temperature or self.needs_imu) else None)
        if self._fused is not None:
            self._predict = None
        elif fast:
            self._predict = model.row_predictor()
        else:
            self._predict = generic_row_predictor(model)
        self._has_std = view.has_std
        # (0, 6) when the reading is in S already: _external_wrench then only subtracts.
        self._to_S = np.empty((0, 6)) if view.to_S is None else view.to_S
        self._lo, self._hi = view.lo, view.hi
        self._constants = np.array([*acceleration_filter_gains(acceleration_cutoff_hz,
                                                               self.period), self.period])
        self._no_acceleration = np.zeros(n)
        self._imu_constants = (*acceleration_filter_gains(imu_alpha_cutoff_hz, self.period),
                               self.period)
        self._alpha = np.zeros(3)

        self._wrench_port = self.DeclareVectorInputPort("wrench_measured", 6)
        self._state_port = self.DeclareVectorInputPort("joint_state", 2 * n)
        self._accel_port = self.DeclareVectorInputPort("joint_acceleration", n)
        self._temperature_port = self.DeclareVectorInputPort("temperature", 1)
        if self.needs_imu:
            self._imu_port = self.DeclareVectorInputPort("imu", 6)
            # α's tracker on ω (signals.estimator_size(3)).
            self._imu_estimator = self.DeclareDiscreteState(estimator_size(3))
        self._nan_wrench = np.full(6, np.nan)
        # The q̈ estimator's state (signals.estimator_size), and copies of the fault and
        # out-of-domain outputs (so the compiled update knows when those change).
        self._estimator = self.DeclareDiscreteState(estimator_size(n) + 2)
        self._internal = self.DeclareDiscreteState(6)
        self._external = self.DeclareDiscreteState(6)
        self._std = self.DeclareDiscreteState(6)
        self._ood = self.DeclareDiscreteState(1)
        self._fault = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        for name, index in (("wrench_internal", self._internal),
                            ("wrench_compensated", self._external), ("wrench_std", self._std),
                            ("out_of_domain", self._ood), ("fault", self._fault)):
            self.DeclareStateOutputPort(name, index)

    def get_input_port_wrench_measured(self):
        return self.GetInputPort("wrench_measured")

    def get_input_port_joint_state(self):
        return self.GetInputPort("joint_state")

    def get_input_port_joint_acceleration(self):
        return self.GetInputPort("joint_acceleration")

    def get_input_port_temperature(self):
        return self.GetInputPort("temperature")

    def get_input_port_imu(self):
        """The IMU input ``[f_S; ω_S]`` (6; only for a model that needs an IMU)."""
        return self.GetInputPort("imu")

    def get_output_port_wrench_internal(self):
        return self.GetOutputPort("wrench_internal")

    def get_output_port_wrench_compensated(self):
        return self.GetOutputPort("wrench_compensated")

    def get_output_port_wrench_std(self):
        return self.GetOutputPort("wrench_std")

    def get_output_port_out_of_domain(self):
        return self.GetOutputPort("out_of_domain")

    def get_output_port_fault(self):
        return self.GetOutputPort("fault")

    def _update(self, context, state):
        # Runs at the sensor rate, so it makes as few Python calls as it can: Drake starts
        # `state` as a copy of the current state, and compiled code updates it in place.
        measured = self._accel_port.HasValue(context)
        self.compensate(
            self._wrench_port.Eval(context), self._state_port.Eval(context),
            self._accel_port.Eval(context) if measured else self._no_acceleration, measured,
            self._temperature(context) if self.needs_temperature else math.nan,
            state.get_mutable_value(self._estimator), state.get_mutable_value(self._internal),
            state.get_mutable_value(self._external), state.get_mutable_value(self._std),
            state.get_mutable_value(self._ood), state.get_mutable_value(self._fault),
            *((self._imu(context), state.get_mutable_value(self._imu_estimator))
              if self.needs_imu else ()))

    def compensate(self, wrench, x, accel, measured, temperature, estimator, internal,
                   external, std, ood, fault, imu=None, imu_estimator=None) -> None:
        """One sample on plain arrays (what ``_update`` does with the context's): the inputs
        (`accel` used when `measured`; `temperature` °C read only when the model needs it)
        and the state (q̈ estimator with the fault/out-of-domain copies, the five outputs),
        updated in place; `imu` (6) and α's tracker `imu_estimator` only when the model
        needs an IMU. :class:`~ftdrake.runtime.step.ChainStep` calls it too, so the diagram
        and the step run the same code."""
        if self._fused is not None:
            update, arrays = self._fused
            status = update(wrench, x, accel, measured, estimator, self._lo, self._hi,
                            self._constants, self._to_S, *arrays, internal, external, std)
        else:
            row = np.empty(3 * self.n + self.needs_temperature + IMU_WIDTH * self.needs_imu)
            if self.needs_temperature:
                row[-1] = temperature
                if not math.isfinite(row[-1]):
                    wrench = self._nan_wrench  # a fault: _prepare_row then writes nothing
            if self.needs_imu and not np.isfinite(imu).all():
                wrench = self._nan_wrench  # a missing or stale IMU sample: a fault
            status = prepare_row(wrench, x, accel, measured, estimator, row, self._lo,
                                 self._hi, self._constants)
            if self.needs_imu and not status & FAULT:
                self._imu_row(imu, imu_estimator, row)
            if not status & FAULT:
                mean, std_row = self._predict(row)
                internal[:] = mean
                external_wrench(wrench, internal, self._to_S, external)
                if self._has_std:
                    std[:] = std_row
        if status & FAULT_CHANGED:
            fault[0] = float(status & FAULT != 0)
        if status & OOD_CHANGED:
            ood[0] = float(status & OOD != 0)

    def _imu_row(self, imu, imu_estimator, row) -> None:
        """The IMU's nine columns after the 3n joint ones: f_S, ω_S, and α from α's tracker
        on ω (updated once per good sample, as the q̈ tracker is)."""
        n3 = 3 * self.n
        row[n3:n3 + 6] = imu
        causal_acceleration_step(np.ascontiguousarray(imu[3:6], dtype=float), imu_estimator,
                                 *self._imu_constants, self._alpha)
        row[n3 + 6:n3 + 9] = self._alpha

    def _imu(self, context) -> np.ndarray:
        if not self._imu_port.HasValue(context):
            raise ConfigError(
                f"CompensatorSystem {self.get_name()!r}: the model takes an IMU at the sensor "
                "([f_S; ω_S], m/s², rad/s, in S), but the 'imu' input port is not connected; "
                "connect the IMU's reading to it (get_input_port_imu())")
        return self._imu_port.Eval(context)

    def _temperature(self, context) -> float:
        if not self._temperature_port.HasValue(context):
            raise ConfigError(
                f"CompensatorSystem {self.get_name()!r}: the model was trained with the sensor "
                "temperature (°C) as an input, but the 'temperature' input port is not "
                "connected; connect the sensor's temperature output to it "
                "(get_input_port_temperature())")
        return float(self._temperature_port.Eval(context)[0])
