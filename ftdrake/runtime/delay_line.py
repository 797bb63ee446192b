"""DelayLine: a vector signal delayed by a (fractional) number of samples.

Joint states and wrenches from a real robot come from different drivers: the wrench stream
often lags the joint states (or the reverse) by a few milliseconds. The chain then pairs a
reading with a joint state it does not belong to; in motion that costs as much as the model's
error. :class:`~ftdrake.runtime.chain.CompensationChain` corrects a known delay by putting a
DelayLine on the stream that is ahead (see :mod:`ftdrake.data.stream_delay` for the
estimate).
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import LeafSystem


class DelayLine(LeafSystem):
    """Outputs its input `delay_samples` samples ago, linearly interpolated between samples.

    Input ports:
      signal (size): any vector signal sampled every `period` s.
    Output ports:
      delayed (size): ``(1 − f)·u[k − m] + f·u[k − m − 1]`` for the delay m + f (m whole,
        0 ≤ f < 1), where u[k] is the input now (direct feedthrough: with m = 0 the current
        sample is used, so the delay adds no sample of lag of its own). Before m + 1 samples
        have been seen the oldest sample seen stands in for the missing ones (the first
        input while there is none yet).
    State: the last m + 1 inputs and how many were seen (updated every `period` s).
    """

    def __init__(self, size: int, delay_samples: float, period: float):
        super().__init__()
        if not (delay_samples >= 0 and math.isfinite(delay_samples)):
            raise ValueError(f"delay_samples must be a finite number >= 0, got {delay_samples!r}")
        self.size, self.period = int(size), float(period)
        self.whole = math.floor(delay_samples)
        self.fraction = float(delay_samples - self.whole)
        self._depth = self.whole + 1
        self._input = self.DeclareVectorInputPort("signal", self.size)
        # Ring of the last `depth` inputs (newest first), then the count seen (capped).
        self._buffer = self.DeclareDiscreteState(self._depth * self.size + 1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period, 0.0, self._update)
        self.DeclareVectorOutputPort("delayed", self.size, self._output,
                                     {self.input_port_ticket(self._input.get_index()),
                                      self.discrete_state_ticket(self._buffer)})

    def get_input_port_signal(self):
        return self.GetInputPort("signal")

    def get_output_port_delayed(self):
        return self.GetOutputPort("delayed")

    def _history(self, u, stored):
        """[u[k], u[k−1], ..., u[k−depth]] (depth + 1 rows), the missing ones filled."""
        seen = int(stored[-1])
        rows = [u] + [stored[i * self.size:(i + 1) * self.size] for i in range(seen)]
        while len(rows) < self._depth + 1:
            rows.append(rows[-1])
        return rows

    def delayed(self, u, stored) -> np.ndarray:
        """The output for the input `u` now and the state `stored` (what ``delayed`` reads
        from a context); :class:`~ftdrake.runtime.step.ChainStep` calls it too."""
        rows = self._history(u, stored)
        m, f = self.whole, self.fraction
        return np.asarray(rows[m] if f == 0.0 else (1.0 - f) * rows[m] + f * rows[m + 1],
                          dtype=float)

    def remember(self, u, stored) -> None:
        """One update of the state `stored` (in place) with the input `u`."""
        rows = self._history(u, stored)
        stored[:-1] = np.concatenate(rows[:self._depth])
        stored[-1] = min(self._depth, int(stored[-1]) + 1)

    def _output(self, context, output):
        output.SetFromVector(self.delayed(
            self._input.Eval(context), context.get_discrete_state(self._buffer).get_value()))

    def _update(self, context, state):
        # `state` starts as a copy of the context's: remember() reads and writes it.
        self.remember(self._input.Eval(context), state.get_mutable_value(self._buffer))
