"""Recording any diagram in the layout ``train``, ``evaluate`` and ``replay`` read.

:func:`add_recorder` puts loggers on a user's own diagram — their plant, their controller,
their sensor — and :meth:`Recorder.to_frame` turns them into one table with the columns of
:mod:`ftdrake.sim.simulate`'s logs::

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

==================  ============================================================
``t``               time, s
``q_i``, ``qd_i``   the joint state, rad, rad/s
``qdd_i``           joint accelerations, rad/s² (only with an `acceleration` port)
``qd_est_i``        the velocity the loop uses: the joint state's own ``qd_i``
``qdd_est_i``       the loop's own q̈ estimate: :func:`ftdrake.signals.causal_acceleration`
                    of ``qd`` at `acceleration_cutoff_hz`, row by row — exactly what the
                    :class:`~ftdrake.runtime.compensator.CompensatorSystem` computes
``meas_*``          the sensor's reading, N, N·m
``temperature``     the sensor's temperature, °C (with a `temperature` port)
``contact``         1 while the tool truly touches (with a `contact_true` port)
``external_*``      the true contact wrench (with a `wrench_contact_true` port)
chain outputs       with `chain`: ``pred_*``, ``comp_external_*``, ``est_external_*``,
                    ``pred_std_*``, ``bias_est_*``, ``out_of_domain``, ``fault``,
                    ``detected``, ``detected_force`` (:mod:`~ftdrake.offline.replay`'s names)
==================  ============================================================

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
from ..offline.replay import FLAG_OUTPUTS, INTEGER_COLUMNS, PAYLOAD_COLUMNS, WRENCH_OUTPUTS
from ..signals import causal_acceleration


@dc.dataclass
class Recorder:
    """The loggers :func:`add_recorder` added; :meth:`to_frame` reads them."""

    period: float  # s
    n_joints: int
    acceleration_cutoff_hz: float  # Hz, of the qdd_est estimate
    loggers: dict  # name → VectorLogSink

    def to_frame(self, root_context, *, drop_first: bool = True) -> pd.DataFrame:
        """The recorded signals as one DataFrame (columns in the module docstring), read from
        `root_context` (the context of the whole diagram, e.g. ``simulator.get_context()``)."""
        logs = {name: logger.FindLog(root_context) for name, logger in self.loggers.items()}
        t = logs["joint_state"].sample_times()
        data = {name: log.data().T for name, log in logs.items()}
        for name, log in logs.items():
            if len(log.sample_times()) != len(t):
                raise ConfigError(f"recorder: logger {name!r} has {len(log.sample_times())} "
                                  f"samples, the joint state {len(t)}")
        keep = t > 0.5 * self.period if drop_first else np.ones(len(t), dtype=bool)
        n = self.n_joints
        q, qd = data["joint_state"][keep, :n], data["joint_state"][keep, n:]
        frame = {col.TIME: t[keep]}
        blocks = [(col.Q, q), (col.QD, qd)]
        if "acceleration" in data:
            blocks.append((col.QDD, data["acceleration"][keep]))
        blocks += [(col.QD_EST, qd),
                   (col.QDD_EST, causal_acceleration(qd, self.period,
                                                     self.acceleration_cutoff_hz))]
        for prefix, values in blocks:
            frame.update(zip(col.joint_columns(prefix, n), values.T, strict=True))
        frame.update(zip(col.wrench_columns(col.MEASURED), data["wrench"][keep].T, strict=True))
        _add_optional_columns(frame, data, keep)
        out = pd.DataFrame(frame)
        out.attrs.update(period_s=self.period, acceleration_cutoff_hz=self.acceleration_cutoff_hz)
        return out


def _add_optional_columns(frame: dict, data: dict, keep) -> None:
    """The columns of the signals recorded only when asked: temperature, the truth, and the
    runtime chain's outputs."""
    if "temperature" in data:
        frame[col.TEMPERATURE] = data["temperature"][keep, 0]
    if "contact_true" in data:
        frame[col.CONTACT] = (data["contact_true"][keep, 0] > 0.5).astype(np.int8)
    if "wrench_contact_true" in data:
        frame.update(zip(col.wrench_columns(col.EXTERNAL),
                         data["wrench_contact_true"][keep].T, strict=True))
    for port, prefix in WRENCH_OUTPUTS.items():
        if port in data:
            frame.update(zip(col.wrench_columns(prefix), data[port][keep].T, strict=True))
    if "payload" in data:
        frame.update(zip(PAYLOAD_COLUMNS, data["payload"][keep].T, strict=True))
    for port, name in FLAG_OUTPUTS.items():
        if port in data:
            values = data[port][keep, 0]
            frame[name] = values.astype(np.int8) if name in INTEGER_COLUMNS else values


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
    are logged too. `acceleration_cutoff_hz`: the cut-off of the ``qdd_est`` estimate (the
    chain's when given, else ``CompensatorConfig``'s default) — set it to the loop's.
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
    if chain is not None:
        for name in (*WRENCH_OUTPUTS, "payload", *FLAG_OUTPUTS):
            if chain.HasOutputPort(name):
                ports[name] = chain.GetOutputPort(name)
    if acceleration_cutoff_hz is None:
        acceleration_cutoff_hz = (chain.config.compensator.acceleration_cutoff_hz
                                  if chain is not None
                                  else CompensatorConfig().acceleration_cutoff_hz)
    loggers = {name: LogVectorOutput(port, builder, period)
               for name, port in ports.items() if port is not None}
    return Recorder(float(period), size // 2, float(acceleration_cutoff_hz), loggers)
