"""The compiled per-message loop of the LCM station: wait, read, check, update the chain,
publish, for every ordinary message, without the interpreter and without the GIL.

:func:`run` is one call from Python (:class:`~.path.CompiledPath`) that works for up to a
time budget. It waits for and dispatches LCM's messages one at a time by
``lcm_handle_timeout`` on the station's own connection (:mod:`.liblcm`; the handler copies
each into the inbox), and handles each as :class:`~ftdrake.hardware.core.StationCore` and
:class:`~ftdrake.hardware.live_inputs.StreamMonitor` would when nothing about it is unusual
(:mod:`ftdrake.hardware.fast.accept`), in the order LCM delivers them, as the Python path
does. Anything else (a message it cannot read or that was cut short, a stamp that does not
advance or jumps, a value that is not finite or beyond the joint bounds, a gap of the F/T
stamps, a backlog beyond ``max_backlog_s``, a joint state too old or none within the
pairing tolerance, an inbox entry lost) is left in the inbox with everything after it, for
the Python path to dispatch: it refuses, faults, warns or bridges as it always does.

Outputs, per F/T message as the Python path publishes them: the wrenches on their channels
(when the chain's fault is low), then the contact state (always, its fault flag the
chain's), on the output connection.
"""

from __future__ import annotations

import math

import numba

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
    STOP,
    STOP_BUDGET,
    STOP_HANDBACK,
    STOP_HEADROOM,
    STOP_RING,
    WAIT,
    joint_accepted,
    now,
    push,
    room,
    silent,
    wrench_done,
    wrench_due,
    wrench_update,
)
from .codec import contact_bytes, read_iiwa_status, read_wrench, wrench_bytes
from .liblcm import FIELDS
from .liblcm import HEAD as INBOX_HEAD

#: Why :func:`run` returned, beyond fast.accept's: lcm_handle_timeout failed (a signal, or
#: a socket error).
STOP_WAIT_FAILED = 4


@numba.njit(cache=True)
def _on_joint(data, size, arrival, f, k, joint, rings) -> bool:
    fingerprint, x_new, limit, joint_state, scratch = joint
    read, t = read_iiwa_status(data, size, fingerprint, x_new, scratch)
    if not read:
        return False
    return joint_accepted(t, x_new, arrival, f, k, limit, joint_state, rings)


@numba.njit(cache=True)
def _publish(c, outputs, t, chain_out, buffers, wrenches) -> int:
    """The wrenches (`wrenches` True) or the contact state (False) of the update at `t`;
    the publications that failed."""
    sender, channels, sources, fingerprint, contact_channel, template, values = outputs
    out, scratch = buffers[0], buffers[2]
    errors = 0
    if wrenches:
        for i in range(len(sources)):
            size = wrench_bytes(out, fingerprint, t, chain_out[sources[i]], scratch)
            errors += c[1](sender, channels[i].ctypes.data, out.ctypes.data, size) < 0
        return errors
    values[0] = 1.0 if chain_out[3][0] > 0.5 else 0.0
    values[1] = chain_out[4][0]
    values[2] = 1.0 if chain_out[5][0] > 0.5 else 0.0  # the inputs are fault-free here
    values[3] = 1.0 if chain_out[6][0] > 0.5 else 0.0
    values[4] = 1.0 if chain_out[7][0] > 0.5 else 0.0
    size = contact_bytes(out, template, t, values, scratch)
    return c[1](sender, contact_channel.ctypes.data, out.ctypes.data, size) < 0


@numba.njit(cache=True)
def _on_wrench(c, data, size, arrival, f, k, ft, rings, chain, outputs, buffers) -> bool:
    """A wrench as StationCore.on_wrench_sample handles a fresh, fault-free one; False
    (nothing changed) for anything else."""
    fingerprint, wrench_new, wrench, joint_state, step_wrench, step_x, chain_out, scratch = ft
    read, t = read_wrench(data, size, fingerprint, wrench_new, scratch)
    if not read or not wrench_due(t, wrench_new, arrival, f, k, rings, joint_state):
        return False
    wrench_update(t, wrench_new, arrival, f, k, rings, wrench, joint_state, step_wrench,
                  step_x, chain)
    spec = buffers[1]
    if chain_out[5][0] <= 0.5:  # the model's fault: no wrench published (as Python's path)
        k[ERR] += _publish(c, outputs, t, chain_out, buffers, True)
        push(rings[2], k, NLAT, now(c[2], spec) - arrival)
        k[PUB] += 1
    if len(outputs[4]):
        k[ERR] += _publish(c, outputs, t, chain_out, buffers, False)
        k[CPUB] += 1
    wrench_done(t, arrival, now(c[2], spec), f, k, rings)
    return True


@numba.njit(cache=True)
def _handle_inbox(c, inbox, inbox_bytes, subs, f, k, joint, ft, rings, chain, outputs,
                  buffers) -> int:
    """The inbox's entries in order while the loop may; the index of the first left for
    Python (their count when none is)."""
    spec = buffers[1]
    count = inbox[0]
    for i in range(count):
        e = INBOX_HEAD + i * FIELDS
        sub, size, kept, offset = inbox[e], inbox[e + 1], inbox[e + 2], inbox[e + 4]
        if kept < size or k[HEAD] <= 0:
            return i
        data = inbox_bytes[offset:offset + kept]
        arrival = now(c[2], spec)
        if sub == subs[0]:
            ok = _on_joint(data, kept, arrival, f, k, joint, rings)
            if ok:
                f[BUSY] += max(0.0, now(c[2], spec) - arrival)
        elif sub == subs[1]:
            ok = _on_wrench(c, data, kept, arrival, f, k, ft, rings, chain, outputs, buffers)
        else:
            ok = False
        if not ok:
            return i
    return count


@numba.njit(cache=True, nogil=True)
def run(c, lcm, inbox, inbox_bytes, subs, f, k, joint, ft, rings, chain, outputs, buffers):
    """Handles messages until ``f[budget]`` s have passed (waiting at most ``f[wait]`` s at a
    time, 1 ms at least; once a stream has been silent past its timeout it returns, so
    that Python raises that fault at once), or until a message must go to Python
    (``k[stop]`` STOP_HANDBACK: the inbox's entries from ``k[handback]`` on), or the
    headroom check is due (STOP_HEADROOM), a ring is nearly full (STOP_RING) or the wait
    failed (STOP_WAIT_FAILED)."""
    spec = buffers[1]
    k[STOP], k[HB] = STOP_BUDGET, 0
    if k[DRY]:
        return
    start = now(c[2], spec)
    while True:
        left = f[BUDGET] - (now(c[2], spec) - start)
        if left <= 0:
            return
        result = c[0](lcm, max(1, math.ceil(min(left, f[WAIT]) * 1e3)))
        if result < 0:
            k[STOP] = STOP_WAIT_FAILED
            return
        if result == 0:
            if silent(now(c[2], spec), f):
                return  # Python raises the timeout's fault at once
            continue
        done = _handle_inbox(c, inbox, inbox_bytes, subs, f, k, joint, ft, rings, chain,
                             outputs, buffers)
        if done < inbox[0] or inbox[2]:  # (an entry lost: Python says so)
            k[STOP], k[HB] = STOP_HANDBACK, done
            return
        inbox[0], inbox[1] = 0, 0
        if k[HEAD] <= 0:
            k[STOP] = STOP_HEADROOM
            return
        if not room(k, rings):
            k[STOP] = STOP_RING
            return


def warm(arguments) -> str | None:
    """One dry call of :func:`run` on `arguments` (``fast.warm``'s child): compiles it into
    numba's cache; or why liblcm cannot be had."""
    from .liblcm import load  # noqa: PLC0415

    loaded = load()
    if isinstance(loaded, str):
        return loaded
    run(loaded[0], *arguments)
    return None
