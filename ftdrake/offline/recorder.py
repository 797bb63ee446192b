"""The one recorder of the runtime chain's signals, in the layout ``train``, ``evaluate`` and
``replay`` read.

Every log of the chain's outputs is made here, whoever runs the chain: the simulated station
(:func:`add_output_loggers`, read by :func:`ftdrake.sim.simulate.simulate`),
:func:`~ftdrake.offline.replay.replay` and the live stations (:class:`UpdateRecorder`, one row
per update), and a user's own diagram (:func:`add_recorder`). The columns of each output port
are :data:`ftdrake.conventions.CHAIN_OUTPUTS`' (``wrench_internal_*``, ``wrench_contact_*``,
``contact`` …; :func:`output_columns`), so the four agree by construction.

:func:`add_recorder` puts loggers on a user's own diagram — their plant, their controller,
their sensor — and :meth:`Recorder.to_frame` turns them into one table::

    builder = DiagramBuilder()
    ...  # the user's plant, controller, sensor
    recorder = ftdrake.add_recorder(builder, joint_state=plant.get_state_output_port(arm),
                                    wrench=sensor_reading, period=0.001)
    diagram = builder.Build()
    simulator = Simulator(diagram); simulator.AdvanceTo(10.0)
    log = recorder.to_frame(simulator.get_context())
    X, Y = ftdrake.joint_state_layout(log), ftdrake.wrench_targets(log)

Columns (one row per `period`; units SI, wrenches ``[Fx Fy Fz Tx Ty Tz]`` as the sensor
reports them):

====================  ============================================================
``t``                 time, s
``q_i``, ``qd_i``     the joint state, rad, rad/s
``qdd_i``             joint accelerations, rad/s² (only with an `acceleration` port)
``qd_est_i``          the velocity the loop uses: the joint state's own ``qd_i``
``qdd_est_i``         the loop's own q̈ estimate: :func:`ftdrake.signals.causal_acceleration`
                      of ``qd`` at `acceleration_cutoff_hz`, row by row — exactly what the
                      :class:`~ftdrake.runtime.compensator.CompensatorSystem` computes
``meas_*``            the sensor's reading, N, N·m
``temperature``       the sensor's temperature, °C (with a `temperature` port)
``contact_true``      1 while the tool truly touches (with a `contact_true` port)
``external_true_*``   the true contact wrench (with a `wrench_contact_true` port)
chain outputs         with `chain`: the columns of every output port it has
                      (:data:`~ftdrake.conventions.CHAIN_OUTPUTS`)
====================  ============================================================

So ``joint_state_layout(log)`` (``source="est"``) gives ``[q, q̇, q̈]`` as the loop sees them,
and a model trained on it gets at run time the inputs it was fitted on. With a discrete
plant, sampled output ports read zero before the plant's first step; the row at t = 0 is
therefore dropped (``to_frame(drop_first=False)`` keeps it).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd
from pydrake.systems.primitives import LogVectorOutput

from .. import conventions as col
from ..config import CompensatorConfig
from ..errors import ConfigError
from ..signals import causal_acceleration


def chain_outputs(chain) -> list[col.ChainOutput]:
    """The rows of :data:`~ftdrake.conventions.CHAIN_OUTPUTS` whose port `chain` (a
    :class:`~ftdrake.runtime.chain.CompensationChain`) has, in the table's order."""
    return [o for o in col.CHAIN_OUTPUTS if chain.HasOutputPort(o.port)]


def output_columns(outputs: dict) -> dict[str, np.ndarray]:
    """{column: (N,) values} of the chain outputs `outputs` ({port: (N, size) array}), named
    as :data:`~ftdrake.conventions.CHAIN_OUTPUTS` says, in its order; a flag becomes int8
    when all its values are finite (a ``view="held"`` replay's first row is NaN)."""
    columns = {}
    for o in col.CHAIN_OUTPUTS:
        if o.port not in outputs:
            continue
        values = np.asarray(outputs[o.port], dtype=float).reshape(-1, o.size)
        if o.flag and np.isfinite(values).all():
            values = values.astype(np.int8)
        columns.update(zip(o.columns, values.T, strict=True))
    return columns


def add_output_loggers(builder, chain, period: float) -> dict:
    """A logger sampled every `period` s on each output port of `chain` (in `builder`, before
    ``Build``): {port name: VectorLogSink}."""
    return {o.port: LogVectorOutput(chain.GetOutputPort(o.port), builder, period)
            for o in chain_outputs(chain)}


def logged_values(loggers: dict, root_context, t=None) -> dict[str, np.ndarray]:
    """{name: (N, size) samples} of `loggers` in `root_context`; each must be sampled at the
    times `t` (default: the first logger's), else RuntimeError names it."""
    logs = {name: logger.FindLog(root_context) for name, logger in loggers.items()}
    if t is None and logs:
        t = next(iter(logs.values())).sample_times()
    for name, log in logs.items():
        times = log.sample_times()
        if len(times) != len(t) or not np.allclose(times, t):
            raise RuntimeError(f"recorder: logger {name!r} has {len(times)} samples, not "
                               f"sampled with the other {len(t)}")
    return {name: log.data().T for name, log in logs.items()}


class UpdateRecorder:
    """The chain's outputs after each update, one row per :meth:`record` call: what
    :func:`~ftdrake.offline.replay.replay` returns and what a live station keeps
    (:meth:`~ftdrake.hardware.core.StationCore.start_recording`).

    `chain`: the :class:`~ftdrake.runtime.chain.CompensationChain` whose output ports are
    read (all it has, :func:`chain_outputs`). :meth:`record` with the update's inputs (the
    live station) gives a log in the replay layout (``t``, ``q_i``, ``qd_i``, ``meas_*``,
    ``temperature``) beside the outputs."""

    def __init__(self, chain):
        self.ports = {o.port: chain.GetOutputPort(o.port) for o in chain_outputs(chain)}
        self._outputs = {name: [] for name in self.ports}
        self._inputs = []

    def __len__(self) -> int:
        return len(next(iter(self._outputs.values()), ()))

    def record(self, context, t: float | None = None, joint_state=None, wrench=None,
               temperature: float | None = None) -> None:
        """Appends the outputs now in `context` (the chain's or its diagram's root context),
        and the update's inputs when given: `t` s, `joint_state` ``[q; v]`` rad, rad/s,
        `wrench` N, N·m, `temperature` °C."""
        self.record_values({name: port.Eval(context) for name, port in self.ports.items()},
                           t, joint_state, wrench, temperature)

    def record_values(self, values: dict, t: float | None = None, joint_state=None,
                      wrench=None, temperature: float | None = None) -> None:
        """As :meth:`record`, the outputs given as {port: value} (a
        :class:`~ftdrake.runtime.step.ChainStep`'s)."""
        for name in self.ports:
            self._outputs[name].append(np.array(values[name], dtype=float))
        if t is not None:
            self._inputs.append((float(t), np.array(joint_state, dtype=float),
                                 np.array(wrench, dtype=float), temperature))

    def outputs(self) -> dict[str, np.ndarray]:
        """{port: (N, size) array}, one row per recorded update."""
        return {name: np.array(rows, dtype=float).reshape(len(rows), self.ports[name].size())
                for name, rows in self._outputs.items()}

    def to_frame(self) -> pd.DataFrame:
        """The recorded updates as a log: the inputs (when recorded) and the outputs'
        columns (:func:`output_columns`)."""
        frame = {}
        if self._inputs:
            t, state, wrench, temperature = zip(*self._inputs, strict=True)
            state = np.array(state)
            n = state.shape[1] // 2
            frame[col.TIME] = np.array(t)
            frame.update(zip(col.joint_columns(col.Q, n), state[:, :n].T, strict=True))
            frame.update(zip(col.joint_columns(col.QD, n), state[:, n:].T, strict=True))
            frame.update(zip(col.wrench_columns(col.MEASURED), np.array(wrench).T, strict=True))
            if temperature[0] is not None:
                frame[col.TEMPERATURE] = np.array(temperature, dtype=float)
        frame.update(output_columns(self.outputs()))
        return pd.DataFrame(frame)


@dc.dataclass
class Recorder:
    """The loggers :func:`add_recorder` added; :meth:`to_frame` reads them."""

    period: float  # s
    n_joints: int
    acceleration_cutoff_hz: float  # Hz, of the qdd_est estimate
    loggers: dict  # name → VectorLogSink (the chain's under their port names)

    def to_frame(self, root_context, *, drop_first: bool = True) -> pd.DataFrame:
        """The recorded signals as one DataFrame (columns in the module docstring), read from
        `root_context` (the context of the whole diagram, e.g. ``simulator.get_context()``)."""
        t = self.loggers["joint_state"].FindLog(root_context).sample_times()
        try:
            data = logged_values(self.loggers, root_context, t)
        except RuntimeError as e:
            raise ConfigError(str(e)) from None
        keep = t > 0.5 * self.period if drop_first else np.ones(len(t), dtype=bool)
        data = {name: values[keep] for name, values in data.items()}
        n = self.n_joints
        q, qd = data["joint_state"][:, :n], data["joint_state"][:, n:]
        frame = {col.TIME: t[keep]}
        blocks = [(col.Q, q), (col.QD, qd)]
        if "acceleration" in data:
            blocks.append((col.QDD, data["acceleration"]))
        blocks += [(col.QD_EST, qd),
                   (col.QDD_EST, causal_acceleration(qd, self.period,
                                                     self.acceleration_cutoff_hz))]
        for prefix, values in blocks:
            frame.update(zip(col.joint_columns(prefix, n), values.T, strict=True))
        frame.update(zip(col.wrench_columns(col.MEASURED), data["wrench"].T, strict=True))
        if "temperature" in data:
            frame[col.TEMPERATURE] = data["temperature"][:, 0]
        if "contact_true" in data:
            frame[col.CONTACT_TRUE] = (data["contact_true"][:, 0] > 0.5).astype(np.int8)
        if "wrench_contact_true" in data:
            frame.update(zip(col.wrench_columns(col.EXTERNAL_TRUE),
                             data["wrench_contact_true"].T, strict=True))
        frame.update(output_columns(data))
        out = pd.DataFrame(frame)
        out.attrs.update(period_s=self.period, acceleration_cutoff_hz=self.acceleration_cutoff_hz)
        return out


def add_recorder(builder, *, joint_state, wrench, period: float, acceleration=None,
                 temperature=None, contact_true=None, wrench_contact_true=None, chain=None,
                 acceleration_cutoff_hz: float | None = None) -> Recorder:
    """Adds loggers sampled every `period` s to `builder` (before ``Build``); returns the
    :class:`Recorder` whose ``to_frame(context)`` gives the table.

    Output ports to log (of systems already in `builder`):
      joint_state (2n): ``[q; v]`` in rad, rad/s (e.g. ``plant.get_state_output_port(arm)``).
      wrench (6): the sensor's reading, N, N·m.
      acceleration (n, optional): v̇ in rad/s² (e.g. the plant's generalized acceleration).
      temperature (1, optional): the sensor's temperature, °C.
      contact_true (1, optional): > 0.5 while the tool truly touches (ground truth).
      wrench_contact_true (6, optional): the true contact wrench, N, N·m.
    `chain`: a :class:`~ftdrake.runtime.chain.CompensationChain` in `builder` whose outputs
    are logged too (:func:`add_output_loggers`). `acceleration_cutoff_hz`: the cut-off of the
    ``qdd_est`` estimate (the chain's when given, else ``CompensatorConfig``'s default) — set
    it to the loop's.
    """
    if not period > 0:
        raise ConfigError(f"add_recorder: period must be a positive number of seconds; "
                          f"got {period!r}")
    size = joint_state.size()
    if size % 2 or wrench.size() != 6:
        raise ConfigError(f"add_recorder: joint_state must be [q; v] (an even size, got {size}) "
                          f"and wrench 6 values (got {wrench.size()})")
    ports = {"joint_state": joint_state, "wrench": wrench, "acceleration": acceleration,
             "temperature": temperature, "contact_true": contact_true,
             "wrench_contact_true": wrench_contact_true}
    if acceleration_cutoff_hz is None:
        acceleration_cutoff_hz = (chain.config.compensator.acceleration_cutoff_hz
                                  if chain is not None
                                  else CompensatorConfig().acceleration_cutoff_hz)
    loggers = {name: LogVectorOutput(port, builder, period)
               for name, port in ports.items() if port is not None}
    if chain is not None:
        loggers.update(add_output_loggers(builder, chain, period))
    return Recorder(float(period), size // 2, float(acceleration_cutoff_hz), loggers)
