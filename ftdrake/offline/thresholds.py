"""Contact-detector thresholds from held-out free motion (the detector's calibration).

:func:`thresholds_for_false_positive_rate` sets them for a false-positive budget (a scenario's
``detector.false_positives_per_hour``) from a Gaussian model of the residual checked against
the data (the norm test, or with ``test="chi2"`` the χ² test's threshold on the residual
whitened by the model's std); :func:`thresholds_from_quantile` from a quantile of the
residual's norms. :func:`armed` selects the samples the detector judges, the only ones
thresholds may come from. :func:`detectable_force` is the force a detector's test needs at a
sample, given the model's std there. :func:`calibrate_thresholds` is the first with a robust
largest-residual term (``tail="robust"``), and returns the stretches it left out.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from scipy.stats import chi2

from ..config import DetectorConfig
from ..runtime.detector import chi2_threshold


def armed(times, arm_after_s: float = DetectorConfig.arm_after_s) -> np.ndarray:
    """The samples the detector judges: run time (s, from each run's start) ≥ `arm_after_s`.

    Thresholds come from these only: before it the detector is not armed, and the controller's
    start-up transient there (large q̈ in the first milliseconds of a simulated run) would
    otherwise set the largest-residual term of
    :func:`thresholds_for_false_positive_rate`."""
    return np.asarray(times, dtype=float) >= arm_after_s


#: The robust largest-residual term: the statistic's peak per window of this length (s;
#: shorter on a short log, so that there are :data:`ROBUST_MIN_WINDOWS`) ...
ROBUST_WINDOW_S = 1.0
ROBUST_MIN_WINDOWS = 10
#: ... and a window is an outlier when the log of its peak is more than this many robust
#: standard deviations (1.4826 × the median absolute deviation) above the median of them.
ROBUST_FENCE = 5.0
#: The tails :func:`calibrate_thresholds` takes: the largest residual over all rows, or over
#: the windows that are not outliers.
TAILS = ("max", "robust")


@dc.dataclass(frozen=True)
class Outlier:
    """A stretch the robust term left out, where the detector would fire on the very data
    that set its thresholds: the `statistic` (``chi2``: Σ (rᵢ/σᵢ)²; ``force``: ‖F‖ in N;
    ``torque``: ‖T‖ in N·m) above its `threshold` from `t_first` to `t_last` (s, on the times
    given), on `rows` rows, its `peak` at `t_peak`."""

    statistic: str
    t_first: float
    t_last: float
    rows: int
    peak: float
    t_peak: float
    threshold: float

    def as_dict(self) -> dict:
        """JSON-ready copy."""
        return dc.asdict(self)

    def text(self) -> str:
        """One line: when, how long, how large (and how many times the threshold)."""
        unit = {"force": " N", "torque": " N·m"}.get(self.statistic, "")
        return (f"{self.statistic} above its threshold {self.threshold:.4g}{unit} from t = "
                f"{self.t_first:.3f} s to {self.t_last:.3f} s ({self.rows} rows), peak "
                f"{self.peak:.4g}{unit} at {self.t_peak:.3f} s "
                f"({self.peak / self.threshold:.1f}× the threshold)")


def thresholds_for_false_positive_rate(
        residual, *, sample_rate_hz: float,
        false_positives_per_hour: float = DetectorConfig.false_positives_per_hour,
        std=None, test: str = "norm", **overrides) -> DetectorConfig:
    """Detector thresholds for a target false-positive rate, from held-out free motion.

    `residual` (N × 6) is measured − predicted wrench on contact-free data the model was not
    trained on, sampled at `sample_rate_hz`. The thresholds come from a Gaussian model of
    that residual, checked against the data itself:

    * Per axis the residual is taken as zero-mean Gaussian with the held-out RMS s_i as its
      standard deviation (model error plus sensor noise). ‖F‖ is then at most s_max·χ₃
      (χ with 3 degrees of freedom), with s_max the largest force-axis RMS; likewise ‖T‖.
    * A budget of R false positives per hour is a per-sample probability
      p = R / (3600·f_s) for each of force and torque (half each). Debouncing
      (``debounce_on`` consecutive samples) is not counted as a further reduction: at 1 kHz a
      model's error is smooth, so one exceeding sample is usually followed by more.
    * force_on = max(s_max·√(χ²₃ quantile at 1 − p/2), 1.05 × the largest ‖F‖ seen on the
      held-out data); torque_on likewise. The second term keeps heavy tails (where the
      motion leaves the training data) from firing on the very data that set the thresholds.

    The smallest contact force it then detects is about force_on plus the residual at that
    moment; ``ftdrake.sim.evaluation`` measures it. The budget is a scenario's
    ``detector.false_positives_per_hour``; the returned config records it. `overrides` set
    the other fields.

    ``test="chi2"`` (with `std`, N × 6, the model's predictive std on those rows): the χ²
    test's threshold instead, :func:`chi2_on_for_false_positive_rate`; force_on and
    torque_on are then the norm test's, kept for a switch back. ``test="auto"``: the χ²
    test when `std` is given, else the norm test; the returned config names the test used.
    """
    return calibrate_thresholds(residual, sample_rate_hz=sample_rate_hz,
                                false_positives_per_hour=false_positives_per_hour, std=std,
                                test=test, tail="max", **overrides)[0]


def calibrate_thresholds(
        residual, *, sample_rate_hz: float,
        false_positives_per_hour: float = DetectorConfig.false_positives_per_hour,
        std=None, test: str = "norm", tail: str = "robust", times=None,
        **overrides) -> tuple[DetectorConfig, list[Outlier]]:
    """:func:`thresholds_for_false_positive_rate` with a choice of its largest-residual term;
    returns ``(the detector config, the outliers left out)``.

    ``tail="max"``: the largest residual over all rows (what that function does: a single
    start transient then sets the threshold). ``tail="robust"``: the rows are cut into
    windows of :data:`ROBUST_WINDOW_S` (shorter on a short log: at least
    :data:`ROBUST_MIN_WINDOWS` of them) by `times` (s, one per row; default: row k at
    k / `sample_rate_hz`); a window whose peak of the test's statistic lies more than
    :data:`ROBUST_FENCE` robust standard deviations above the median of the windows' peaks
    (on a log scale) is an outlier, and the term (and the RMS of the Gaussian term) come from
    the other windows. Heavy tails spread over the motion raise many windows' peaks, and with
    them the fence; a transient in a few windows does not. The outliers returned are the
    stretches of the left-out windows where the statistic passes the threshold set (there the
    detector would fire on this data); none with ``tail="max"``.
    """
    r, test, times = _checked(residual, sample_rate_hz, false_positives_per_hour, std, test,
                              tail, times)
    kept = (np.ones(len(r), bool) if tail == "max"
            else _robust_rows(r, std, times, test, sample_rate_hz))
    outliers = []
    if test == "chi2":
        chi2_on = chi2_on_for_false_positive_rate(
            r, std, sample_rate_hz=sample_rate_hz,
            false_positives_per_hour=false_positives_per_hour, rows=kept)
        overrides = {**overrides, "test": "chi2", "chi2_on": chi2_on}
        outliers = _stretches("chi2", _chi2(r, std), times, chi2_on, kept)
    else:
        overrides = {**overrides, "test": "norm"}
    p = false_positives_per_hour / (3600.0 * sample_rate_hz) / 2.0
    k = float(np.sqrt(chi2.isf(p, 3)))
    rms = np.sqrt(np.mean(r[kept] ** 2, axis=0))  # the outliers left out of the RMS too
    thresholds = []
    for name, block in (("force", slice(0, 3)), ("torque", slice(3, 6))):
        norms = np.linalg.norm(r[:, block], axis=1)
        gaussian = k * rms[block].max()
        observed = 1.05 * norms[kept].max()
        thresholds.append(float(max(gaussian, observed)))
        if test == "norm":
            outliers += _stretches(name, norms, times, thresholds[-1], kept)
    return DetectorConfig(force_on=thresholds[0], torque_on=thresholds[1],
                          false_positives_per_hour=false_positives_per_hour,
                          **overrides).validate(), outliers


def _checked(residual, sample_rate_hz, false_positives_per_hour, std, test, tail, times):
    """(the residual as an array, the test resolved, the times); ValueErrors name what is
    wrong."""
    if tail not in TAILS:
        raise ValueError(f"tail must be one of {TAILS}; got {tail!r}")
    r = np.asarray(residual, dtype=float)
    if r.ndim != 2 or r.shape[1] != 6 or len(r) < 100:
        raise ValueError(f"residual must be N × 6 with N >= 100; got shape {r.shape}")
    if not np.isfinite(r).all():
        raise ValueError("residual holds NaN or infinity; drop those rows first")
    if not (false_positives_per_hour > 0 and sample_rate_hz > 0):
        raise ValueError("false_positives_per_hour and sample_rate_hz must be positive")
    if test == "auto":  # as the chain resolves it: χ² when there is a std of a reading
        test = "chi2" if std is not None else "norm"
    if test not in ("norm", "chi2"):
        raise ValueError(f"test must be 'auto', 'norm' or 'chi2'; got {test!r}")
    times = (np.arange(len(r)) / sample_rate_hz if times is None
             else np.asarray(times, dtype=float).reshape(-1))
    if len(times) != len(r):
        raise ValueError(f"times has {len(times)} values for {len(r)} rows")
    return r, test, times


def _chi2(r: np.ndarray, std) -> np.ndarray:
    return np.sum((r / np.asarray(std, dtype=float)) ** 2, axis=1)


def _robust_rows(r, std, times, test: str, sample_rate_hz: float) -> np.ndarray:
    """(N,) bool: the rows of the windows that are not outliers (see calibrate_thresholds),
    judged on the test's statistics (χ²; or ‖F‖ and ‖T‖, a window out when either is)."""
    chi2_ok = test == "chi2" and std is not None and np.shape(std) == r.shape
    stats = ([_chi2(r, std)] if chi2_ok
             else [np.linalg.norm(r[:, :3], axis=1), np.linalg.norm(r[:, 3:], axis=1)])
    span = float(times[-1] - times[0]) + 1.0 / sample_rate_hz
    window = min(ROBUST_WINDOW_S, span / ROBUST_MIN_WINDOWS)
    label = np.floor((times - times[0]) / window).astype(int)
    windows = np.unique(label)
    kept = np.ones(len(r), bool)
    if len(windows) < ROBUST_MIN_WINDOWS:
        return kept
    for stat in stats:
        peaks = np.log(np.maximum([stat[label == w].max() for w in windows], 1e-300))
        median = np.median(peaks)
        spread = 1.4826 * np.median(np.abs(peaks - median))
        out = windows[peaks > median + ROBUST_FENCE * max(spread, 1e-3)]
        kept &= ~np.isin(label, out)
    return kept


def _stretches(name: str, stat, times, threshold: float, kept) -> list[Outlier]:
    """Per run of left-out rows (not `kept`), the stretch where `stat` exceeds
    `threshold` (none when it stays below)."""
    over = (~kept) & (stat > threshold)
    found = []
    edges = np.flatnonzero(np.diff(np.r_[0, (~kept).astype(int), 0]))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        rows = np.flatnonzero(over[start:stop]) + start
        if len(rows):
            peak = rows[np.argmax(stat[rows])]
            found.append(Outlier(name, float(times[rows[0]]), float(times[rows[-1]]),
                                 len(rows), float(stat[peak]), float(times[peak]),
                                 float(threshold)))
    return found


def chi2_on_for_false_positive_rate(residual, std, *, sample_rate_hz: float,
                                    false_positives_per_hour: float, rows=None) -> float:
    """The χ² test's threshold from held-out free motion: max(the χ²₆ quantile at 1 − p,
    1.05 × the largest Σ (rᵢ/σᵢ)² seen on it), p = false_positives_per_hour /
    (3600 · sample_rate_hz) (one test: the budget is not split). `residual`, `std`: N × 6,
    measured − predicted and the model's predictive std on the same rows. The second term, as
    in the norm test, keeps the rows where the std did not grow enough (the model is unsure
    there and does not say so) from firing on the very data that set the threshold. `rows`:
    a bool mask of the rows that largest value is taken over (None: all)."""
    r = np.asarray(residual, dtype=float)
    s = None if std is None else np.asarray(std, dtype=float)
    if s is None or s.shape != r.shape:
        raise ValueError("the χ² test needs the model's std on the residual's rows (N × 6, "
                         f"std=...); got {None if s is None else s.shape} for {r.shape}")
    if not (np.isfinite(s).all() and (s > 0).all()):
        raise ValueError("std holds values that are not positive and finite: the χ² test "
                         "needs a model with a predictive std (physics, hybrid, GP)")
    quantile = chi2_threshold(DetectorConfig(
        false_positives_per_hour=false_positives_per_hour), 1.0 / sample_rate_hz)
    stat = np.sum((r / s) ** 2, axis=1)
    return float(max(quantile, 1.05 * np.max(stat if rows is None else stat[rows])))


def detectable_force(detector: DetectorConfig, std, period: float) -> np.ndarray:
    """(N,) the smallest contact force (N) the detector's test reports at each sample, given
    the model's std there (`std` N × 6, N, N·m; `period` the sample period, s): along the
    least favourable force axis, on a zero residual. χ² test: √chi2_on · max(σ_Fx, σ_Fy,
    σ_Fz); norm test: force_on + std_gain · ‖σ_F‖."""
    detector = detector.without_model()
    s = np.atleast_2d(np.asarray(std, dtype=float))
    if detector.test == "chi2":
        return np.sqrt(chi2_threshold(detector, period)) * s[:, :3].max(axis=1)
    return detector.force_on + detector.std_gain * np.linalg.norm(s[:, :3], axis=1)


def thresholds_from_quantile(residual, margin: float = 1.5, quantile: float = 0.999,
                             **overrides) -> DetectorConfig:
    """Thresholds from free-motion residuals (N × 6: measured − predicted wrench on held-out
    contact-free data): `margin` × the `quantile` of ‖F‖ and ‖T‖, floored at 0.5 N and
    0.02 N·m. A quantile, not k·RMS: a learned model's residuals are heavy-tailed (largest
    where the motion leaves the training data). `overrides` set the other fields."""
    r = np.asarray(residual, dtype=float)
    if r.ndim != 2 or r.shape[1] != 6 or len(r) < 100:
        raise ValueError(f"residual must be N × 6 with N >= 100; got shape {r.shape}")
    force = np.quantile(np.linalg.norm(r[:, :3], axis=1), quantile)
    torque = np.quantile(np.linalg.norm(r[:, 3:], axis=1), quantile)
    return DetectorConfig(force_on=max(0.5, margin * force),
                          torque_on=max(0.02, margin * torque),
                          **{"test": "norm", **overrides}).validate()


def threshold_text(detector: dict) -> str:
    """A detector record's threshold in words: the χ² test's on the whitened wrench, or the
    norm test's force and torque."""
    if detector.get("test") == "chi2":
        return f"χ² > {detector['chi2_on']:.1f}"
    return f"{detector['force_on']:.2f} N, {detector['torque_on']:.3f} N·m"
