"""Weighted, column-normalised least squares and its diagnostics, shared by the payload
identifications (:mod:`.consistent`).

Rows of ``A θ ≈ y`` are reduced once to a p × p triangular factor R (:func:`reduce_rows`), so
the cost of everything after does not grow with the number of samples; the diagnostics read
R's singular values: directions the data do not determine at all (below
:data:`NULL_DIRECTION_TOL` of the largest) and parameters whose standard error is large for
their group (:func:`poorly_determined`).
"""

from __future__ import annotations

import numpy as np

# Singular values of the column-normalised regressor below this fraction of the largest mark
# a direction the data does not determine at all (least squares' pseudo-inverse drops them,
# so their parameters would otherwise show small standard errors).
NULL_DIRECTION_TOL = 1e-7
# A regressor column below this fraction of the largest column's norm is round-off, not data.
ZERO_COLUMN_TOL = 1e-9
#: Groups of θ whose standard errors are compared with the group's scale: mass; first
#: moment; inertia; the weight carried without inertia; its first moment.
PARAMETER_GROUPS = ((0,), (1, 2, 3), (4, 5, 6, 7, 8, 9), (16,), (17, 18, 19))


def axis_weights(A, Y) -> np.ndarray:
    """Per-axis weights 1 / RMS of the residual of an unweighted least-squares pass (as
    ``weighted_least_squares``), floored so that an exact fit does not divide by zero."""
    p = A.shape[-1]
    R, z = reduce_rows(A.reshape(-1, p), Y.reshape(-1))
    theta = np.linalg.lstsq(R, z, rcond=None)[0]
    rms = np.sqrt(np.mean((Y - A @ theta) ** 2, axis=0))
    return 1.0 / np.maximum(rms, 1e-9 * (1 + np.abs(Y).max()))


def column_scale(Aw):
    """(column norms, which columns the data do not touch). A column at round-off level
    (below 1e-9 of the largest, e.g. an inertia entry no rotation reaches: its entries are
    1e-16-level leftovers of the kinematics) counts as zero, and is zeroed in `Aw` in
    place: normalised to unit norm it would pass for an excited parameter."""
    scale = np.linalg.norm(Aw, axis=0)
    zero = scale <= ZERO_COLUMN_TOL * max(scale.max(), 1e-300)
    Aw[:, zero] = 0.0
    return np.where(zero, 0.0, scale), zero


def reduce_rows(M, y):
    """(R, z) with ‖M x − y‖² = ‖R x − z‖² + const for every x (R: p×p upper triangular),
    from the QR factorisation of [M y] without forming Q."""
    p = M.shape[1]
    R_aug = np.linalg.qr(np.column_stack([M, y]), mode="r")
    R_aug = np.vstack([R_aug, np.zeros((p + 1 - len(R_aug), p + 1))])  # fewer rows than p+1
    return R_aug[:p, :p], R_aug[:p, p]


def pinv_normal(R):
    """(RᵀR)⁺ from the SVD of R, dropping directions below the null-direction tolerance."""
    _, s, Vt = np.linalg.svd(R)
    keep = s > NULL_DIRECTION_TOL * s[0] if s[0] > 0 else np.zeros_like(s, bool)
    inv = np.zeros_like(s)
    inv[keep] = 1.0 / s[keep] ** 2
    return (Vt.T * inv) @ Vt


def poorly_determined(R, data_cov, theta, cols, relative_se_limit):
    """(relative data-only standard errors, names of the parameters the data cannot
    determine, indices of those in a null direction of R)."""
    names = set()
    _, s, Vt = np.linalg.svd(R)
    for k in np.flatnonzero(s <= NULL_DIRECTION_TOL * s[0]):
        v = np.abs(Vt[k])
        names.update(np.flatnonzero(v >= 0.5 * v.max()).tolist())
    unseen = sorted(names)
    se = np.sqrt(np.maximum(np.diag(data_cov), 0.0))
    rel = np.full(len(cols), np.nan)
    magnitude = np.abs(theta)
    for group in PARAMETER_GROUPS:
        idx = [i for i, c in enumerate(cols) if c in group]
        if not idx:
            continue
        group_scale = max(magnitude[idx].max(), 1e-12)
        rel[idx] = se[idx] / group_scale
        names.update(i for i in idx if rel[i] > relative_se_limit)
    return rel, tuple(int(cols[i]) for i in sorted(names)), unseen


#: The residual's correlation length is the first lag whose autocorrelation falls below this.
CORRELATION_FLOOR = 0.05
#: The window of the overlapping-batch-means estimate, in correlation lengths (a Bartlett
#: window of this width keeps ~90 % of an AR(1) residual's long-run variance).
WINDOW_LENGTHS = 3


def correlation_length(residual) -> int:
    """Rows until the (N, k) residual's autocorrelation, averaged over its columns, first
    falls below :data:`CORRELATION_FLOOR` (1 for white noise), by FFT."""
    e = residual - residual.mean(axis=0)
    n = len(e)
    f = np.fft.rfft(e, n=2 * n, axis=0)
    acov = np.fft.irfft(f * np.conj(f), axis=0)[:n].sum(axis=1)
    if acov[0] <= 0:
        return 1
    below = np.flatnonzero(acov / acov[0] < CORRELATION_FLOOR)
    return int(below[0]) if len(below) else n


def correlated_variance_ratio(Aw, ew):
    """(per-parameter variance ratio, window in rows): how much larger each parameter's
    variance is when the rows are a time series whose errors are correlated than the
    independent-rows formula ``σ²·(AᵀA)⁻¹`` says.

    Aw: (N, k, p) weighted regressor, one time step a row; ew: (N, k) weighted residual.
    The scores ``s_t = A_tᵀ e_t`` (p) are summed over overlapping windows of ``b`` rows
    (:data:`WINDOW_LENGTHS` × :func:`correlation_length`, at most N/5): the
    overlapping-batch-means (Bartlett-kernel, Newey–West) estimate of their long-run
    covariance S gives the sandwich ``H⁺ S H⁺`` (H = AᵀA), compared with the independent
    formula; ratios are floored at 1 (independent rows are the least one can claim).
    ``rows``: the number of time steps (N).
    """
    n, _, p = Aw.shape
    b = int(min(max(1, WINDOW_LENGTHS * correlation_length(ew)), max(1, n // 5)))
    scores = np.einsum("nkp,nk->np", Aw, ew)
    flat = Aw.reshape(-1, p)
    H_inv = np.linalg.pinv(flat.T @ flat, hermitian=True)
    sigma2 = float(np.sum(ew ** 2) / max(1, ew.size - p))
    iid = sigma2 * np.diag(H_inv)
    csum = np.vstack([np.zeros((1, p)), np.cumsum(scores, axis=0)])
    windows = csum[b:] - csum[:-b]  # (N − b + 1, p) sums over b consecutive rows
    S = n * (windows.T @ windows) / (b * len(windows))
    sandwich = np.diag(H_inv @ S @ H_inv)
    ratio = np.where(iid > 0, sandwich / np.where(iid > 0, iid, 1.0), 1.0)
    return np.maximum(ratio, 1.0), b
