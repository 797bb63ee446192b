"""The study's claims (a)-(e), and ftdrake's own (f), checked against the numbers.

Each check returns a :class:`Finding`: whether the claim holds on the judged dataset, and the
numbers that decide it and that the report quotes. No prose here: the claims' wording, the
evidence and the likely reasons are chosen from these numbers in :mod:`.report`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from .layout import AXES, DATASETS, FEATURES

# Claims (b) and (d): thresholds, stated once.
UNCHANGED_VS = 0.05  # "unchanged": variance score moves by less than this on every axis
Q_SHARE = 0.8  # "concentrated on q": the q block holds at least this share of importance
#: The black-box methods the study compares.
BLACK_BOXES = ("rf", "svr", "svr_scaled")


@dataclass(frozen=True)
class Finding:
    """One claim checked: ``id`` (a-f), ``source`` (``"study"`` or ``"ftdrake"``), the dataset
    it is judged on, whether it holds, and the numbers (JSON-ready) behind the verdict."""

    id: str
    source: str
    dataset: str
    reproduced: bool
    numbers: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, record: dict) -> Finding:
        """From :meth:`as_dict` or a results.json record (extra keys, e.g. prose, ignored)."""
        return cls(record["id"], record["source"], record["dataset"],
                   bool(record["reproduced"]), record["numbers"])


def check_findings(results: dict) -> list[Finding]:
    """Every claim, in order a-f, checked against `results` (as :func:`~.run.run_study`
    builds them: metrics, cv_disagreement, wrench_stats, feature_importances, tool_tip,
    warnings, settings)."""
    return [check(results) for check in (claim_a, claim_b, claim_c, claim_d, claim_e,
                                          claim_f)]


def _metric(results, dataset, method, features, metric) -> np.ndarray:
    cell = results["metrics"][dataset][method][features]
    return np.array([cell[a][metric] for a in AXES], dtype=float)


def _study(id_, ok, numbers, source="study") -> Finding:
    return Finding(id_, source, "reference", bool(ok), numbers)


def _rf_wins(results, d, svr="svr") -> tuple[int, list[dict]]:
    """Cells (axis × feature set) where RF's test MSE is below `svr`'s, and the others."""
    wins, losses = 0, []
    for f in FEATURES:
        rf, other = (_metric(results, d, m, f, "mse") for m in ("rf", svr))
        wins += int(np.sum(rf < other))
        losses += [{"axis": a, "features": f, "rf_mse": float(r), "svr_mse": float(v)}
                   for a, r, v in zip(AXES, rf, other, strict=True) if r >= v]
    return wins, losses


def claim_a(results) -> Finding:
    """(a) RF has a lower test MSE than SVR on every axis (and feature set)."""
    wins = {d: _rf_wins(results, d)[0] for d in DATASETS}
    scaled = {d: _rf_wins(results, d, "svr_scaled")[0] for d in DATASETS}
    total = len(FEATURES) * len(AXES)
    stats, eps = results["wrench_stats"]["reference"], results["settings"]["svr_epsilon"]
    return _study("a", wins["reference"] == total, {
        "rf_wins": wins, "rf_wins_vs_scaled_svr": scaled, "cells": total,
        "svr_wins_reference": _rf_wins(results, "reference")[1],
        "shuffled_test_over_cv":
            results["cv_disagreement"]["reference"]["shuffled"]["median_test_over_cv"],
        "svr_epsilon": eps,
        # Axes whose whole signal is narrower than SVR's ε-tube (in N or N·m).
        "narrow_axes_std": {a: stats[a]["std"] for a in AXES if stats[a]["std"] < eps},
    })


def claim_b(results) -> Finding:
    """(b) RF is ~unchanged when q̇, q̈ are added, SVR changes."""
    def change(d, m):
        delta = (_metric(results, d, m, "q,qd,qdd", "variance_score")
                 - _metric(results, d, m, "q", "variance_score"))
        j = int(np.argmax(np.abs(delta)))
        return float(delta[j]), AXES[j]

    numbers = {d: {m: change(d, m)[0] for m in ("rf", "svr")} for d in DATASETS}
    axis = {d: {m: change(d, m)[1] for m in ("rf", "svr")} for d in DATASETS}
    rf_unchanged = abs(numbers["reference"]["rf"]) < UNCHANGED_VS
    svr_changed = abs(numbers["reference"]["svr"]) >= UNCHANGED_VS
    return _study("b", rf_unchanged and svr_changed, {
        "largest_change": numbers, "threshold": UNCHANGED_VS, "largest_change_axis": axis,
        "rf_unchanged": rf_unchanged, "svr_changed": svr_changed})


def _mean_nmse(results, d) -> np.ndarray:
    return np.mean([_metric(results, d, m, f, "nmse") for m in ("rf", "svr")
                    for f in FEATURES], axis=0)


def claim_c(results) -> Finding:
    """(c) Fz and Tz are the worst axes (mean NMSE of RF and SVR) on the reference motion."""
    nmse = _mean_nmse(results, "reference")
    order = [AXES[j] for j in np.argsort(-nmse)]
    stats = results["wrench_stats"]["reference"]
    sigma = dict(zip(AXES, results["settings"]["noise_std"], strict=True))
    physics = _metric(results, "reference", "physics", "q,qd,qdd", "nmse")
    return _study("c", set(order[:2]) == {"Fz", "Tz"}, {
        "mean_nmse": dict(zip(AXES, map(float, nmse), strict=True)),
        # σ²/var: the NMSE of a perfect model, whose only error is the sensor noise.
        "noise_floor_nmse": {a: sigma[a] ** 2 / stats[a]["std"] ** 2 for a in AXES},
        "worst_first": order,
        "physics_nmse": dict(zip(AXES, map(float, physics), strict=True))})


def claim_d(results) -> Finding:
    """(d) The RF Fx model relies on the joint positions q (their share of importance)."""
    imp = results["feature_importances"]
    share = {d: float(sum(v for k, v in imp[d]["q,qd,qdd"].items() if k.startswith("q_")))
             for d in DATASETS}
    full, q_only = imp["reference"]["q,qd,qdd"], imp["reference"]["q"]
    fx = {f: float(_metric(results, "reference", "rf", f, "nmse")[0]) for f in ("q", "q,qd,qdd")}
    return _study("d", share["reference"] >= Q_SHARE, {
        "q_share": share, "top3": sorted(full, key=full.get, reverse=True)[:3],
        "top3_q_only": sorted(q_only, key=q_only.get, reverse=True)[:3],
        "threshold": Q_SHARE, "rf_fx_nmse": fx})


def claim_e(results) -> Finding:
    """(e) More Z motion (z_rich) makes Fz and Tz easier to learn."""
    ref, rich = _mean_nmse(results, "reference"), _mean_nmse(results, "z_rich")
    z = [AXES.index("Fz"), AXES.index("Tz")]
    return _study("e", all(rich[j] < ref[j] for j in z), {
        "reference": {a: float(ref[j]) for a, j in zip(("Fz", "Tz"), z, strict=True)},
        "z_rich": {a: float(rich[j]) for a, j in zip(("Fz", "Tz"), z, strict=True)},
        "tool_tip_z_std_mm": {d: results["tool_tip"][d]["z"]["std"] * 1000
                              for d in DATASETS}})


def claim_f(results) -> Finding:
    """(f, ftdrake's) Physics + RF residual beats the best tuned RF or SVR on every axis."""
    better = {}
    for d in DATASETS:
        hybrid = _metric(results, d, "hybrid", "q,qd,qdd", "mse")
        best = np.min([_metric(results, d, m, f, "mse") for m in BLACK_BOXES
                       for f in FEATURES], axis=0)
        better[d] = {"axes": int(np.sum(hybrid < best)),
                     "median_ratio": float(np.median(best / hybrid))}
    warned = {d: len(results.get("warnings", {}).get(d, [])) for d in DATASETS}
    return _study("f", better["reference"]["axes"] == len(AXES),
                  {**better, "excitation_warnings": warned}, source="ftdrake")
