"""The transports' receive threads yield to the thread that runs the chain.

LCM's ``udpm://`` provider and Cyclone DDS receive on threads of their own: one wakes for
every datagram on the group (on a shared LCM multicast group that includes the station's
own outputs) and hands it to the thread that runs the chain. Under Linux's default policy
a waking receive thread preempts that thread in the middle of a sample, and each preemption
costs both threads a context switch. Under ``SCHED_BATCH`` (see ``sched(7)``) a thread does
not preempt on wake-up: it runs when the chain's thread waits for its next message, or at
the scheduler's next tick, taking every datagram queued meanwhile in one wake-up. The
datagrams wait in the socket's buffer, so none is lost for it; what the chain's thread
needs next is at most one sample's work late, and it could not have handled it sooner.
The measured effect on ``serve`` is in docs/results/live.md.

:class:`NewThreads` finds the threads a transport started: the ids of this process's
threads before and after the transport is opened. Only those are changed; the chain's own
thread and the caller's keep their policy. Where the platform has no ``SCHED_BATCH``
(not Linux) nothing is changed.

:func:`pin_process` keeps every thread of the process on the CPUs given (the stations'
``cpu_affinity``): the chain's working set (the compiled kernels, the model's and the
filters' arrays) then stays in those cores' caches between messages instead of following
the scheduler's moves, and threads started later inherit the set from their creator.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from typing import Self

_TASKS = "/proc/self/task"


def thread_ids() -> set[int]:
    """This process's thread ids (Linux); empty where ``/proc`` has none."""
    try:
        return {int(tid) for tid in os.listdir(_TASKS)}
    except OSError:
        return set()


class NewThreads:
    """``with NewThreads() as new: <open a transport>`` then ``new.yield_to_caller()``.

    ``started`` holds the ids of the threads started inside the block (a thread the caller
    starts there at the same time is counted too: open transports from one thread).
    """

    def __init__(self):
        self.started: set[int] = set()
        self._before: set[int] = set()

    def __enter__(self) -> Self:
        self._before = thread_ids()
        return self

    def __exit__(self, *exc) -> None:
        self.started = thread_ids() - self._before - {os.getpid()}

    def yield_to_caller(self) -> list[int]:
        """Puts the threads started in the block under ``SCHED_BATCH`` (module docstring);
        returns the ids changed (none where unsupported or a thread already ended)."""
        policy = getattr(os, "SCHED_BATCH", None)
        if policy is None:
            return []
        changed = []
        for tid in sorted(self.started):
            try:
                os.sched_setscheduler(tid, policy, os.sched_param(0))
            except (ProcessLookupError, PermissionError):  # ended, or not ours to change
                continue
            changed.append(tid)
        return changed


def usable_cpus() -> set[int]:
    """The CPUs this process may run on (empty where the platform cannot say)."""
    try:
        return set(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return set()


def pin_process(cpus) -> list[int]:
    """Puts every thread of this process on `cpus` (ids from :func:`usable_cpus`); returns
    the thread ids changed (a thread that ended meanwhile is skipped)."""
    cpus = set(cpus)
    changed = []
    for tid in sorted(thread_ids() or {0}):
        try:
            os.sched_setaffinity(tid, cpus)
        except ProcessLookupError:  # ended meanwhile
            continue
        changed.append(tid)
    return changed
