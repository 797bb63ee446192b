"""The bias tracker's compiled estimator (:class:`~ftdrake.runtime.bias_tracker.OnlineBiasTracker`
holds its state and ports): one sample of recursive least squares with forgetting, the
rate-bounded publication of the estimate, and a re-tare estimated as a jump of the bias.

The state vector x of the tracker is laid out as [θ (n), published θ (n), R (n²), 4 counters,
the jump's state (:func:`jump_state_size`)]; every function updates its arrays in place and
allocates little, so one sample costs a few µs.
"""

import math

import numba
import numpy as np

from ..compensation.compiled.payload import regressor_row
from ..conventions import STANDARD_GRAVITY

#: Parameters with payload tracking: b (6), Δm, Δ(m·c) (3), ΔI_So (6).
N_PAYLOAD = 16


@numba.njit(cache=True)
def _regressor(g, motion, n, K, out):
    """Φ (6 × n), rows F then T, columns θ = [b (6); Δm; Δ(m·c) (3); ΔI_So (6)]: b plus
    K times the Newton–Euler wrench of the payload (:mod:`ftdrake.runtime.bias_tracker`) for
    g = g − a_So and motion = [ω; α], all in S; K (6 × 6) the map from a wrench at the sensor
    to the compensated wrench (the model's reading matrix in S; identity without one). The
    payload's columns are the physics compensator's regressor row
    (:func:`~ftdrake.compensation.compiled.payload.regressor_row`, d = a − g = −g), whose
    parameter order is [m, m·c, I_So, b]."""
    out[:, :] = 0.0
    for i in range(6):
        out[i, i] = 1.0
    if n == N_PAYLOAD:
        A = np.zeros((6, 16))
        d = np.empty(3)
        w = np.zeros(6)  # [ω; α]; an empty `motion`: at rest (the gravity part)
        for i in range(3):
            d[i] = -g[i]
        for i in range(len(motion)):
            w[i] = motion[i]
        regressor_row(w[:3], w[3:], d, A)
        for i in range(6):
            for j in range(10):
                acc = 0.0
                for k in range(6):
                    acc += K[i, k] * A[k, j]
                out[i, 6 + j] = acc


@numba.njit(cache=True)
def _reset_block(R, n, lo, hi):
    """Information of parameters lo..hi-1 back to the prior (scaled: 1 on the diagonal)."""
    for i in range(lo, hi):
        for j in range(n):
            R[i, j] = 0.0
            R[j, i] = 0.0
        R[i, i] = 1.0


@numba.njit(cache=True)
def track_sample(y, g, motion, flags, n, K, x, constants, steps, sigma, prior, corrected,
                 bias, payload, inertia, tracking, std):
    """One sample of the tracker; updates the state arrays in place (see
    :mod:`ftdrake.runtime.bias_tracker` for what it estimates and when it freezes).

    `g` (3) = g − a_So and `motion` (6) = [ω, α], in S; `K` (6 × 6) maps the payload's
    wrench in S to the compensated wrench (:func:`_regressor`); `x` = [θ (n), published θ
    (n), R (n²), tare hold, tare settle, payload hold, payload settle, the jump's state];
    `constants` = [λ, hold samples, tare settle samples, payload settle samples, jump
    window, guard samples]; `steps` = the rate bound × period per parameter; `flags` =
    [contact, out_of_domain, fault, tared, payload_changed]; `std` (6) receives the
    predictive std of Φ·θ (:func:`_predictive_std`).
    """
    theta = x[:n]
    published = x[n:2 * n]
    R = x[2 * n:2 * n + n * n].reshape((n, n))
    k = 2 * n + n * n
    counters = x[k:k + 4]  # tare hold, tare settle, payload hold, payload settle
    jump = x[k + 4:]  # the tare-as-a-jump state (_jump_state_size)
    lam, hold, tare_settle, payload_settle = constants[0], constants[1], constants[2], constants[3]
    window, guard = int(constants[4]), int(constants[5])
    _take_tare_signal(flags[3], counters, jump, published, hold, tare_settle, window)
    if n == N_PAYLOAD and flags[4] > 0.5:
        counters[2], counters[3] = hold, payload_settle
    if not _all_finite(y, g, motion):
        return  # hold every output; not evidence of anything
    phi = np.empty((6, n))
    _regressor(g, motion, n, K, phi)
    L = np.zeros((n, n))  # R's Cholesky factor, for the update and the std alike
    if jump[_PHASE] > 0:
        _jump_step(y, phi, flags, n, theta, published, jump, window, corrected, bias, payload,
                   inertia, tracking)
        _predictive_std(L, _cholesky(R, n, L), phi, prior, n, std)
        return
    free = flags[0] < 0.5
    update = _may_update(flags, counters)
    if update:
        rhs = _rls_step(y, g, motion, phi, n, K, theta, R, counters, lam, sigma, prior)
    factored = _cholesky(R, n, L)
    if update:
        if factored:
            _solve_factored(L, rhs, n)
            for j in range(n):
                theta[j] += prior[j] * rhs[j]
        _move_published(theta, published, counters, steps, n)
    _publish(y, phi, n, published, corrected, bias, payload, inertia)
    _predictive_std(L, factored, phi, prior, n, std)
    if update and free and counters[0] <= 0 and counters[1] <= 0:
        _remember(jump, corrected, window, guard)
    tracking[0] = 1.0 if update else 0.0


@numba.njit(cache=True)
def _take_tare_signal(tared, counters, jump, published, hold, tare_settle, window):
    """A tared sample starts a jump estimate, or (no history: the run's start, no window)
    the bias block's hold and settle window; a level's end is noted."""
    if tared > 0.5 and not _start_jump(jump, published, hold, window):
        counters[0], counters[1] = hold, max(counters[1], tare_settle)
    if tared <= 0.5:
        jump[_LEVEL_JUMPED] = 0.0  # the level (if any) is over
    jump[_SIGNAL] = tared


@numba.njit(cache=True)
def _all_finite(y, g, motion):
    for v in y:
        if not np.isfinite(v):
            return False
    for v in g:
        if not np.isfinite(v):
            return False
    for v in motion:
        if not np.isfinite(v):
            return False
    return True


@numba.njit(cache=True)
def _may_update(flags, counters):
    """Free of contact, or in a hold or settle window (after tared / payload_changed: they
    update through contact, since a re-initialised estimate that froze at the first false
    contact would never recover); never at fault, and never out of domain except in the
    payload's hold: a held sample re-initialises the payload from itself alone, so the
    compensator's error there lasts that sample, while a grasp's jolt (q̈ out of the
    domain for a few ms) would otherwise freeze a half-risen payload into the detector's
    input."""
    if flags[2] >= 0.5:
        return False
    if counters[2] > 0:
        return True
    holding = counters[0] > 0 or counters[1] > 0 or counters[3] > 0
    free = flags[0] < 0.5
    return flags[1] < 0.5 and (holding or free)


@numba.njit(cache=True)
def _rls_step(y, g, motion, phi, n, K, theta, R, counters, lam, sigma, prior):
    """One RLS update of R (a held block's information reset to the prior first); returns
    Φ'ᵀe', with which R⁻¹ gives θ's step (scaled)."""
    if counters[0] > 0:
        _reset_block(R, n, 0, 6)
        counters[0] -= 1
    fit = phi
    noise = sigma
    if counters[2] > 0:
        _reset_block(R, n, 6, n)
        counters[2] -= 1
        # A held sample re-initialises the payload from itself alone: the gravity part
        # (Δm, Δ(m·c) ⊥ g_S), which one sample determines; the motion terms need a
        # spread of motion (the settle window's), and fitted to one sample they take up
        # the compensator's error in the grasp's transient.
        fit = np.empty((6, n))
        _regressor(g, motion[:0], n, K, fit)
        noise = _with_unfitted_terms(phi, fit, n, sigma, prior)
    scaled = np.empty((6, n))
    e = np.empty(6)
    _whiten(y, fit, n, theta, noise, prior, scaled, e)
    rhs = np.zeros(n)
    _forget_and_add(R, scaled, e, n, lam, rhs)
    return rhs


@numba.njit(cache=True)
def _with_unfitted_terms(phi, fit, n, sigma, prior):
    """Each row's noise σᵢ with the terms a held sample leaves out (Φ − fit: the payload's
    motion terms) added at their prior's spread, √(σᵢ² + Σⱼ ((Φ − fit)ᵢⱼ·priorⱼ)²): the
    sample then informs the payload only as far as the motion lets it, so the estimate's
    covariance after the hold is honest (at rest it is σ, the gravity part exact)."""
    noise = np.empty(6)
    for i in range(6):
        acc = sigma[i] * sigma[i]
        for j in range(6, n):
            d = (phi[i, j] - fit[i, j]) * prior[j]
            acc += d * d
        noise[i] = math.sqrt(acc)
    return noise


@numba.njit(cache=True)
def _whiten(y, fit, n, theta, sigma, prior, scaled, e):
    """Scaled, whitened regressor Φ' = Σ⁻¹ Φ S and innovation e' = Σ⁻¹ (y − Φθ)."""
    for i in range(6):
        acc = y[i]
        for j in range(n):
            acc -= fit[i, j] * theta[j]
            scaled[i, j] = fit[i, j] * prior[j] / sigma[i]
        e[i] = acc / sigma[i]


@numba.njit(cache=True)
def _forget_and_add(R, scaled, e, n, lam, rhs):
    """R ← λ·R + Φ'ᵀΦ' + (1 − λ)·I and rhs = Φ'ᵀe'."""
    for a in range(n):
        for b in range(n):
            acc = 0.0
            for i in range(6):
                acc += scaled[i, a] * scaled[i, b]
            R[a, b] = lam * R[a, b] + acc + ((1.0 - lam) if a == b else 0.0)
        for i in range(6):
            rhs[a] += scaled[i, a] * e[i]


@numba.njit(cache=True)
def _move_published(theta, published, counters, steps, n):
    """The published θ follows the estimate: freely in a settle window, else at most `steps`
    per sample; the settle windows count down."""
    payload_window = counters[3] > 0
    bias_window = counters[1] > 0 or payload_window
    for j in range(n):
        unbounded = bias_window if j < 6 else payload_window
        delta = theta[j] - published[j]
        if not unbounded:
            delta = min(max(delta, -steps[j]), steps[j])
        published[j] += delta
    if counters[1] > 0:
        counters[1] -= 1
    if payload_window:
        counters[3] -= 1


@numba.njit(cache=True)
def _publish(y, phi, n, published, corrected, bias, payload, inertia):
    """The outputs from the published θ: the corrected wrench y − Φ·θ, the bias, the payload."""
    for i in range(6):
        acc = y[i]
        for j in range(n):
            acc -= phi[i, j] * published[j]
        corrected[i] = acc
    for i in range(6):
        bias[i] = published[i]
    if n == N_PAYLOAD:
        for j in range(4):
            payload[j] = published[6 + j]
        for j in range(6):
            inertia[j] = published[10 + j]


# -- a re-tare as a jump ---------------------------------------------------------------------
# The jump's state (after the four counters), fixed fields first, then the ring of the last
# `guard` corrected wrenches (6·guard).
_BEFORE, _B0, _AFTER = 0, 6, 12  # 6 each: the "before" mean, the pulse's bias, the sum after
_AFTER_N, _PHASE = 18, 19  # samples summed after; samples left (hold + window)
_SIGNAL, _LEVEL_JUMPED = 20, 21  # the last sample's signal; whether this level started a jump
_MEAN, _MEAN_N = 22, 28  # the running mean of the corrected wrench (6), its count
_RING_N, _RING_POS, _RING = 29, 30, 31  # ring entries filled, next slot, the ring


def jump_state_size(guard: int) -> int:
    return _RING + 6 * guard


@numba.njit(cache=True)
def _remember(jump, corrected, window, guard):
    """Keeps the corrected wrench of a used, contact-free sample: into the ring; the one
    leaving it (`guard` samples old) into the running mean (a mean until `window` samples,
    then an exponential one of that length)."""
    if window <= 0:
        return
    ring = jump[_RING:_RING + 6 * guard].reshape((guard, 6))
    pos = int(jump[_RING_POS])
    if jump[_RING_N] >= guard:
        jump[_MEAN_N] += 1.0
        w = 1.0 / min(jump[_MEAN_N], window)
        for i in range(6):
            jump[_MEAN + i] += (ring[pos, i] - jump[_MEAN + i]) * w
    else:
        jump[_RING_N] += 1.0
    for i in range(6):
        ring[pos, i] = corrected[i]
    jump[_RING_POS] = (pos + 1) % guard


@numba.njit(cache=True)
def _start_jump(jump, published, hold, window):
    """At a tared sample: starts the jump estimate at the signal's rising edge (a level's
    later samples change nothing: the jump is measured right after the edge, where the
    compensator's error is nearest the "before" level's). False when there is no history to
    compare with (the run's start, `window` 0): then the block resets."""
    if window <= 0:
        return False
    if jump[_SIGNAL] > 0.5 and (jump[_PHASE] > 0 or jump[_LEVEL_JUMPED] > 0.5):
        return True  # the same level, estimated (or being estimated) as a jump
    if jump[_PHASE] <= 0 and jump[_MEAN_N] < window:
        return False
    if jump[_PHASE] <= 0:  # a new jump; during one, a second pulse only restarts the hold
        for i in range(6):
            jump[_BEFORE + i] = jump[_MEAN + i]  # the mean corrected wrench before it
            jump[_B0 + i] = published[i]
        jump[_RING_N] = 0.0  # the ring refills after the jump
    jump[_AFTER:_PHASE] = 0.0
    jump[_PHASE] = hold + window
    jump[_LEVEL_JUMPED] = 1.0
    return True


@numba.njit(cache=True)
def _jump_step(y, phi, flags, n, theta, published, jump, window, corrected, bias, payload,
               inertia, tracking):
    """One sample of a re-tare estimated as a jump of the bias: the hold samples re-initialise
    from themselves, the next `window` ones average; at the end θ's bias moves by the jump and
    its information is kept. The estimator does not update meanwhile."""
    before, b0, after = jump[_BEFORE:_B0], jump[_B0:_AFTER], jump[_AFTER:_AFTER_N]
    usable = flags[1] < 0.5 and flags[2] < 0.5
    if usable:
        level = np.empty(6)  # the reading less the published payload's wrench
        for i in range(6):
            acc = y[i]
            for j in range(6, n):
                acc -= phi[i, j] * published[j]
            level[i] = acc
        if jump[_PHASE] > window:  # hold: this sample alone
            for i in range(6):
                published[i] = level[i] - before[i]
        else:
            jump[_AFTER_N] += 1.0
            for i in range(6):
                after[i] += level[i]
                published[i] = after[i] / jump[_AFTER_N] - before[i]
        jump[_PHASE] -= 1.0
        if jump[_PHASE] <= 0:
            for i in range(6):
                theta[i] += published[i] - b0[i]
    _publish(y, phi, n, published, corrected, bias, payload, inertia)
    tracking[0] = 0.0


@numba.njit(cache=True)
def _cholesky(R, n, L):
    """L (n × n, lower) with L·Lᵀ = R; False if R is not positive definite."""
    for i in range(n):
        for j in range(i + 1):
            acc = R[i, j]
            for m in range(j):
                acc -= L[i, m] * L[j, m]
            if i == j:
                if not acc > 0.0:
                    return False
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
    return True


@numba.njit(cache=True)
def _solve_factored(L, rhs, n):
    """Solves L·Lᵀ·z = rhs in place (rhs ← z)."""
    z = np.empty(n)
    for i in range(n):
        acc = rhs[i]
        for m in range(i):
            acc -= L[i, m] * z[m]
        z[i] = acc / L[i, i]
    for i in range(n - 1, -1, -1):
        acc = z[i]
        for m in range(i + 1, n):
            acc -= L[m, i] * rhs[m]
        rhs[i] = acc / L[i, i]


@numba.njit(cache=True)
def _predictive_std(L, factored, phi, prior, n, std):
    """std_i = √(Φ S R⁻¹ S Φᵀ)_ii (S = diag(prior), L·Lᵀ = R): the std of row i of Φ·θ from
    the estimate's covariance, N or N·m; ∞ on every axis when R was not positive definite."""
    if not factored:
        for i in range(6):
            std[i] = np.inf
        return
    v = np.empty(n)
    for i in range(6):
        total = 0.0
        for a in range(n):  # v = L⁻¹ S Φᵢᵀ; std_i² = |v|²
            acc = phi[i, a] * prior[a]
            for m in range(a):
                acc -= L[a, m] * v[m]
            v[a] = acc / L[a, a]
            total += v[a] * v[a]
        std[i] = math.sqrt(total)


def steady_information(sigma, prior, lam, n, K=None):
    """R (scaled) after a long run of free motion: E[Φ'ᵀΦ']/(1 − λ) + I, the expectation over
    the six axis directions of g (exact isotropic second moments), at rest: the inertia's
    information stays at its prior (motion is not assumed). `K`: the payload's map
    (:func:`_regressor`; default the identity)."""
    phi = np.empty((6, n))
    K = np.eye(6) if K is None else np.asarray(K, dtype=float)
    info = np.zeros((n, n))
    directions = STANDARD_GRAVITY * np.vstack([np.eye(3), -np.eye(3)])
    for g in directions:
        _regressor(g, np.zeros(6), n, K, phi)
        scaled = phi * prior[None, :] / sigma[:, None]
        info += scaled.T @ scaled / len(directions)
    return info / (1.0 - lam) + np.eye(n)
