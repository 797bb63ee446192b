"""The physics payload model's row, compiled: S's kinematics on the serial chain, the 6 × p
regressor row (p = 16, 20 with the weight carried without inertia, 22 with a tether too), the
reading's mean and the parameters' variance, from two packed arrays.

A numba call pays for unboxing each array argument before it does any work; with the chain,
the parameters and the covariance factor as eleven arrays that would cost more than this
kernel's arithmetic. :func:`pack_payload_row` puts them into one float64 and one int64 array
once; :func:`payload_mean_var` unpacks views of them inside the kernel.
:class:`~ftdrake.compensation.estimators.physics.PhysicsPayloadCompensator` and the hybrid's fused
row (:mod:`.hybrid`) use it; the estimators fill it, this module knows nothing of them.

Packed layout (m moving joints, n joints in the row, r columns of the covariance factor)::

    reals (float64): g_W (3) | X_pre ((m + 1)·12) | axes (3m) | block_T (36) | θ (p)
                     | Fᵀ (r·p) | σ² (6) [| p_FP (3) | p_SQ (3)]
    ints (int64):    n, m, r, static, rotated, p | kinds (m) | q_index (m) | v_index (m)
                     [| the tether's frame (0 … m − 1 a moving joint's M, m the world)]

with X_pre, kinds, axes, q_index, v_index :class:`~ftdrake.physics.chain.SerialChain`'s kernel
arrays, block_T (6 × 6) rotating a wrench from S into the measuring frame Sm, θ = [φ; b],
F Fᵀ the parameters' covariance and σ² a variance added per axis; ``rotated`` is 0 when
block_T is the identity (no mounting rotation: the kernel skips the product). The bracketed
entries are there when p = 22: the tether's geometry
(:mod:`~ftdrake.compensation.identification.tether`).
"""

from __future__ import annotations

import numba
import numpy as np

from ...physics.chain import joint_frames_in_sensor_row, sensor_kinematics_row


def pack_payload_row(chain_args, n_joints: int, gravity_W, static: bool, block_T, parameters,
                     factor, noise_var, tether=None) -> tuple[np.ndarray, np.ndarray]:
    """(reals, ints) for :func:`payload_mean_var` (layout in the module docstring).

    chain_args: ``SerialChain.kernel_args()`` (X_pre, kinds, axes, q_index, v_index);
    block_T (6, 6); parameters (p,) with p = 16, 20 or 22; factor (p, r ≤ p); noise_var (6,);
    tether (p = 22 only): (frame index, p_FP, p_SQ), the index as in the module docstring.
    """
    X_pre, kinds, axes, q_index, v_index = chain_args
    factor = np.asarray(factor, dtype=float)
    p = len(np.asarray(parameters).reshape(-1))
    if p not in (16, 20, 22) or np.shape(parameters) != (p,) or factor.ndim != 2 or \
            factor.shape[0] != p or factor.shape[1] > p or np.shape(block_T) != (6, 6):
        raise ValueError("expected 16, 20 or 22 parameters, a p × r factor (r <= p) and a "
                         "6 × 6 rotation")
    if (p == 22) != (tether is not None) or (
            tether is not None and not 0 <= int(tether[0]) <= len(kinds)):
        raise ValueError("22 parameters need a tether (frame index 0 … m, p_FP, p_SQ); 16 or "
                         "20 none")
    # Zero columns (directions with no uncertainty, e.g. a static model's inertia) add
    # exact zeros to the variance: dropped.
    used = np.flatnonzero(np.any(factor != 0.0, axis=0))
    factor = factor[:, used] if len(used) else np.zeros((p, 1))
    m, r = len(kinds), factor.shape[1]
    reals = np.concatenate([
        np.asarray(gravity_W, dtype=float).reshape(3), np.asarray(X_pre, float).reshape(-1),
        np.asarray(axes, float).reshape(-1), np.asarray(block_T, float).reshape(-1),
        np.asarray(parameters, float), factor.T.reshape(-1),
        np.asarray(noise_var, float).reshape(6),
        *([] if tether is None else [np.asarray(tether[1], float).reshape(3),
                                     np.asarray(tether[2], float).reshape(3)])])
    rotated = int(not np.array_equal(block_T, np.eye(6)))
    ints = np.concatenate([[n_joints, m, r, int(bool(static)), rotated, p], kinds, q_index,
                           v_index, [] if tether is None else [int(tether[0])]]
                          ).astype(np.int64)
    return np.ascontiguousarray(reals), np.ascontiguousarray(ints)


@numba.njit(cache=True, nogil=True)
def payload_mean_var(x, reals, ints, mean, var):
    """One full-layout row x [q, q̇, q̈] (3n) → mean (6) = B·θ and var (6) = ‖B_i F‖² + σ_i²,
    with B = [block_T · A_φ | I | block_T · A_w | block_T · A_t] the regressor row rotated
    into Sm (A_w: the weight carried without inertia, when θ has 20 or 22 entries; A_t: the
    tether, when it has 22)."""
    n, m, r, static, rotated, p = ints[0], ints[1], ints[2], ints[3], ints[4], ints[5]
    kinds, q_index, v_index = ints[6:6 + m], ints[6 + m:6 + 2 * m], ints[6 + 2 * m:6 + 3 * m]
    k = 3
    gravity_W = reals[:k]
    X_pre = reals[k:k + (m + 1) * 12].reshape((m + 1, 3, 4))
    k += (m + 1) * 12
    axes = reals[k:k + 3 * m].reshape((m, 3))
    k += 3 * m
    block_T = reals[k:k + 36].reshape((6, 6))
    k += 36
    parameters = reals[k:k + p]
    k += p
    factor_T = reals[k:k + p * r].reshape((r, p))
    k += p * r
    noise_var = reals[k:k + 6]
    k += 6
    work = np.zeros((2, 6, p))  # A and B in one allocation
    A, B = work[0], work[1]
    kin = np.empty((7, 3))  # ω, α, a of S and g, in S; then R_WS
    sensor_kinematics_row(x[:n], x[n:2 * n], x[2 * n:3 * n], gravity_W, X_pre, kinds, axes,
                          q_index, v_index, kin[4:], kin[:4])
    if static:
        kin[:3, :] = 0.0
    if p >= 20:
        weight_columns(kin[3], A)  # before g is overwritten
    if p == 22:
        frames = np.empty((m + 1, 3, 4))
        joint_frames_in_sensor_row(x[:n], X_pre, kinds, axes, q_index, frames)
        tether_columns_row(frames[ints[6 + 3 * m]], reals[k:k + 3], reals[k + 3:k + 6], A)
    for c in range(3):
        kin[3, c] = kin[2, c] - kin[3, c]  # a − g
    regressor_row(kin[0], kin[1], kin[3], A)
    if rotated:
        for i in range(6):
            for j in range(p):
                if 10 <= j < 16:
                    continue  # the biases are added in the measuring frame
                s = 0.0
                for c in range(6):
                    s += block_T[i, c] * A[c, j]
                B[i, j] = s
            B[i, 10 + i] = 1.0
    else:
        B = A  # the product with the identity, exactly
    for i in range(6):
        s = 0.0
        for j in range(p):
            s += B[i, j] * parameters[j]
        mean[i] = s
    # var_i = σ_i² + ‖B_i F‖², F's columns as contiguous rows of Fᵀ. Scalar sums: a
    # vectorised form's larger code evicts the caches the rest of the 1 kHz step needs.
    for i in range(6):
        v = noise_var[i]
        for c in range(r):
            t = 0.0
            for j in range(p):
                t += B[i, j] * factor_T[c, j]
            v += t * t
        var[i] = v


@numba.njit(cache=True, nogil=True)
def payload_mean_std(x, reals, ints, mean, std):
    """:func:`payload_mean_var`, then std = √var in place."""
    payload_mean_var(x, reals, ints, mean, std)
    for i in range(6):
        std[i] = np.sqrt(std[i])


@numba.njit(cache=True, nogil=True)
def payload_predict(x, n, gravity_W, X_pre, kinds, axes, q_index, v_index, static, parameters,
                    out):
    """One full-layout row [q, q̇, q̈] (3n) → wrench (6) = A(row) · parameters (in S; the
    mean-only path of ``PhysicsPayloadCompensator.predict_row``; 16 or 20 parameters)."""
    R = np.empty((3, 3))
    kin = np.empty((4, 3))  # ω, α, a of S and g, in S
    sensor_kinematics_row(x[:n], x[n:2 * n], x[2 * n:3 * n], gravity_W, X_pre, kinds, axes,
                          q_index, v_index, R, kin)
    if static:
        kin[:3, :] = 0.0
    p = len(parameters)
    A = np.zeros((6, p))
    regressor_row(kin[0], kin[1], kin[2] - kin[3], A)
    if p == 20:
        weight_columns(kin[3], A)
    for i in range(6):
        s = 0.0
        for j in range(p):
            s += A[i, j] * parameters[j]
        out[i] = s


@numba.njit(cache=True, nogil=True)
def regressor_row(w, al, d, A):
    """The 6 × 16 regressor row of ``physics.payload_regressor`` (A zeroed on entry); ω, α and
    d = a − g in S."""
    wx, wy, wz = w[0], w[1], w[2]
    ax, ay, az = al[0], al[1], al[2]
    # Small matrices as tuples (no allocation); the same sums, term for term, as the
    # matrix form: [ω]×[ω]× = ω ωᵀ − |ω|² I, [α]×, [d]×, L(α), L(ω), [ω]×.
    ww = wx * wx + wy * wy + wz * wz
    Sa = ((0.0, -az, ay), (az, 0.0, -ax), (-ay, ax, 0.0))
    Sd = ((0.0, -d[2], d[1]), (d[2], 0.0, -d[0]), (-d[1], d[0], 0.0))
    for i in range(3):
        A[i, 0] = -d[i]
        for j in range(3):
            w2 = w[i] * w[j]
            if i == j:
                w2 -= ww
            A[i, 1 + j] = -(Sa[i][j] + w2)
            A[3 + i, 1 + j] = Sd[i][j]
    # −(L(α) + [ω]× L(ω)) over [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]
    La = ((ax, ay, az, 0.0, 0.0, 0.0), (0.0, ax, 0.0, ay, az, 0.0),
          (0.0, 0.0, ax, 0.0, ay, az))
    Lw = ((wx, wy, wz, 0.0, 0.0, 0.0), (0.0, wx, 0.0, wy, wz, 0.0),
          (0.0, 0.0, wx, 0.0, wy, wz))
    Sw = ((0.0, -wz, wy), (wz, 0.0, -wx), (-wy, wx, 0.0))
    for i in range(3):
        for j in range(6):
            A[3 + i, 4 + j] = -(La[i][j] + Sw[i][0] * Lw[0][j] + Sw[i][1] * Lw[1][j]
                                + Sw[i][2] * Lw[2][j])
    for i in range(6):
        A[i, 10 + i] = 1.0


@numba.njit(cache=True, nogil=True)
def weight_columns(g, A):
    """Columns 16–19 of the regressor: a weight carried without inertia, [m_w·g; (m_w·c_w) × g]
    with g gravity in S (``physics.payload_regressor``'s ``gravity_S``)."""
    for i in range(3):
        A[i, 16] = g[i]
    # (m_w·c_w) × g = [−g]× (m_w·c_w)
    A[3, 17], A[3, 18], A[3, 19] = 0.0, g[2], -g[1]
    A[4, 17], A[4, 18], A[4, 19] = -g[2], 0.0, g[0]
    A[5, 17], A[5, 18], A[5, 19] = g[1], -g[0], 0.0


@numba.njit(cache=True, nogil=True)
def tether_columns_row(X_SF, p_FP, p_SQ, A):
    """Columns 20–21 of the regressor: a tether of unit k and unit k·ℓ0 from Q (p_SQ, in S) to
    P (p_FP in the frame F posed by X_SF (3 × 4) in S): ``[d; Q×d]`` and ``[−u; −Q×u]``,
    d = p_SP − p_SQ, u = d / |d|
    (:func:`ftdrake.compensation.identification.tether.tether_columns`)."""
    d = np.empty(3)
    for i in range(3):
        d[i] = (X_SF[i, 0] * p_FP[0] + X_SF[i, 1] * p_FP[1] + X_SF[i, 2] * p_FP[2]
                + X_SF[i, 3] - p_SQ[i])
    length = max(np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1e-9)
    for i in range(3):
        A[i, 20] = d[i]
        A[i, 21] = -d[i] / length
    A[3, 20] = p_SQ[1] * d[2] - p_SQ[2] * d[1]
    A[4, 20] = p_SQ[2] * d[0] - p_SQ[0] * d[2]
    A[5, 20] = p_SQ[0] * d[1] - p_SQ[1] * d[0]
    for i in range(3):
        A[3 + i, 21] = -A[3 + i, 20] / length
