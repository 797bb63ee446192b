"""What the compiled per-message loops do with an ordinary message once their transport
has read it: :class:`~ftdrake.hardware.live_inputs.StreamMonitor`'s checks and pairing,
:class:`~ftdrake.hardware.overload.LoadMonitor`'s bookkeeping and
:class:`~ftdrake.hardware.core.StationCore`'s counts, as those do for a fresh, fault-free
message. Each check returns False, having changed nothing, for anything else: the loop then
hands the message to the station's Python path.

State crosses by the arrays ``f`` (floats, :data:`F`) and ``k`` (counts, :data:`K`) that
:class:`~.path.CompiledPathBase` fills before a call and reads back after it, and the rings of
what the Python objects keep (joint history, latencies, busy times, F/T stamps).
Times are in s on the station's clock (time.monotonic) and the streams' stamps.
"""

from __future__ import annotations

import math

import numba

from .chain import chain_update

#: Indices of the float state ``f``.
F = {name: i for i, name in enumerate((
    "period", "joint_timeout", "pair_tolerance", "max_backlog", "last_t_joint",
    "last_arrival_joint", "last_t_ft", "last_arrival_ft", "core_last_t", "load_last_t",
    "min_lag", "lag", "backlog", "max_backlog_seen", "pending_busy", "budget", "wait",
    "sensor_timeout"))}
#: Indices of the count state ``k``.
K = {name: i for i, name in enumerate((
    "received_joint", "received_ft", "processed", "published", "contact_published",
    "until_headroom", "errors", "stop", "history", "latencies", "busy", "stamps", "handback",
    "dry"))}
F_SIZE, K_SIZE = 18, 14
#: Why a loop returned (``k[K["stop"]]``).
STOP_BUDGET, STOP_HANDBACK, STOP_HEADROOM, STOP_RING = 0, 1, 2, 3
#: Entries of each ring (joint history, latencies, busy times, F/T stamps) per call.
RING = 16384
#: Ring entries kept free for one round of a loop's messages.
ROUND = 4096
#: clock_gettime's id of CLOCK_MONOTONIC (Linux), time.monotonic's clock.
CLOCK_MONOTONIC = 1

(P, JT, TOL, MAXB, LTJ, LAJ, LTF, LAF, CLT, LLT, MINLAG, LAG, BACKLOG, MAXSEEN, BUSY, BUDGET,
 WAIT, ST) = range(F_SIZE)
(RJ, RF, PROC, PUB, CPUB, HEAD, ERR, STOP, HIST, NLAT, NBUSY, NSTAMP, HB, DRY) = range(
    K_SIZE)


@numba.njit(cache=True)
def now(clock_gettime, spec) -> float:
    """time.monotonic (CLOCK_MONOTONIC, as CPython converts it); `spec` two int64."""
    clock_gettime(CLOCK_MONOTONIC, spec.ctypes.data)
    return float(spec[0] * 1_000_000_000 + spec[1]) / 1e9


@numba.njit(cache=True)
def finite(values) -> bool:
    for value in values:
        if not math.isfinite(value):
            return False
    return True


@numba.njit(cache=True)
def push(ring, k, index, value) -> None:
    ring[k[index]] = value
    k[index] += 1


@numba.njit(cache=True)
def joint_accepted(t, x_new, arrival, f, k, limit, joint_state, rings) -> bool:
    """A joint state stamped `t` (s), ``[q; v]`` `x_new`, as StreamMonitor.on_joint accepts
    it; False (nothing changed) for anything else."""
    if not (math.isfinite(t) and finite(x_new) and t > f[LTJ]):
        return False
    for j in range(len(limit)):
        if abs(x_new[j]) > limit[j]:
            return False
    k[RJ] += 1
    joint_state[:] = x_new
    if f[TOL] > 0:
        m = k[HIST]
        rings[0][m] = t
        rings[1][m, :] = x_new
        k[HIST] = m + 1
    f[LTJ], f[LAJ] = t, arrival
    return True


@numba.njit(cache=True)
def paired(t, f, k, rings, joint_state) -> bool:
    """StreamMonitor._pair's common case: the newest joint state within the tolerance of
    `t`, brought forward to it when stamped before (joint_state_at); False for none."""
    if f[TOL] <= 0:
        return True
    hist_t, hist_x = rings[0], rings[1]
    m = k[HIST]
    if m == 0 or abs(hist_t[m - 1] - t) > f[TOL]:
        return False
    t_joint, x = hist_t[m - 1], hist_x[m - 1]
    delta = t - t_joint
    if t <= t_joint or delta == 0.0:
        joint_state[:] = x
        return True
    n = len(x) // 2
    for j in range(n):
        a = 0.0
        if m >= 2:
            a = (x[n + j] - hist_x[m - 2][n + j]) / (t_joint - hist_t[m - 2])
        joint_state[j] = x[j] + delta * x[n + j] + (0.5 * delta * delta) * a
        joint_state[n + j] = x[n + j] + delta * a
    return True


@numba.njit(cache=True)
def wrench_due(t, wrench_new, arrival, f, k, rings, joint_state) -> bool:
    """Whether the wrench stamped `t` is one StationCore runs through the chain at once:
    finite, in order, no gap of the stamps, no backlog past ``max_backlog``, a joint state
    fresh and (with a tolerance) paired, which is then in `joint_state`; False (nothing
    changed) otherwise."""
    if not (math.isfinite(t) and finite(wrench_new)):
        return False
    period = f[P]
    if not (t > f[LTF] and t > f[LLT] and t - f[LLT] <= 1.5 * period
            and t - f[CLT] <= 1.5 * period):
        return False  # out of order, a restart, or a gap to count and bridge: Python's
    if max(0.0, arrival - t - f[MINLAG]) > f[MAXB] or arrival - f[LAJ] > f[JT]:
        return False
    return paired(t, f, k, rings, joint_state)


@numba.njit(cache=True)
def wrench_update(t, wrench_new, arrival, f, k, rings, wrench, joint_state, step_wrench,
                  step_x, chain) -> None:
    """A wrench :func:`wrench_due` passed: the load, the monitor and the chain as the
    Python path leaves them, one update of the chain."""
    lag = arrival - t
    backlog = max(0.0, lag - f[MINLAG])
    f[LAG], f[LLT], f[BACKLOG] = lag, t, backlog
    f[MAXSEEN] = max(f[MAXSEEN], backlog)
    push(rings[4], k, NSTAMP, t)
    k[RF] += 1
    wrench[:] = wrench_new
    f[LTF], f[LAF], f[CLT] = t, arrival, t
    step_wrench[:] = wrench
    step_x[:] = joint_state
    kind, comp, arrays, detector, tracker = chain
    chain_update(k[PROC] * f[P], step_wrench, step_x, kind, comp, arrays, detector, tracker)
    k[PROC] += 1


@numba.njit(cache=True)
def wrench_done(t, arrival, done, f, k, rings) -> None:
    """After the outputs of the wrench stamped `t` that arrived at `arrival` (s) went out at
    `done` (s): the time it kept the station busy, the lag's baseline, the headroom count."""
    f[BUSY] += max(0.0, done - arrival)
    f[MINLAG] = min(f[MINLAG], arrival - t)
    push(rings[3], k, NBUSY, f[BUSY])
    f[BUSY] = 0.0
    k[HEAD] -= 1


@numba.njit(cache=True)
def silent(t, f) -> bool:
    """Whether a stream has been silent past its timeout at `t` (StreamMonitor's
    check_timeouts would fault it)."""
    return t - f[LAF] > f[ST] or t - f[LAJ] > f[JT]


@numba.njit(cache=True)
def room(k, rings) -> bool:
    """Whether every ring has room for the items of one more round."""
    free = len(rings[2]) - ROUND
    return k[HIST] < free and k[NLAT] < free and k[NBUSY] < free and k[NSTAMP] < free
