"""What a log's in-motion residual is made of: drift, stream delay, the sensor's filter, rest.

A model that is right at rest can still leave a residual in motion several times the sensor's
resting noise. Three effects of the *streams*, not of the model, cause part of it on a real
robot, and none of them is something a model of the joint state can learn:

* **offset and drift** (a constant and a slope in time): what the bias tracker did not
  follow (the constant also holds the model's mean error in this motion);
* **stream delay** d: the wrench stream lags the joint states (drivers' latencies,
  :mod:`ftdrake.data.stream_delay`'s convention: the reading at t is the load of t − d);
* **the sensor's own filter**: a first-order low-pass at f_c of the sensor's electronics or
  driver, which the model's prediction does not have.

:func:`residual_budget` replays the log through the whole runtime chain
(:func:`ftdrake.replay`, bias tracker included), takes its contact-wrench estimate r (the
residual the detector judges) on the rows in motion, and explains r by fitting, per log,

    r ≈ a + b·(t − t̄)  +  T·(L_fc(P(t − d)) − P(t))

(per axis a, b; shared d, f_c; t̄ the mean time of the rows in motion; L_fc the first-order
low-pass; T the model's reading-to-S transform; P the load that follows the motion: the
prediction of the model's physics part — a hybrid's ``physics_`` or a physics model — from
[q, q̇, central-difference q̈], else the chain's own prediction. Not a hybrid's whole
prediction: its residual forest is piecewise constant in q, and a filter would be credited
with smoothing the forest's steps). All four are fitted together (whole-sample lags refined
to a fraction of a sample, f_c on a log grid refined between neighbours, "no filter"
included): a first-order filter at f_c delays slow motion by 1/(2π f_c), so fitted one after
the other the delay would take the filter's share. With a filter the delay is at least −1
sample: a filter's attenuation combined with a lead of the wrench would otherwise stand in
for a gain error of the model's prediction in motion; and a filter is kept only when it
explains more than ``FILTER_MIN_GAIN`` of the misfit a delay alone leaves. What
:func:`decompose` reports per axis, as shares of the in-motion mean square of r (they add up
to 1):

* ``offset``, ``drift``: what removing a, then b·(t − t̄), removes;
* ``delay``, ``filter``: what correcting the fitted delay and filter removes after the drift,
  split between the two by their Shapley values (each one's average gain over the two
  orders; for slow motion the split goes as d : 1/(2π f_c));
* ``remainder``: what is left — the model's error and the sensor noise.

A share can be negative: the delay and the filter are fitted to all six axes together (and
the offset and drift with them), so correcting them can make one axis's residual larger while
the others' shrink; each axis's shares still add up to 1. A negative delay means the wrench
stream leads the joint states (or a model error that follows the motion's rate reads as a
lead). :meth:`ResidualBudget.notes` says so in the report.

Delay and filter are told apart only when the motion has content near f_c; for slower motion
the fit can trade one for the other (the sum of their shares is then still right). A model
error that follows the wrench's rate (e.g. a payload model fitted on too little motion) also
reads as a delay; the budget explains the log with the model it is given.

Units: wrenches N, N·m; RMS values in those units and in units of the resting noise (σ).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter

from .. import conventions as col
from ..compensation.calibration.joint_offsets import kinematics_budget
from ..compensation.estimators.physics import PhysicsPayloadCompensator
from ..config import ChainConfig
from ..data.robot_log import resample_uniform
from ..errors import LogError, spelled
from .replay import chain_config_of, read_replay_log, replay

SHARES = ("offset", "drift", "delay", "filter", "remainder")
#: Joint speed (rad/s) at or below which every joint counts as at rest.
REST_SPEED = 0.01
#: A filter is fitted only when it lowers the best delay-alone misfit by more than this
#: fraction: slow motion cannot tell a filter from a delay (its group delay) and a gain
#: error of the model (its attenuation), and the simpler explanation is reported.
FILTER_MIN_GAIN = 0.05
#: Rows at rest needed to measure the resting noise from the log itself.
MIN_REST_ROWS = 200
#: How far (relative) a time step may stray from the median step for the log to count as
#: uniformly sampled: the delay and the filter are fitted in whole and fractional samples.
UNIFORM_RTOL = 0.05


@dc.dataclass(frozen=True)
class ResidualBudget:
    """The in-motion residual of a log and its parts (module docstring); (6,) arrays per
    axis in :data:`ftdrake.WRENCH_AXES` order."""

    noise_std: np.ndarray  # the resting noise (N, N·m)
    noise_source: str  # "rest rows" (measured in the log) or "sensor config"
    motion_rms: np.ndarray  # RMS of r in motion (N, N·m)
    remainder_rms: np.ndarray  # RMS of what is left after drift, delay and filter
    shares: dict  # name in SHARES → (6,) share of the in-motion mean square
    drift_per_s: np.ndarray  # the fitted slope b (N/s, N·m/s)
    delay_s: float  # the fitted stream delay d (s; > 0: the wrench lags)
    filter_cutoff_hz: float  # the fitted first-order cut-off (inf: no filter found)
    rows: dict  # {"motion": n, "rest": n}
    #: What joint zero offsets explain of the refitted payload model's in-motion residual
    #: (:func:`~ftdrake.compensation.calibration.joint_offsets.kinematics_budget`), apart from
    #: the shares; None for a model without a physics part.
    kinematics: dict | None = None

    @property
    def motion_over_noise(self) -> np.ndarray:
        """In-motion RMS in units of the resting noise."""
        return self.motion_rms / self.noise_std

    @property
    def remainder_over_noise(self) -> np.ndarray:
        """What is left, in units of the resting noise."""
        return self.remainder_rms / self.noise_std

    def notes(self) -> list[str]:
        """What negative shares or a negative delay in this budget mean, one sentence each
        (none when nothing is negative)."""
        said = []
        low = [f"{name} {a} {round(float(v), 3):g}" for name in SHARES
               for a, v in zip(col.WRENCH_AXES, self.shares[name], strict=True)
               if round(float(v), 3) < 0]
        if low:
            said.append(
                f"negative shares ({', '.join(low)}): correcting that part made that axis's "
                "in-motion residual larger, not smaller — the delay and the filter are fitted "
                "to all six axes together (the offset and drift along with them), so an axis "
                "can lose what the others gain; each axis's shares still add up to 1, and one "
                "near 0 of either sign is within the fit's scatter")
        if self.delay_s < 0:
            said.append(
                f"delay_s {self.delay_s * 1e3:.3g} ms is negative: the wrench stream leads the "
                "joint states (delay_s > 0 when the wrench lags), or the model's error follows "
                "the motion's rate and reads as a lead")
        return said

    def as_dict(self) -> dict:
        """Plain numbers per axis (for JSON reports), and the :meth:`notes` on what negative
        values mean."""
        def axes(values, digits=4):
            return dict(zip(col.WRENCH_AXES, (np.round(np.asarray(values, float), digits)
                                              + 0.0).tolist(), strict=True))  # no −0.0
        return {"noise_std": axes(self.noise_std, 5), "noise_source": self.noise_source,
                "motion_rms": axes(self.motion_rms, 5),
                "motion_over_noise": axes(self.motion_over_noise, 2),
                "shares": {name: axes(v, 3) for name, v in self.shares.items()},
                "remainder_rms": axes(self.remainder_rms, 5),
                "remainder_over_noise": axes(self.remainder_over_noise, 2),
                "drift_per_s": axes(self.drift_per_s, 6), "delay_s": self.delay_s,
                "filter_cutoff_hz": (None if not np.isfinite(self.filter_cutoff_hz)
                                     else round(self.filter_cutoff_hz, 2)),
                "rows": self.rows, "notes": self.notes(),
                **({} if self.kinematics is None else {"kinematics": self.kinematics})}


def residual_budget(model, log, config: ChainConfig | None = None, *,
                    pairing: str = "row", noise_std=None, rest_speed: float = REST_SPEED,
                    max_lag_s: float = 0.05, result: pd.DataFrame | None = None,
                    resample: bool = False, joint_offsets: bool = True,
                    **replay_options) -> ResidualBudget:
    """Replays `log` through the runtime chain of `model` and splits its in-motion residual
    (module docstring).

    `log`, `config`, `pairing` and `replay_options`: as :func:`ftdrake.replay` (one log, the
    columns ``t``, ``q_i``, ``qd_i``, ``meas_*``). `noise_std`: the resting noise (6 values,
    N, N·m); default: the wrench's spread on the log's rows at rest (every joint at or below
    `rest_speed` rad/s; each still stretch's own mean removed) when it has at least
    ``MIN_REST_ROWS`` of them, else the chain config sensor's ``sqrt(noise_std² +
    resolution²/12)``. `max_lag_s`: the largest delay tried either way (s). `result`: the
    replay of `log` when it was run already (``ftdrake replay --budget``). The log must be
    sampled uniformly (:func:`check_uniform_sampling`, checked before the replay); `resample`
    puts it on a uniform grid first (:func:`~ftdrake.data.robot_log.resample_uniform`; a
    given `result` must then be the replay of the resampled log).
    `joint_offsets`: also the ``kinematics`` line, for a model with a physics part
    (:func:`~ftdrake.compensation.calibration.joint_offsets.kinematics_budget`).
    """
    frame = log if isinstance(log, pd.DataFrame) else read_replay_log(log)
    if resample:
        frame = resample_uniform(frame)
    check_uniform_sampling(frame[col.TIME].to_numpy(float))  # before the replay, which is long
    config = chain_config_of(frame, config)
    if result is None:
        result = replay(model, frame, config, pairing=pairing, **replay_options)
    n = int(model.n_joints_)
    speed = np.abs(frame[col.joint_columns(col.QD, n)].to_numpy(float)).max(axis=1)
    moving = speed > rest_speed
    t = result[col.TIME].to_numpy(float)
    settle = t >= t[0] + 0.1  # s: the chain's acceleration filter and detector settle first
    noise, source = _resting_noise(frame, ~moving & settle, noise_std, config)
    motion = moving & settle
    if motion.sum() < 100:
        raise LogError(f"residual_budget: {int(motion.sum())} rows in motion (a joint faster "
                       f"than {rest_speed} rad/s); the budget needs a log of the arm moving")
    transform = model.reading_to_model_frame() if hasattr(model, "reading_to_model_frame") \
        else None
    predicted = _motion_prediction(model, frame)
    if predicted is None:
        predicted = result[col.wrench_columns(col.WRENCH_INTERNAL)].to_numpy(float)
    budget = decompose(result[col.wrench_columns(col.WRENCH_CONTACT)].to_numpy(float),
                       predicted, t, motion, noise, transform=transform,
                       max_lag_s=max_lag_s)
    X = _physics_rows(model, frame)
    kinematics = None if X is None or not joint_offsets else kinematics_budget(
        model, X[motion], frame[col.wrench_columns(col.MEASURED)].to_numpy(float)[motion])
    return dc.replace(budget, noise_source=source, kinematics=kinematics,
                      rows={"motion": int(motion.sum()), "rest": int((~moving & settle).sum())})


def check_uniform_sampling(t) -> None:
    """Raises LogError unless every time step of `t` (s) is within ``UNIFORM_RTOL`` of the
    median step: the message gives the steps' range, how many stray, and the fix (resample
    onto a uniform grid: ``--resample``, ``resample=True``)."""
    t = np.asarray(t, float)
    dt = np.diff(t)
    period = float(np.median(dt)) if len(dt) else float("nan")
    if len(dt) and period > 0 and np.all(np.abs(dt - period) <= UNIFORM_RTOL * period):
        return
    if not (len(dt) and period > 0 and np.all(dt > 0)):
        raise LogError("residual_budget: the log's time column must increase (one row per "
                       "sample; split a dataset by its trajectory column)")
    stray = int(np.count_nonzero(np.abs(dt - period) > UNIFORM_RTOL * period))
    raise LogError(
        f"residual_budget: the log is not sampled uniformly: {stray} of {len(dt)} time steps "
        f"are more than {UNIFORM_RTOL:.0%} off the median {period * 1e3:.4g} ms (steps "
        f"{dt.min() * 1e3:.4g}–{dt.max() * 1e3:.4g} ms); the delay and filter are fitted in "
        "samples of one period. Resample it onto a uniform grid at the median period: "
        + spelled("residual_budget(..., resample=True) or "
                  "ftdrake.data.robot_log.resample_uniform(frame)", "--resample"))


def decompose(residual, predicted, t, motion, noise_std, *, transform=None,
              max_lag_s: float = 0.05, cutoffs_hz=None) -> ResidualBudget:
    """The budget of :func:`residual_budget` on arrays: `residual` r and `predicted` P (N, 6)
    at times `t` (N,) s, uniformly sampled; `motion` (N,) the rows to explain; `noise_std`
    (6,) the resting noise; `transform` the (6, 6) T from the reading's frame to r's (None:
    the identity); `cutoffs_hz` the f_c grid (default: 24 values from 0.5 Hz to 0.45× the
    sample rate)."""
    r, P = np.asarray(residual, float), np.asarray(predicted, float)
    t, motion = np.asarray(t, float), np.asarray(motion, bool)
    check_uniform_sampling(t)
    period = float(np.median(np.diff(t)))
    max_lag = max(1, round(max_lag_s / period))
    rows = np.flatnonzero(motion)
    rows = rows[(rows >= max_lag) & (rows < len(t) - max_lag)]
    if cutoffs_hz is None:
        cutoffs_hz = np.geomspace(0.5, 0.45 / period, 24)
    T = np.eye(6) if transform is None else np.asarray(transform, float)
    weight = 1.0 / np.asarray(noise_std, float)

    # Drift, delay and filter fitted together: m = r + T·P is the reading (in r's frame) the
    # model should have predicted; d, f_c and per axis a, b minimise the noise-weighted misfit
    # of a + b·t + T·L_fc(P(t − d)) to it.
    m = r + P @ T.T
    # [1, t − t̄] with t̄ the rows' mean time: the offset and the slope apart.
    A = np.column_stack([np.ones(len(t)), t - t[rows].mean()])
    delay, cutoff = _fit_delay_and_filter(m, P, T, A, rows, max_lag, cutoffs_hz, period,
                                          weight)
    coef, *_ = np.linalg.lstsq(A[rows], (m - _filtered(_shifted(P, t, delay), cutoff, period)
                                         @ T.T)[rows], rcond=None)
    r1 = r - A @ coef
    m = r1 + P @ T.T

    def left(d, fc):
        """r1 with the delay d and the filter fc corrected (either may be 0 / inf: none)."""
        return m - _filtered(_shifted(P, t, d), fc, period) @ T.T

    total = _ms(r, rows)
    offset = _ms(r - coef[0], rows)
    after = {"0": _ms(r1, rows), "d": _ms(left(delay, np.inf), rows),
             "f": _ms(left(0.0, cutoff), rows), "df": _ms(left(delay, cutoff), rows)}
    shares = {"offset": (total - offset) / total, "drift": (offset - after["0"]) / total,
              "delay": 0.5 * ((after["0"] - after["d"]) + (after["f"] - after["df"])) / total,
              "filter": 0.5 * ((after["0"] - after["f"]) + (after["d"] - after["df"])) / total,
              "remainder": after["df"] / total}
    return ResidualBudget(
        noise_std=np.asarray(noise_std, float), noise_source="given",
        motion_rms=np.sqrt(total), remainder_rms=np.sqrt(after["df"]), shares=shares,
        drift_per_s=coef[1], delay_s=float(delay), filter_cutoff_hz=float(cutoff),
        rows={"motion": len(rows), "rest": int((~motion).sum())})


def _fit_delay_and_filter(m, P, T, A, rows, max_lag, cutoffs_hz, period, weight):
    """(d in s, f_c in Hz or inf) minimising Σ over `rows` of ‖w·(m − A·c − T·L_fc(P(t − d)))‖²
    with the best c (per axis; A = [1, t − t̄]): whole-sample lags for each f_c on the grid (and
    none), the best lag refined to a fraction of a sample and the best f_c between its grid
    neighbours, each by the parabola through the minimum and its neighbours (f_c in log).
    The search reads every k-th row (k: about 10,000 rows in all)."""
    rows = rows[::max(1, len(rows) // 10_000)]
    lags = np.arange(-max_lag, max_lag + 1)
    step = max(1, max_lag // 8)
    A = A[rows]
    project = np.linalg.pinv(A)  # c = project·e

    def misfit_at(model, lag):
        e = m[rows] - model[rows - lag]
        e -= A @ (project @ e)  # the drift's least-squares part removed
        return np.sum((e * weight) ** 2)

    def best_lag(fc):
        """(misfit, d in s) at `fc`: lags every `step` samples, then every sample around the
        best (the misfit is smooth in the lag)."""
        model = _filtered(P, fc, period) @ T.T
        # With a filter, no lead of the wrench stream (d ≥ −1 sample): a filter's attenuation
        # with a lead would stand in for a gain error of the model's prediction.
        usable = lags if not np.isfinite(fc) else lags[lags >= -1]
        coarse = usable[::step]
        i = int(np.argmin([misfit_at(model, lag) for lag in coarse]))
        fine = usable[(usable >= coarse[i] - step) & (usable <= coarse[i] + step)]
        misfit = np.array([misfit_at(model, lag) for lag in fine])
        i = int(np.argmin(misfit))
        offset, value = _vertex(misfit, i)
        return value, (fine[i] + offset) * period

    cutoffs = np.asarray(cutoffs_hz, float)
    fits = [best_lag(fc) for fc in cutoffs]
    i = int(np.argmin([f[0] for f in fits]))
    best = (*fits[i], cutoffs[i])
    if 0 < i < len(cutoffs) - 1:  # between the grid's neighbours, in log f_c
        found = minimize_scalar(lambda x: best_lag(np.exp(x))[0], method="bounded",
                                bounds=(np.log(cutoffs[i - 1]), np.log(cutoffs[i + 1])),
                                options={"xatol": 1e-3})
        refined = best_lag(np.exp(found.x))
        if refined[0] < best[0]:
            best = (*refined, float(np.exp(found.x)))
    none = best_lag(np.inf)
    if best[0] > (1.0 - FILTER_MIN_GAIN) * none[0]:
        best = (*none, np.inf)
    return best[1], best[2]


def _vertex(values, i):
    """(offset, value) of the minimum of the parabola through values[i − 1..i + 1]: the
    offset (−½..½) from i; (0, values[i]) at an end or where the three do not curve up."""
    if not 0 < i < len(values) - 1:
        return 0.0, float(values[i])
    a, b, c = values[i - 1:i + 2]
    curvature = a - 2 * b + c
    if not curvature > 0:
        return 0.0, float(b)
    offset = float(np.clip(0.5 * (a - c) / curvature, -0.5, 0.5))
    return offset, float(b - 0.5 * (a - c) * offset + 0.5 * curvature * offset ** 2)


def _shifted(P, t, delay_s):
    """P(t − d), linearly interpolated (held at the ends)."""
    if delay_s == 0:
        return P
    return np.column_stack([np.interp(t - delay_s, t, P[:, j]) for j in range(P.shape[1])])


def _filtered(P, cutoff_hz, period):
    """The first-order low-pass of the sensor model (y_k = y_{k−1} + α(x_k − y_{k−1}),
    α = 1 − exp(−2π f_c T), started at the first value); inf: P itself."""
    if not np.isfinite(cutoff_hz):
        return P
    alpha = 1.0 - np.exp(-2 * np.pi * cutoff_hz * period)
    y, _ = lfilter([alpha], [1.0, alpha - 1.0], P, axis=0, zi=(1.0 - alpha) * P[:1])
    return y


def _motion_prediction(model, frame):
    """The prediction of `model`'s physics part (a hybrid's ``physics_``, a physics model
    itself) from [q, q̇, central-difference q̈] (and the temperature), in the reading's frame;
    None for a model without one."""
    X = _physics_rows(model, frame)
    return None if X is None else np.asarray(getattr(model, "physics_", model).predict(X), float)


def _physics_rows(model, frame):
    """[q, q̇, central-difference q̈] (and the temperature) for `model`'s physics part; None
    for a model without one."""
    physics = getattr(model, "physics_", model)
    if not isinstance(physics, PhysicsPayloadCompensator):
        return None
    n = int(model.n_joints_)
    t = frame[col.TIME].to_numpy(float)
    qd = frame[col.joint_columns(col.QD, n)].to_numpy(float)
    blocks = [frame[col.joint_columns(col.Q, n)].to_numpy(float), qd,
              np.gradient(qd, t, axis=0)]
    if getattr(physics, "temperature_in_", False):
        blocks.append(frame[[col.TEMPERATURE]].to_numpy(float))
    return np.hstack(blocks)


def _ms(values, rows):
    return np.mean(values[rows] ** 2, axis=0)


def _resting_noise(frame, rest, noise_std, config):
    """(noise (6,), where it came from): given; the rest rows' spread; the sensor config."""
    if noise_std is not None:
        noise = np.asarray(noise_std, float).reshape(6)
        if not np.all(noise > 0):
            raise LogError(f"residual_budget: noise_std must be 6 positive values, got {noise}")
        return noise, "given"
    if rest.sum() >= MIN_REST_ROWS:
        reading = frame[col.wrench_columns(col.MEASURED)].to_numpy(float)[rest]
        stretch = np.cumsum(np.r_[1, np.diff(np.flatnonzero(rest)) > 1])
        centred = reading - pd.DataFrame(reading).groupby(stretch).transform("mean").to_numpy()
        return np.sqrt(np.mean(centred ** 2, axis=0)), "rest rows"
    spec = config.sensor.spec()
    noise = np.sqrt(np.asarray(spec.noise_std) ** 2 + np.asarray(spec.resolution) ** 2 / 12)
    return noise, "sensor config"
