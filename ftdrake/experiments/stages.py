"""Stages: a long run's progress, one line as each stage starts (what it is doing) and one as
it ends (its wall time), with the times kept for the run's summary."""

from __future__ import annotations

import sys
import time


class Stages:
    """The stages of a run, `total` of them, printed with `label` on `stream` (stdout by
    default; nothing when `progress` is false)::

        [demo] 1/4 collect: simulating 16 free-motion runs …
        [demo] 1/4 collect done in 21.9 s
        ...
        [demo] done in 155.7 s: collect 21.9 s, train 120.8 s, ...

    :meth:`times` gives each stage's wall time (s) so far; `clock` is the wall clock
    (``time.perf_counter``)."""

    def __init__(self, total: int, *, label: str, progress: bool = True, stream=None,
                 clock=time.perf_counter):
        self.total, self.label, self.progress = total, label, progress
        self.stream, self.clock = stream, clock
        self.started = clock()
        self._starts: dict[str, float] = {}
        self._ended: dict[str, float] = {}

    def _say(self, line: str) -> None:
        if self.progress:
            print(f"{self.label} {line}", file=self.stream or sys.stdout, flush=True)

    def _end_current(self, now: float) -> None:
        if self._starts:
            name = list(self._starts)[-1]
            if name not in self._ended:
                self._ended[name] = now - self._starts[name]
                self._say(f"{len(self._starts)}/{self.total} {name} done in "
                          f"{self._ended[name]:.1f} s")

    def start(self, name: str, doing: str) -> None:
        """Ends the stage running (printing its time) and starts `name`, saying what it is
        `doing`."""
        now = self.clock()
        self._end_current(now)
        self._starts[name] = now
        self._say(f"{len(self._starts)}/{self.total} {name}: {doing} …")

    def times(self) -> dict[str, float]:
        """Each stage's wall time (s), the running one's until now, rounded to 10 ms."""
        now = self.clock()
        return {name: round(self._ended.get(name, now - start), 2)
                for name, start in self._starts.items()}

    def finish(self) -> float:
        """Ends the last stage and prints the total; returns the run's wall time (s)."""
        now = self.clock()
        self._end_current(now)
        total = now - self.started
        self._say(f"done in {total:.1f} s: " + ", ".join(
            f"{name} {seconds:.1f} s" for name, seconds in self._ended.items()))
        return total
