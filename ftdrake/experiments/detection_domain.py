"""The detectable force against how far out of domain the arm is, in the detection evaluation.

A detector whose threshold follows the model's std (``detector.test: chi2``) needs more force
to fire where the model is unsure — out of the training data's domain — and less where it
is sure; the norm test's threshold is one force everywhere. For each free-motion sample of
the evaluation (every :data:`STRIDE`-th judged sample) :func:`free_motion_samples` takes
the model's distance d to its training inputs (``domain_distance``, in training stds) and
the std the chain gave the detector there; :func:`detectable_force_vs_domain` turns them
into the force each test needs
(:func:`~ftdrake.offline.thresholds.detectable_force`: on a zero residual, along the least
favourable force axis) per distance bin of
:data:`~ftdrake.compensation.estimators.domain.DISTANCE_BINS` and as a curve (equal-count bins of d:
median and 5–95 % band), and :func:`plot_detectable_force_vs_domain` draws the curves.
Only models with a support (the hybrid) have a d.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import conventions as col
from ..compensation.estimators.domain import DISTANCE_BINS
from ..config import DetectorConfig
from ..data.dataset import joint_state_layout
from ..offline.thresholds import armed, detectable_force
from ..plots import plt

#: Every k-th judged free-motion sample (10 ms at 1 kHz: the std changes slowly).
STRIDE = 10
#: Points of the curve (equal-count bins of d).
CURVE_BINS = 16
TESTS = ("chi2", "norm")


def has_domain(model) -> bool:
    """Whether `model` reports a distance to its training inputs (a hybrid)."""
    return callable(getattr(model, "domain_distance", None))


def free_motion_samples(model, log: pd.DataFrame, replayed: pd.DataFrame,
                        arm_after_s: float) -> dict | None:
    """{"d": (n,), "std": (n, 6)} at every :data:`STRIDE`-th sample the detector judges in a
    free-motion run: d of the log's joint state ([q, q̇, q̈] as estimated in the log) and the
    chain's std (``wrench_std_*`` of the replay, N, N·m). None for a model without a support."""
    if not has_domain(model):
        return None
    judged = np.flatnonzero(armed(log[col.TIME].to_numpy(), arm_after_s))[::STRIDE]
    X = joint_state_layout(log, n=int(model.n_joints_))[judged]
    std = replayed[col.wrench_columns(col.WRENCH_STD)].to_numpy(dtype=float)[judged]
    return {"d": model.domain_distance(X), "std": std}


def _spread(force: np.ndarray) -> dict:
    return {"median_n": float(np.median(force)), "p5_n": float(np.quantile(force, 0.05)),
            "p95_n": float(np.quantile(force, 0.95))}


def detectable_force_vs_domain(samples: list[dict], detectors: dict[str, DetectorConfig],
                               period: float) -> dict:
    """Per test of `detectors` ("chi2", "norm": the thresholds calibrated for the model):
    the detectable force (N) in each distance bin (``bins``: samples, median d, median and
    5–95 % of the force) and along d (``curve``: :data:`CURVE_BINS` equal-count bins), from
    :func:`free_motion_samples`' `samples` of one model; `period` the sample period (s)."""
    d = np.concatenate([s["d"] for s in samples])
    std = np.vstack([s["std"] for s in samples])
    edges = np.unique(np.quantile(d, np.linspace(0.0, 1.0, CURVE_BINS + 1)))
    which = np.clip(np.searchsorted(edges, d, side="right") - 1, 0, max(len(edges) - 2, 0))
    out = {"samples": len(d), "stride": STRIDE}
    for test, detector in detectors.items():
        force = detectable_force(detector, std, period)
        bins = {}
        for name, (lo, hi) in DISTANCE_BINS.items():
            rows = (d >= lo) & (d < hi)
            bins[name] = {"distance": [lo, hi if np.isfinite(hi) else None],
                          "samples": int(rows.sum()),
                          "median_distance": float(np.median(d[rows])) if rows.any() else None,
                          **(_spread(force[rows]) if rows.any() else {})}
        curve = [{"distance": float(np.median(d[which == k])), **_spread(force[which == k])}
                 for k in range(len(edges) - 1) if (which == k).any()]
        out[test] = {"bins": bins, "curve": curve}
    return out


def distinct(results: dict) -> dict:
    """{name: entry} of the results with a ``detectable_force_vs_domain`` entry, each entry
    once: a model evaluated with both tests (``--compare-tests``) has the same entry twice,
    named after the model alone."""
    out = {}
    for name, r in results.items():
        entry = r.get("detectable_force_vs_domain")
        if not entry:
            continue
        twin = next((k for k, v in out.items() if v == entry), None)
        if twin is None:
            out[name] = entry
        else:
            out = {(_model_name(k) if k == twin else k): v for k, v in out.items()}
    return out


def _model_name(name: str) -> str:
    """"hybrid (chi2)" → "hybrid": the model of a result named "model (test)"."""
    for test in TESTS:
        if name.endswith(f" ({test})"):
            return name[:-len(test) - 3]
    return name


def plot_detectable_force_vs_domain(results: dict, path: Path) -> bool:
    """The figure of :func:`detectable_force_figure` saved to `path`; False (nothing drawn)
    when no model of `results` has a ``detectable_force_vs_domain`` entry."""
    fig = detectable_force_figure(results)
    if fig is None:
        return False
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def plain_log_ticks(axis) -> None:
    """Labels a log-scale `axis` in plain numbers (0.2, 0.5, 1, 2) rather than powers of ten
    at every minor tick (``3×10⁻¹`` beside ``4×10⁻¹`` overlap): on an axis spanning a decade
    or more, minor ticks are labelled at 2 and 5 × a power of ten only."""
    from matplotlib.ticker import FuncFormatter  # noqa: PLC0415 (with matplotlib's import)

    low, high = sorted(axis.get_view_interval())
    wide = high / low >= 10

    def label(value, _position):
        leading = round(value / 10 ** np.floor(np.log10(value) + 1e-9), 6)
        return f"{value:g}" if not wide or leading in (1.0, 2.0, 5.0) else ""

    axis.set_major_formatter(FuncFormatter(label))
    axis.set_minor_formatter(FuncFormatter(label))


def detectable_force_figure(results: dict):
    """The detectable force against d, a line (median) and band (5–95 %) per model and test,
    from the ``detectable_force_vs_domain`` entries of `results` (model name → result), as a
    matplotlib Figure; None when no model has one."""
    entries = distinct(results)
    if not entries:
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, (name, entry) in enumerate(entries.items()):
        for test, style in zip(TESTS, ("-", "--"), strict=True):
            if test not in entry:
                continue
            curve = entry[test]["curve"]
            x = [c["distance"] for c in curve]
            color = f"C{2 * k + (test == 'norm')}"
            ax.plot(x, [c["median_n"] for c in curve], style, color=color,
                    label=f"{name}, {'χ² test' if test == 'chi2' else 'norm test'}")
            ax.fill_between(x, [c["p5_n"] for c in curve], [c["p95_n"] for c in curve],
                            color=color, alpha=0.2, lw=0)
    for lo, _ in DISTANCE_BINS.values():
        if lo > 0:
            ax.axvline(lo, color="0.6", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("distance to the training inputs d [training stds]")
    ax.set_ylabel("detectable force [N]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("force a contact needs to be detected, free motion (median, 5–95 %)")
    plain_log_ticks(ax.xaxis)
    plain_log_ticks(ax.yaxis)
    fig.tight_layout()
    return fig


def markdown(results: dict) -> str:
    """The table of the detectable force per distance bin (empty without any)."""
    lines = []
    for name, entry in distinct(results).items():
        if not lines:
            heads = " | ".join(f"{b.replace('_', ' ')} ({_range(lo, hi)})"
                               for b, (lo, hi) in DISTANCE_BINS.items())
            lines = ["", ("Detectable force in free motion by distance d to the training "
                          "inputs (median [5–95 %]; share of samples):"), "",
                     f"| model | test | {heads} |",
                     "| --- | --- |" + " --- |" * len(DISTANCE_BINS)]
        for test in TESTS:
            bins = entry[test]["bins"]
            cells = " | ".join(
                f"{b['median_n']:.2f} N [{b['p5_n']:.2f}–{b['p95_n']:.2f}]; "
                f"{b['samples'] / entry['samples']:.0%}" if b["samples"] else "–"
                for b in bins.values())
            lines.append(f"| {name} | {test} | {cells} |")
    return "\n".join(lines) + ("\n" if lines else "")


def _range(lo: float, hi: float) -> str:
    return f"d ≥ {lo:g}" if not np.isfinite(hi) else f"{lo:g} ≤ d < {hi:g}"
