"""Where a learned residual has seen data: its support, and an uncertainty that grows without it.

A residual learned on some configurations knows nothing about others: a forest keeps
predicting its boundary leaves' values there, however far the arm goes. The hybrid therefore
weighs its residual by its *support* at the input,

    d = min over training rows ‖(z − zᵢ) / s‖      (z: the residual's inputs, s: their std)
    w = exp(−(d / ℓ)²)                             (1 on the data, → 0 far from it)

and predicts ``physics + w · residual`` with the per-axis variance

    σ² = c · ‖B F‖² + w · σ²_in + (1 − w) · σ²_far + g² · d

(σ²_in: the residual's error where it has data; σ²_far: the physics part's own error, what is
left when the residual is switched off; ‖B F‖²: the physics parameters', c its calibrated
scale (1 until calibrated); g² · d: the error the
model makes as it extrapolates — a rigid model fitted on a few configurations absorbs part of
the unmodelled effects into its parameters, and that part is wrong elsewhere. Its variance
grows linearly with the distance, as a random walk's: an error that decorrelates with distance
(a linear variogram) rather than one that grows like a trend, which is what held-out runs
show: on the coverage test's sub-region model the Fx error's variance is ~3σ² per unit of d
from d = 0.3 to 6).
The distance runs on a k-d tree of at most :data:`SUPPORT_POINTS` training rows
(:mod:`..compiled.kdtree`).

ℓ and σ²_in are calibrated when the hybrid is fitted, on its cross-fit (the residual refitted
on alternate blocks of rows and scored on the others, whose rows lie at many distances from
the other half), with g = 0; :func:`calibrate` re-fits ℓ and g (and, optionally, σ²_in and
c) on held-out runs that leave the training data (``HybridCompensator.domain_terms``, which
:class:`~.domain_calibrated.DomainCalibratedHybrid` predicts with). Which runs: another log of
the task's motion (``holdout=None``), or those of the training data that
:func:`farthest_groups` picks — the runs (or, in a log of one run, the time blocks) whose
inputs lie farthest from the others' (``holdout=share``). Both choose ℓ by
the Gaussian likelihood of the held-out errors over a grid; for each ℓ the variance terms are a
(weighted, non-negative) least-squares fit of the squared errors, which they are linear in.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from ..compiled.kdtree import build_kdtree, nearest_distances

#: The most training rows the support's k-d tree keeps (every k-th row: neighbouring samples
#: of a trajectory are nearly copies). Its query costs ~1 µs at this size.
SUPPORT_POINTS = 4000
#: Smallest std of an input column in the metric (rad, rad/s, rad/s²): a joint that never
#: moved in training is out of domain as soon as it moves.
MIN_SCALE = 1e-2
#: ℓ is searched over this many values, log-spaced around the calibration rows' median d.
LENGTH_GRID = 41
#: Re-weighted least-squares passes of :func:`calibrate` (weights 1/σ⁴ of the last pass).
REWEIGHTING_PASSES = 4
#: Rows the calibration uses at most (every k-th).
CALIBRATION_ROWS = 20000
#: The share of the training rows :func:`farthest_groups` holds out by default.
HOLDOUT_SHARE = 0.2
#: A log of fewer runs than :data:`MIN_GROUPS` is cut into this many contiguous time blocks,
#: the groups of :func:`farthest_groups` (one run alone has nothing to leave).
TIME_BLOCKS = 10
MIN_GROUPS = 3
#: Rows of a group whose distances :func:`farthest_groups` ranks it by (every k-th).
GROUP_ROWS = 500
#: Distance bins (training stds) that reports split rows by: in domain (within one std of a
#: training row), its edge, out of domain.
DISTANCE_BINS = {"in_domain": (0.0, 1.0), "edge": (1.0, 2.0), "out_of_domain": (2.0, np.inf)}


def fit_support(Zd: np.ndarray, max_points: int = SUPPORT_POINTS) -> dict:
    """The support of training inputs `Zd` (N, d): ``center``, ``scale`` (d,) and the k-d
    tree's ``points``, ``nodes``, ``splits`` (standardised rows, :mod:`..compiled.kdtree`)."""
    Zd = np.asarray(Zd, dtype=float)
    center = Zd.mean(axis=0)
    scale = np.maximum(Zd.std(axis=0), MIN_SCALE)
    stride = max(1, int(np.ceil(len(Zd) / max_points)))
    points, nodes, splits = build_kdtree((Zd[::stride] - center) / scale)
    return {"center": center, "scale": scale, "points": points, "nodes": nodes,
            "splits": splits}


def distances(Zd: np.ndarray, support: dict) -> np.ndarray:
    """d (N,) of rows `Zd` (N, d) to `support` (:func:`fit_support`), in training stds."""
    Z = np.ascontiguousarray((np.asarray(Zd, dtype=float) - support["center"])
                             / support["scale"])
    out = np.empty(len(Z))
    nearest_distances(Z, support["points"], support["nodes"], support["splits"], out)
    return out


def weight(d: np.ndarray, length: float) -> np.ndarray:
    """The residual's weight exp(−(d/ℓ)²); 1 everywhere when ℓ is ∞ (no support term)."""
    d = np.asarray(d, dtype=float)
    if not np.isfinite(length):
        return np.ones_like(d)
    return np.exp(-(d / length) ** 2)


def _rows(*arrays):
    stride = max(1, int(np.ceil(len(arrays[0]) / CALIBRATION_ROWS)))
    return [np.asarray(a, dtype=float)[::stride] for a in arrays]


def _lengths(d: np.ndarray) -> np.ndarray:
    centre = np.median(d[d > 0]) if (d > 0).any() else 1.0
    return np.concatenate([centre * np.geomspace(0.03, 30.0, LENGTH_GRID), [np.inf]])


def _nll(error, var):
    return float(np.sum(np.log(var) + error ** 2 / var))


def fit_in_domain(d, target, predicted, far_var) -> tuple[float, np.ndarray]:
    """(ℓ, σ²_in (k,)) from cross-fit rows: their distances `d` (N,) to the half the residual
    was fitted on, the residual's `target` and its `predicted` value there (N, k), and σ²_far
    (k,). For each ℓ, σ²_in solves E[e²] = w σ²_in + (1 − w) σ²_far in least squares (within
    [10⁻⁶, 1] · σ²_far); the ℓ of the highest likelihood wins."""
    d, target, predicted = _rows(d, target, predicted)
    far_var = np.maximum(np.asarray(far_var, dtype=float), 1e-300)
    best = (np.inf, np.inf, np.mean((target - predicted) ** 2, axis=0))
    for length in _lengths(d):
        w = weight(d, length)[:, None]
        error = target - w * predicted
        numerator = np.sum(w * (error ** 2 - (1 - w) * far_var), axis=0)
        in_var = np.clip(numerator / max(float(np.sum(w ** 2)), 1e-300), 1e-6 * far_var,
                         far_var)
        score = _nll(error, w * in_var + (1 - w) * far_var)
        if score < best[0]:
            best = (score, length, in_var)
    return float(best[1]), best[2]


#: Where the hybrid's in-domain level (σ²_in, and the parameters' scale c) comes from when it is
#: calibrated: ``"cross_fit"`` keeps the fit's (c = 1), ``"held_out"`` fits them on the
#: held-out runs with g (:func:`calibrate`).
IN_DOMAIN_SOURCES = ("cross_fit", "held_out")


def calibrate(d, target, predicted, in_var, far_var, parameter_var, *,
              shared: bool = False, in_domain: str = "cross_fit"
              ) -> tuple[float, np.ndarray, np.ndarray, float]:
    """(ℓ, σ²_in (k,), g (k,), c) from held-out rows that leave the training data: their
    distances `d` (N,), the physics part's error `target` (N, k), the residual's `predicted`
    value (N, k) and the physics parameters' variance ‖B F‖² (N, k). σ²_far (k,) is kept
    (the physics part's training error is the fallback: fitting it too would let
    (1 − w) σ²_far with a long ℓ mimic a growth ∝ d² that extrapolates badly).

    The variance is c ‖B F‖² + w σ²_in + (1 − w) σ²_far + g² d. For each ℓ of the grid, the
    free terms are the non-negative least-squares fit of the squared errors (re-weighted by
    1/σ⁴, the variance of e² for a Gaussian e); the ℓ of the highest likelihood wins.

    `in_domain`: ``"cross_fit"`` (default): `in_var` is σ²_in (the fit's cross-fit) and c = 1;
    only g is fitted with ℓ. ``"held_out"``: `in_var` is the residual's error on its own
    training rows, the floor of σ²_in = `in_var` + a; a and c are fitted with g (one c for all
    axes: one covariance). Why one might: the cross-fit's residual learned from half the runs,
    so its error is that of rows about a run away, not of rows next to the training data, and
    the parameters' covariance treats the physics part's training error as white noise, most
    of which the residual explains. Why it is not the default: its tighter std rests on the
    few held-out runs, and where the model's own error is larger than they show it raises
    false contacts the cross-fit's std does not (docs/guide/calibration.md: both, measured;
    the demo uses it with `shared`).

    `shared`: one growth for all axes in units of each axis' σ²_far, g²ₐ = κ · σ²_far,ₐ (an
    axis whose physics part errs more in training errs more away from it), and with
    ``"held_out"`` one excess in units of each axis' floor, aₐ = λ · `in_var`ₐ (the same
    argument next to the data); default one per axis. Per axis suits many independent
    held-out poses (``tests/compensation/test_domain_uncertainty``: the synthetic error's
    growth differs per axis; shared leaves Fx at 0.66 coverage out of domain); the shared
    terms carried over better on the demo's few held-out runs (the guide)."""
    if in_domain not in IN_DOMAIN_SOURCES:
        raise ValueError(f"in_domain must be one of {IN_DOMAIN_SOURCES}; got {in_domain!r}")
    fit_level = in_domain == "held_out"
    d, target, predicted, parameter_var = _rows(d, target, predicted, parameter_var)
    in_var = np.maximum(np.asarray(in_var, dtype=float), 0.0)
    far_var = np.asarray(far_var, dtype=float)
    unit = np.maximum(far_var, 1e-300)  # g² = κ · σ²_far when shared
    best = (np.inf, np.inf, in_var, np.zeros(len(far_var)), 1.0)
    for length in _lengths(d):
        w = weight(d, length)
        error = target - w[:, None] * predicted
        known = w[:, None] * in_var + (1 - w[:, None]) * far_var
        scale, excess, growth2, var = _fit_variance_terms(error, known, parameter_var, w, d,
                                                          unit, in_var, shared, fit_level)
        score = _nll(error, var)
        if score < best[0]:
            best = (score, length, in_var + excess, np.sqrt(growth2), scale)
    return float(best[1]), best[2], best[3], float(best[4])


def _fit_variance_terms(error, known, parameter_var, w, d, unit, floor, shared, fit_level):
    """(c, a (k,), g² (k,), the variance (N, k)), all ≥ 0: the re-weighted non-negative
    least-squares fit of E[e²] = known + c · parameter_var + w · a + g² · d over all axes at
    once (one c), with g² = κ · `unit` and a = λ · `floor` (one κ, one λ) when `shared`;
    without `fit_level` only g² (c = 1, a = 0)."""
    n, k = error.shape
    var = np.maximum(np.mean(error ** 2, axis=0), 1e-300) * np.ones_like(known)
    levels = (1 if shared else k) if fit_level else 0
    first = 1 + levels if fit_level else 0  # the growth's first column
    scale, excess = 1.0, np.zeros(k)
    for _ in range(REWEIGHTING_PASSES):
        design = np.zeros((n * k, first + (1 if shared else k)))
        for a in range(k):
            rows = slice(a * n, (a + 1) * n)
            if fit_level:
                design[rows, 0] = parameter_var[:, a] / var[:, a]
                level_unit = floor[a] if shared else 1.0
                design[rows, 1 if shared else 1 + a] = w * level_unit / var[:, a]
            growth_unit = unit[a] if shared else 1.0
            design[rows, first + (0 if shared else a)] = d * growth_unit / var[:, a]
        fixed = known + (0.0 if fit_level else parameter_var)
        x, _ = nnls(design, ((error ** 2 - fixed) / var).T.ravel())
        if fit_level:
            scale, excess = float(x[0]), (x[1] * floor if shared else x[1:first])
        growth2 = x[first] * unit if shared else x[first:]
        var = np.maximum(known + scale * parameter_var + w[:, None] * excess
                         + growth2 * d[:, None], 1e-300)
    return scale, excess, growth2, var


def farthest_groups(inputs, groups=None, share: float = HOLDOUT_SHARE
                    ) -> tuple[np.ndarray, list]:
    """(held-out rows (N,) bool, their group labels): whole groups of rows `inputs` (N, d)
    — `groups` (N,) a run or trajectory label per row; None or fewer than
    :data:`MIN_GROUPS` distinct labels: the rows cut into :data:`TIME_BLOCKS` contiguous time
    blocks instead (rows in time order) — held out for :func:`calibrate`, those farthest from the
    other groups first, until `share` of the rows is held out (at least one group; never so
    many that less than half the rows are left to train on).

    A group's distance is the median over its rows of the distance to the support
    (:func:`fit_support`) of all the other groups: a run that goes where no other run went
    ranks high, a repeat of another run low. Held-out runs that leave the training data —
    and, being whole runs, come back to it — give the rows at many distances that pin ℓ and g
    down; a random share of rows would all lie next to a training row."""
    inputs = np.asarray(inputs, dtype=float)
    if not 0 < share < 0.5:
        raise ValueError(f"share must be in (0, 0.5): the share of rows held out; got {share!r}")
    n = len(inputs)
    if n < 2 * TIME_BLOCKS:
        raise ValueError(f"farthest_groups: {n} rows are too few to hold some out (need "
                         f"{2 * TIME_BLOCKS})")
    labels = None if groups is None else np.asarray(groups).ravel()
    if labels is not None and len(labels) != n:
        raise ValueError(f"groups has {len(labels)} labels for {n} rows")
    if labels is None or len(np.unique(labels)) < MIN_GROUPS:
        labels = (np.arange(n) * TIME_BLOCKS) // n
    names, index = np.unique(labels, return_inverse=True)
    score = np.empty(len(names))
    for g in range(len(names)):
        own = np.flatnonzero(index == g)
        rows = own[::max(1, len(own) // GROUP_ROWS)]
        score[g] = np.median(distances(inputs[rows], fit_support(inputs[index != g])))
    held = np.zeros(n, dtype=bool)
    chosen = []
    for g in np.argsort(-score, kind="stable"):
        if held.sum() >= share * n:
            break
        grown = held | (index == g)
        if grown.sum() <= n / 2:  # a group too big to leave half the rows is passed over
            held, chosen = grown, [*chosen, names[g]]
    if not chosen:
        raise ValueError("farthest_groups: every group holds more than half the rows; pass "
                         "groups=None to cut the rows into time blocks")
    return held, [v.item() if hasattr(v, "item") else v for v in chosen]
