"""serve with the chain's update taken out, and nothing else: `live_rate.py --no-chain` runs
serve with :func:`install` done first.

Every :class:`~ftdrake.runtime.step.ChainStep` update then returns the outputs as they stand
(the chain's initial values: no fault, no contact) without running the compensator, the bias
tracker, the detector or the joint-state gravity. Everything around it is as always: the
transport, the decode, the stream checks, the pairing, the overload accounting, the contact
state, the encode and the publishing, the loop. A run's CPU per message minus this one's is
what the chain's update costs live, in serve; minus ``--floor``'s (station_floor.py), the
rest of ftdrake's per-message work.
"""

from __future__ import annotations

from ftdrake.runtime.step import ChainStep


def held(self, t, wrench_measured, joint_state, *args, **kwargs):  # noqa: ARG001
    """ChainStep.update without the update: the outputs as they stand."""
    return self.outputs


def install() -> None:
    """Every ChainStep from now on skips its update (for a process that runs only serve)."""
    ChainStep.update = held
