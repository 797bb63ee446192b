"""The delay between a log's joint-state and wrench streams: estimated, and corrected.

Joint states and wrenches from a real robot come from different drivers, each with its own
latency; a log that pairs them by timestamp then pairs a reading with a joint state it does
not belong to. In motion the wrench changes by ẇ·d over a delay d, which a model cannot learn
and the loop cannot compensate.

Convention: ``delay_s`` = d > 0 means the **wrench stream lags** the joint states: the reading
stamped t is the sensor's load at the robot's state of t − d (d < 0: the joint states lag).

* :func:`estimate_stream_delay`: the d that best aligns a model's prediction from the joint
  state with the measured wrench — a physics model, or a hybrid's physics part
  (:func:`motion_model`), whose prediction follows the robot's motion (a model fitted on
  the misaligned log is good enough: a delay is not in the span of its regressors). The
  misfit is computed at whole-sample lags, each axis scaled by its spread and its mean
  offset removed; the minimum is refined by a parabola through it and its neighbours
  (sub-sample), and its uncertainty is the spread of that minimum over a bootstrap of
  contiguous segments of the log.
* :func:`shift_wrench`: a table corrected offline: the wrench columns moved d earlier
  (linearly interpolated), so each row pairs the joint state of t with the reading of t + d.
* Live (and in :func:`ftdrake.replay`), the runtime chain cannot look ahead: it delays the
  joint state by d instead (:class:`~ftdrake.runtime.delay_line.DelayLine`; a model's
  ``wrench_delay_s_`` or ``ChainConfig.sensor.wrench_delay_s``). Both pair the same
  samples.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd

from .. import conventions as col
from ..errors import LogError
from .dataset import joint_state_layout, wrench_targets

DEFAULT_MAX_LAG_S = 0.1


@dc.dataclass(frozen=True)
class DelayEstimate:
    """How long the wrench stream lags the joint states (see the module docstring)."""

    delay_s: float  # s; > 0: the wrench lags
    std_s: float  # s, bootstrap over segments
    period_s: float  # the log's median sample period
    lags_s: np.ndarray  # whole-sample lags tried, s
    misfit: np.ndarray  # mean squared scaled misfit at each lag (1 = the wrench's variance)

    @property
    def samples(self) -> float:
        """The delay in sample periods."""
        return self.delay_s / self.period_s

    def as_dict(self) -> dict:
        """The estimate as plain numbers (for reports and model summaries)."""
        best = int(np.argmin(self.misfit))
        return {"delay_s": self.delay_s, "std_s": self.std_s, "samples": self.samples,
                "distinct_from_zero": bool(abs(self.delay_s) > 2 * self.std_s),
                "period_s": self.period_s, "misfit_at_delay": float(self.misfit[best]),
                "misfit_at_zero": float(self.misfit[len(self.misfit) // 2])}


def estimate_stream_delay(model, log: pd.DataFrame, *, wrench: str = col.MEASURED,
                          max_lag_s: float = DEFAULT_MAX_LAG_S, segments: int = 10,
                          bootstraps: int = 200, seed: int = 0) -> DelayEstimate:
    """Estimates the wrench stream's delay behind the joint states in `log` with `model`.

    `log`: ``t``, ``q_i``, ``qd_i`` and the wrench columns `wrench`_* (and ``temperature``
    for a model trained with it); q̈ is the central difference of q̇ (no lag of its own).
    `max_lag_s`: the largest delay either way tried. `segments` contiguous pieces are
    resampled `bootstraps` times for the uncertainty.
    """
    t = log[col.TIME].to_numpy(dtype=float)
    measured = _columns(log, col.wrench_columns(wrench), "the sensor's reading")
    return delay_between(measured, motion_model(model).predict(_model_input(model, log)), t,
                         max_lag_s=max_lag_s, segments=segments, bootstraps=bootstraps,
                         seed=seed)


def delay_between(measured: np.ndarray, predicted: np.ndarray, t: np.ndarray,
                  groups: np.ndarray | None = None, *, max_lag_s: float = DEFAULT_MAX_LAG_S,
                  segments: int = 10, bootstraps: int = 200, seed: int = 0) -> DelayEstimate:
    """:func:`estimate_stream_delay` on arrays: `measured` and `predicted` (N, m) wrenches
    at times `t` (s); `groups` (N,) numbers separate recordings (a lag never pairs rows of
    two of them; time may restart in each)."""
    measured, predicted = np.asarray(measured, float), np.asarray(predicted, float)
    t = np.asarray(t, float)
    groups = np.zeros(len(t)) if groups is None else np.asarray(groups)
    same = groups[1:] == groups[:-1]
    period = float(np.median(np.diff(t)[same])) if same.any() else float("nan")
    if not period > 0:
        raise LogError("estimate_stream_delay: the log needs increasing times")
    max_lag = max(1, round(max_lag_s / period))
    # Rows whose every shifted partner lies in the same recording: the same rows at each lag,
    # so the misfits compare.
    index = np.arange(len(t))
    inside = (index >= max_lag) & (index < len(t) - max_lag)
    rows = index[inside]
    rows = rows[(groups[rows - max_lag] == groups[rows]) & (groups[rows + max_lag] == groups[rows])]
    if len(rows) < max(4 * max_lag, 2 * segments):
        raise LogError(f"estimate_stream_delay: {len(rows)} usable rows are too few for lags "
                       f"up to {max_lag_s} s; record longer or lower max_lag_s")
    lags = np.arange(-max_lag, max_lag + 1)
    scale = measured.std(axis=0)
    scale[scale == 0] = 1.0
    blocks = np.array_split(np.arange(len(rows)), segments)
    sums = np.empty((len(lags), segments))
    for i, lag in enumerate(lags):
        # The reading at k belongs to the state at k − lag.
        diff = (measured[rows] - predicted[rows - lag]) / scale
        diff -= diff.mean(axis=0)  # a constant offset (bias) is not a delay
        squared = (diff ** 2).sum(axis=1)
        sums[i] = [squared[block].sum() for block in blocks]
    misfit = sums.sum(axis=1) / len(rows) / measured.shape[1]
    delay = _parabolic_minimum(misfit) - max_lag
    rng = np.random.default_rng(seed)
    draws = [_parabolic_minimum(sums[:, rng.integers(0, segments, segments)].sum(axis=1))
             - max_lag for _ in range(bootstraps)]
    return DelayEstimate(delay_s=float(delay * period), std_s=float(np.std(draws) * period),
                         period_s=period, lags_s=lags * period, misfit=misfit)


def shift_rows(Y: np.ndarray, t: np.ndarray, delay_s: float,
               groups: np.ndarray | None = None) -> np.ndarray:
    """(values, keep): `Y` (N, m) moved `delay_s` earlier within each group (linear
    interpolation at t + d), and the mask of the rows whose t + d lies inside their group."""
    Y, t = np.asarray(Y, float), np.asarray(t, float)
    groups = np.zeros(len(t)) if groups is None else np.asarray(groups)
    out, keep = np.empty_like(Y), np.zeros(len(t), dtype=bool)
    for g in pd.unique(groups):
        idx = np.flatnonzero(groups == g)
        tg, target = t[idx], t[idx] + float(delay_s)
        keep[idx] = (target >= tg[0]) & (target <= tg[-1])
        for j in range(Y.shape[1]):
            out[idx, j] = np.interp(target, tg, Y[idx, j])
    return out, keep


def shift_wrench(log: pd.DataFrame, delay_s: float, *, wrench: str = col.MEASURED
                 ) -> pd.DataFrame:
    """`log` with the wrench columns moved `delay_s` earlier (the reading of t + d on the row
    of t, linearly interpolated in time), which corrects a wrench stream that lags by d; rows
    whose t + d lies outside the log are dropped."""
    names = col.wrench_columns(wrench)
    values, keep = shift_rows(_columns(log, names, "the sensor's reading"),
                              log[col.TIME].to_numpy(dtype=float), delay_s)
    out = log.loc[keep].copy()
    out[names] = values[keep]
    return out.reset_index(drop=True)


def motion_model(model):
    """The part of `model` whose prediction follows the motion: a hybrid's physics part (its
    residual forest, fitted on the same rows, learnt their delayed reading along the
    trajectory, so the whole hybrid's prediction of its training rows shows no delay), else
    `model` itself."""
    return getattr(model, "physics_", model)


def _parabolic_minimum(values: np.ndarray) -> float:
    """The index of the minimum, refined by the parabola through it and its neighbours."""
    i = int(np.argmin(values))
    if i == 0 or i == len(values) - 1:
        return float(i)
    a, b, c = values[i - 1], values[i], values[i + 1]
    curvature = a - 2 * b + c
    return float(i) if curvature <= 0 else i + 0.5 * (a - c) / curvature


def _model_input(model, log: pd.DataFrame) -> np.ndarray:
    n = int(model.n_joints_)
    t = log[col.TIME].to_numpy(dtype=float)
    q = _columns(log, col.joint_columns(col.Q, n), "joint positions (rad)")
    qd = _columns(log, col.joint_columns(col.QD, n), "joint velocities (rad/s)")
    blocks = [q, qd, np.gradient(qd, t, axis=0)]
    if getattr(model, "temperature_in_", False):
        blocks.append(_columns(log, [col.TEMPERATURE], "the sensor's temperature (°C)"))
    return np.hstack(blocks)


def _columns(log: pd.DataFrame, names: list[str], what: str) -> np.ndarray:
    missing = [c for c in names if c not in log.columns]
    if missing:
        raise LogError(f"estimate_stream_delay: the log lacks {missing} ({what})")
    return log[names].to_numpy(dtype=float)


def fit_aligned(model, log: pd.DataFrame, *, delay_s: float | None = None,
                source: str = "est", wrench: str = col.MEASURED, iterations: int = 2,
                **estimate_options):
    """Fits `model` on `log` with the streams aligned; returns (model, DelayEstimate or None).

    `delay_s` None: the delay is estimated (:func:`estimate_stream_delay`) with the model
    fitted on the log as it is, the log corrected, the model fitted again and what delay is
    left estimated and added, `iterations` times (a model fitted on a misaligned log absorbs
    a little of the delay: 1 ms of 30 ms at once, none after the second pass on the demo's
    arm), then the model is fitted on the log corrected by the total. A number: that delay
    corrected, nothing estimated. The model is fitted with the delay (``fit``'s
    `wrench_delay_s`): it keeps it as ``wrench_delay_s_`` (s), which the runtime chain applies
    live (a delay line on the joint state).
    """
    def fit(delay):
        aligned = shift_wrench(log, delay, wrench=wrench) if delay else log
        model.fit(joint_state_layout(aligned, source), wrench_targets(aligned, wrench),
                  wrench_delay_s=float(delay))
        return aligned

    estimate = None
    if delay_s is None:
        delay_s = 0.0
        for _ in range(max(1, int(iterations))):
            aligned = fit(delay_s)
            estimate = estimate_stream_delay(model, aligned, wrench=wrench, **estimate_options)
            delay_s += estimate.delay_s
        estimate = dc.replace(estimate, delay_s=float(delay_s))
    fit(delay_s)
    return model, estimate


def align_training_data(data, delay_s: float):
    """A :class:`~.training.TrainingData` with its targets moved `delay_s` earlier within each
    recording (:func:`shift_rows`; rows whose t + d lies outside their recording dropped)."""
    Y, keep = shift_rows(data.Y, data.t, delay_s, data.groups)
    rows = dict(data.rows, used=int(keep.sum()))
    return dc.replace(data, X=data.X[keep], Y=Y[keep], t=data.t[keep],
                      groups=data.groups[keep], rows=rows)


def estimate_training_delay(fit, data, *, iterations: int = 2, **options) -> DelayEstimate:
    """The delay of `data`'s targets behind its joint states (a TrainingData), with the model
    `fit(data)` returns (fitted on the data as given, then on the data corrected by the
    estimate so far, `iterations` times; see :func:`fit_aligned`)."""
    delay, estimate = 0.0, None
    for _ in range(max(1, int(iterations))):
        aligned = align_training_data(data, delay) if delay else data
        model = fit(aligned)
        estimate = delay_between(aligned.Y, motion_model(model).predict(aligned.X), aligned.t,
                                 aligned.groups, **options)
        delay += estimate.delay_s
    return dc.replace(estimate, delay_s=float(delay))
