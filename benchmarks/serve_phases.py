"""serve's main thread, its CPU per F/T message split by phase, live: `live_rate.py --phases`
runs serve with :func:`install` done first.

Each phase is the thread CPU time (``time.thread_time_ns``) spent in one of the station's own
methods, summed over the timed part of a run (SIGUSR1, sent by the benchmark when its warm-up
ends, zeroes the sums) and divided by the F/T messages handled in it:

* ``wait`` (ROS 2): the node's wait set, waiting for a message;
* ``receive``: ROS 2, the takes and the CDR reads (``Ros2Node._complete``); LCM,
  ``handle`` without the callbacks (its wait for a message, LCM's read and dispatch: LCM's
  wait cannot be told apart from the rest);
* ``joint``: the joint-state callback (decode, joint order, checks);
* ``ft``: the F/T callback without the writes below (decode, checks, the chain's update,
  bookkeeping, encoding LCM's messages);
* ``write <output>``: one output's write from the F/T callback (ROS 2: the packed message
  and Cyclone's write; LCM: LCM's publish);
* ``rest``: the station's loop around these (the timeouts, the periodic status or
  diagnostics and their writes).

The sums are written to ``$FTDRAKE_PHASES_FILE`` (JSON) when serve exits. Each wrapped call
adds two readings of the thread's clock and a Python call, to its phase and the one around
it: the phases add up to more than the main thread of a run without them, and each reads
somewhat high.
"""

from __future__ import annotations

import atexit
import collections
import functools
import json
import os
import signal
import time

_clock = time.thread_time_ns
_sums: collections.Counter = collections.Counter()  # phase → ns
_state = {"in_ft": False, "ft_messages": 0}


def _timed(phase: str, *, counts_ft: bool = False):
    """A method wrapped to add its thread CPU time to `phase` (`counts_ft`: the F/T
    callback, whose writes are timed on their own)."""
    def wrap(method):
        @functools.wraps(method)
        def timed(*args, **kwargs):
            if counts_ft:
                _state["in_ft"] = True
            start = _clock()
            try:
                return method(*args, **kwargs)
            finally:
                _sums[phase] += _clock() - start
                if counts_ft:
                    _state["in_ft"] = False
                    _state["ft_messages"] += 1
        return timed
    return wrap


def _timed_write(name_of):
    """A write method wrapped to add its time, when called from the F/T callback, to
    ``write <name_of(self, args)>``."""
    def wrap(method):
        @functools.wraps(method)
        def timed(self, *args):
            if not _state["in_ft"]:
                return method(self, *args)
            start = _clock()
            try:
                return method(self, *args)
            finally:
                _sums["write " + name_of(self, args)] += _clock() - start
        return timed
    return wrap


def _wrap_lcm() -> None:
    from ftdrake.hardware.station import HardwareStation
    from ftdrake.hardware.transport import LcmTransport

    LcmTransport.handle = _timed("handle")(LcmTransport.handle)
    LcmTransport.publish = _timed_write(lambda _self, args: args[0])(LcmTransport.publish)
    HardwareStation._on_joint = _timed("joint")(HardwareStation._on_joint)
    HardwareStation._on_wrench = _timed("ft", counts_ft=True)(HardwareStation._on_wrench)
    HardwareStation.spin_once = _timed("loop")(HardwareStation.spin_once)


def _wrap_ros2() -> None:
    try:
        from cyclonedds.core import WaitSet

        from ftdrake.hardware.ros2 import packing
        from ftdrake.hardware.ros2.dds import Ros2Node
        from ftdrake.hardware.ros2.station import Ros2Station
    except ImportError:  # no cyclonedds: LCM only
        return
    WaitSet.wait = _timed("wait")(WaitSet.wait)
    Ros2Node._complete = _timed("receive")(Ros2Node._complete)
    by_topic = _timed_write(lambda self, _args: self.writer.topic.name)
    packing.WrenchWriter.write = by_topic(packing.WrenchWriter.write)
    packing.ValueWriter.write = by_topic(packing.ValueWriter.write)
    Ros2Station._on_joint = _timed("joint")(Ros2Station._on_joint)
    Ros2Station._on_wrench = _timed("ft", counts_ft=True)(Ros2Station._on_wrench)
    Ros2Station.spin_once = _timed("loop")(Ros2Station.spin_once)


def phases() -> dict:
    """µs per F/T message of each phase (module docstring), and the messages counted."""
    n = max(_state["ft_messages"], 1)
    us = {key: ns / n / 1e3 for key, ns in _sums.items()}
    writes = sum(v for k, v in us.items() if k.startswith("write "))
    out = {"ft_messages": _state["ft_messages"]}
    if "handle" in us:  # LCM: the callbacks run inside handle
        out["receive"] = us["handle"] - us.get("joint", 0.0) - us.get("ft", 0.0)
        out["rest"] = us.get("loop", 0.0) - us["handle"]
    else:
        out["wait"], out["receive"] = us.get("wait", 0.0), us.get("receive", 0.0)
        out["rest"] = us.get("loop", 0.0) - sum(us.get(k, 0.0) for k in (
            "wait", "receive", "joint", "ft"))
    out["joint"] = us.get("joint", 0.0)
    out["ft"] = us.get("ft", 0.0) - writes
    out.update({k: v for k, v in us.items() if k.startswith("write ")})
    out["total"] = us.get("loop", 0.0)
    return out


def _reset(*_) -> None:
    _sums.clear()
    _state["ft_messages"] = 0


def _save() -> None:
    path = os.environ.get("FTDRAKE_PHASES_FILE")
    if path:
        with open(path + ".tmp", "w", encoding="utf-8") as f:
            json.dump(phases(), f)
        os.replace(path + ".tmp", path)


def install() -> None:
    """Every station from now on has its phases timed (for a process that runs only it)."""
    _wrap_lcm()
    _wrap_ros2()
    signal.signal(signal.SIGUSR1, _reset)
    atexit.register(_save)
