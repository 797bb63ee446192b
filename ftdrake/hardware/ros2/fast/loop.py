"""The compiled per-message loop of the ROS 2 station: wait, take, check, update the chain,
publish, for every ordinary message, without the interpreter and without the GIL.

:func:`run` is one call from Python (:class:`~.path.CompiledPath`) that works for up to a
time budget. It takes the joint-state and wrench readers' samples as CDR
(``dds_takecdr``) in :class:`~ftdrake.hardware.ros2.dds.Ros2Node`'s order (taken twice,
sorted by source timestamp, those up to the first pass's newest handed over), and handles
each as :class:`~ftdrake.hardware.core.StationCore` and
:class:`~ftdrake.hardware.live_inputs.StreamMonitor` would when nothing about it is
unusual. Anything else (a message it cannot read, a joint name list other than the last
one, a stamp that does not advance or jumps, a value that is not finite or beyond the joint
bounds, a wrench in another frame, a gap of the F/T stamps, a backlog beyond
``max_backlog_s``, a joint state too old or none within the pairing tolerance) is handed
back untouched, with everything after it: Python runs it through the station's own
path, which refuses, faults, warns or bridges as it always does. So the compiled loop
changes no behaviour; it only does the common case's work in compiled code.

What it does with a message once read is :mod:`ftdrake.hardware.fast.accept`'s, shared with
the LCM station's loop; its state crosses as that module says.
"""

from __future__ import annotations

import numba
import numpy as np

from ...fast.accept import (
    BUDGET,
    BUSY,
    CPUB,
    DRY,
    ERR,
    HB,
    HEAD,
    NLAT,
    PUB,
    ROUND,
    STOP,
    STOP_BUDGET,
    STOP_HANDBACK,
    STOP_HEADROOM,
    STOP_RING,
    WAIT,
    joint_accepted,
    push,
    room,
    silent,
    wrench_done,
    wrench_due,
    wrench_update,
)
from ...fast.accept import now as clock_now
from . import cyclone
from .cdr import (
    bool_bytes,
    float64_bytes,
    frame_is,
    read_joint_state,
    read_wrench,
    stamp,
    wrench_bytes,
)
from .cyclone import INFO_BYTES, SDK_DATA, SOURCE_TIMESTAMP, VALID_DATA

#: Samples taken per dds_takecdr call; items held at most.
TAKE, ITEMS = 256, ROUND


@numba.njit(cache=True)
def now(c, spec) -> float:
    """time.monotonic, by Cyclone's tuple's clock_gettime."""
    return clock_now(c[7], spec)


@numba.njit(cache=True)
def _take(c, reader, stream, mask, samples, infos, ptrs, stamps, streams, count) -> int:
    """Appends the reader's valid samples (pointer, source timestamp, stream) after `count`
    items; the new count."""
    while count + TAKE <= len(ptrs):
        n = c[1](reader, samples.ctypes.data, TAKE, infos.ctypes.data, mask)
        for i in range(max(n, 0)):
            info = i * INFO_BYTES
            if infos[info + VALID_DATA] == 0:  # a writer went away: no data
                c[6](samples[i])
                continue
            ptrs[count] = samples[i]
            stamps[count] = infos[info + SOURCE_TIMESTAMP:info + SOURCE_TIMESTAMP + 8].view(
                np.int64)[0]
            streams[count] = stream
            count += 1
        if n < TAKE:
            break
    return count


@numba.njit(cache=True)
def _take_both(c, readers, mask, samples, infos, ptrs, stamps, streams, count) -> int:
    for stream in range(2):  # the joint states first, as the node subscribes them
        count = _take(c, readers[stream], stream, mask, samples, infos, ptrs, stamps, streams,
                      count)
    return count


@numba.njit(cache=True)
def _sort(ptrs, stamps, streams, start, count) -> None:
    """Items start..count-1 by source timestamp, stable (taken order breaks ties)."""
    for i in range(start + 1, count):
        p, s, m = ptrs[i], stamps[i], streams[i]
        j = i - 1
        while j >= start and stamps[j] > s:
            ptrs[j + 1], stamps[j + 1], streams[j + 1] = ptrs[j], stamps[j], streams[j]
            j -= 1
        ptrs[j + 1], stamps[j + 1], streams[j + 1] = p, s, m


@numba.njit(cache=True)
def _on_joint(data, size, arrival, f, k, joint, rings) -> bool:
    """A joint state as StreamMonitor.on_joint accepts it; False (nothing changed) for
    anything else."""
    names, order, x_new, values, limit, scratch, joint_state = joint
    if not read_joint_state(data, size, names, order, x_new, values, scratch):
        return False
    return joint_accepted(stamp(data), x_new, arrival, f, k, limit, joint_state, rings)


@numba.njit(cache=True)
def _write(c, writer, sertype, out, size, iov) -> int:
    """`size` bytes of `out` written on `writer`; 1 when that failed."""
    iov[0], iov[1] = out.ctypes.data, size
    serdata = c[5](sertype, SDK_DATA, 1, iov.ctypes.data, size)
    if serdata == 0:
        return 1
    return 1 if c[2](writer, serdata) < 0 else 0


@numba.njit(cache=True)
def _publish(c, data, end, outputs, chain_out, out, iov, scratch, wrenches) -> int:
    """The station's per-sample outputs, the wrenches (with the input's header: `wrenches`
    True) or the contact and contact force (False); the writes that failed."""
    writers, sertypes, heads, sources, _ = outputs
    flag, force = chain_out[3][0], chain_out[4][0]
    errors = 0
    for i in range(len(writers)):
        source = sources[i]
        if (source < 3) != wrenches:
            continue
        if source < 3:
            size = wrench_bytes(out, heads[i], data, end, chain_out[source], scratch)
        elif source == 3:
            size = bool_bytes(out, heads[i], flag)
        else:
            size = float64_bytes(out, heads[i], force, scratch)
        errors += _write(c, writers[i], sertypes[i], out, size, iov)
    return errors


@numba.njit(cache=True)
def _on_wrench(c, data, size, arrival, f, k, ft, rings, chain, outputs, buffers) -> bool:
    """A wrench as StationCore.on_wrench_sample handles a fresh, fault-free one: checks,
    load, pairing, one chain update, the outputs; False (nothing changed) for anything
    else."""
    frame, wrench_new, scratch, wrench, joint_state, step_wrench, step_x, chain_out = ft
    out, iov, spec = buffers
    end = read_wrench(data, size, wrench_new, scratch)
    if end < 0 or not frame_is(data, frame):
        return False
    t = stamp(data)
    if not wrench_due(t, wrench_new, arrival, f, k, rings, joint_state):
        return False
    wrench_update(t, wrench_new, arrival, f, k, rings, wrench, joint_state, step_wrench,
                  step_x, chain)
    if chain_out[5][0] <= 0.5:  # the model's fault: nothing published (as Python's path)
        # The latency to the wrenches' publication, then contact and force (Python's order).
        k[ERR] += _publish(c, data, end, outputs, chain_out, out, iov, scratch, True)
        push(rings[2], k, NLAT, now(c, spec) - arrival)
        k[PUB] += 1
        k[ERR] += _publish(c, data, end, outputs, chain_out, out, iov, scratch, False)
        if outputs[4]:
            k[CPUB] += 1
    wrench_done(t, arrival, now(c, spec), f, k, rings)
    return True


@numba.njit(cache=True, nogil=True)
def run(c, waitset, readers, mask, items, f, k, joint, ft, rings, chain, outputs, buffers,
        take_buffers):
    """Handles messages until ``f[budget]`` s have passed (waiting at most ``f[wait]`` s at a
    time; once a stream has been silent past its timeout it returns, so that Python
    raises that fault at once), or until a message must go to Python (``k[stop]``
    STOP_HANDBACK: the items from ``items[0][:k[handback]]`` on, not yet handled and still
    referenced, in order), or the headroom check is due (STOP_HEADROOM) or a ring is
    nearly full (STOP_RING); anything taken and not handled is handed back likewise."""
    ptrs, stamps, streams = items
    samples, infos, data = take_buffers
    spec = buffers[2]
    k[STOP], k[HB] = STOP_BUDGET, 0
    if k[DRY]:
        return
    start = now(c, spec)
    count = 0
    while True:
        count = _take_both(c, readers, mask, samples, infos, ptrs, stamps, streams, count)
        if count == 0:
            left = f[BUDGET] - (now(c, spec) - start)
            if left <= 0:
                return
            c[0](waitset, 0, 0, np.int64(min(left, f[WAIT]) * 1e9))
            if silent(now(c, spec), f):
                return  # Python raises the timeout's fault at once
            continue
        limit = stamps[:count].max()
        count = _take_both(c, readers, mask, samples, infos, ptrs, stamps, streams, count)
        _sort(ptrs, stamps, streams, 0, count)
        done = _handle_due(c, count, limit, items, f, k, joint, ft, rings, chain, outputs,
                           buffers, data)
        left = count - done
        ptrs[:left], stamps[:left], streams[:left] = (ptrs[done:count], stamps[done:count],
                                                      streams[done:count])
        count = left
        stop = _stop(count, stamps, limit, k, rings)
        if stop == STOP_BUDGET and now(c, spec) - start < f[BUDGET]:
            continue
        k[STOP], k[HB] = stop, count
        return


@numba.njit(cache=True)
def _handle_due(c, count, limit, items, f, k, joint, ft, rings, chain, outputs, buffers,
                data) -> int:
    """Handles the sorted items up to `limit` in order while the loop may; how many (the
    first not handled, if any, goes back to Python)."""
    ptrs, stamps, streams = items
    spec = buffers[2]
    done = 0
    while done < count and stamps[done] <= limit and k[HEAD] > 0:
        size = c[3](ptrs[done])
        if size > len(data):
            break
        c[4](ptrs[done], 0, size, data.ctypes.data)
        arrival = now(c, spec)
        if streams[done] == 0:
            ok = _on_joint(data, size, arrival, f, k, joint, rings)
            if ok:
                f[BUSY] += max(0.0, now(c, spec) - arrival)
        else:
            ok = _on_wrench(c, data, size, arrival, f, k, ft, rings, chain, outputs, buffers)
        if not ok:
            break
        c[6](ptrs[done])
        done += 1
    return done


@numba.njit(cache=True)
def _stop(count, stamps, limit, k, rings) -> int:
    """Why the loop returns now (STOP_BUDGET: it need not)."""
    if count and stamps[0] <= limit:
        return STOP_HANDBACK
    if k[HEAD] <= 0:
        return STOP_HEADROOM
    if not room(k, rings):
        return STOP_RING
    return STOP_BUDGET


def warm(arguments) -> str | None:
    """One dry call of :func:`run` on `arguments` (``fast.warm``'s child): compiles it into
    numba's cache; or why Cyclone's C functions cannot be had."""
    c = cyclone.load()
    if isinstance(c, str):
        return c
    run(c, *arguments)
    return None
