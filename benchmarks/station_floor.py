"""A station with its per-message work taken out: the transport's floor, for the live
benchmarks (`live_rate.py --floor` runs serve with it, `live_step.py` feeds its callbacks).

With :func:`floor` (or after :func:`install`), a station's decoded F/T sample publishes the
outputs as they stand (the chain's initial values; the contact state without a fault) and is
counted; a joint state is counted and dropped. The stamps of both are kept, as the monitor
keeps a good sample's, so that the station's loop runs as when messages flow. No check, no
chain update, no bookkeeping: everything the station does around ``on_wrench_sample`` and
``on_joint_sample`` (the transport, the decode, the encode and the publishing, the loop) is
as always. A run's CPU per message minus the floor's is the cost of ftdrake's own
per-message work.
"""

from __future__ import annotations

import contextlib

from ftdrake.hardware.core import StationCore


def _seen(monitor, stream: str, sample, arrival: float) -> None:
    """Counts the sample and, as the monitor does for a good one, keeps its stamp and
    arrival: the station's loop then runs as when messages flow (its timeouts checked
    against them, no search for a silent stream's publishers)."""
    monitor.received[stream] += 1
    if sample is not None:
        monitor._last_t[stream], monitor._last_arrival[stream] = sample.t, arrival


def on_wrench_sample(self, sample, arrival, problem=None) -> None:  # noqa: ARG001
    _seen(self.monitor, "ft", sample, arrival)
    if sample is None:
        return
    self._publish_wrench(sample.t)
    self._publish_contact(sample.t, False)
    self.latencies.append(self.clock() - arrival)
    self.processed += 1
    self.published += 1


def on_joint_sample(self, sample, arrival, problem=None) -> None:  # noqa: ARG001
    _seen(self.monitor, "joint", sample, arrival)


def install() -> None:
    """Every station from now on runs the floor (for a process that runs only it)."""
    StationCore.on_wrench_sample = on_wrench_sample
    StationCore.on_joint_sample = on_joint_sample


@contextlib.contextmanager
def floor():
    """Stations run the floor inside the block, their own work again after it."""
    saved = StationCore.on_wrench_sample, StationCore.on_joint_sample
    install()
    try:
        yield
    finally:
        StationCore.on_wrench_sample, StationCore.on_joint_sample = saved
