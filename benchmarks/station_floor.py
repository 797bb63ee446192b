"""A station with its per-message work taken out: the transport's floor, for the live
benchmarks (`live_rate.py --floor` runs serve with it, `live_step.py` feeds its callbacks).

With :func:`floor` (or after :func:`install`), a station's decoded F/T sample publishes the
outputs as they stand (the chain's initial values; the contact state without a fault) and is
counted; a joint state is counted and dropped. No check, no chain update, no bookkeeping:
everything the station does around ``on_wrench_sample``/``on_joint_sample`` (the transport,
the decode, the encode and the publishing, the loop) is as always. A run's CPU per message
minus the floor's is the cost of ftdrake's own per-message work.
"""

from __future__ import annotations

import contextlib

from ftdrake.hardware.core import StationCore


def on_wrench_sample(self, sample, arrival, problem=None) -> None:  # noqa: ARG001
    self.monitor.received["ft"] += 1
    if sample is None:
        return
    self._publish_wrench(sample.t)
    self._publish_contact(sample.t, False)
    self.latencies.append(self.clock() - arrival)
    self.processed += 1
    self.published += 1


def on_joint_sample(self, sample, arrival, problem=None) -> None:  # noqa: ARG001
    self.monitor.received["joint"] += 1


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
