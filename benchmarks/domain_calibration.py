"""How the hybrid's out-of-domain std is calibrated, measured on the demo's free-motion data.

Collects the demo's training runs and held-out runs (``ftdrake demo``'s collection, its
default sizes), fits the demo's hybrid five ways — not calibrated (fitted alone: σ²_in from
the cross-fit, g = 0), and calibrated with a growth per axis or one shared by the axes, with
the in-domain level σ²_in kept from the cross-fit (``in_domain="cross_fit"``, c = 1) or
fitted on the held-out runs with the parameters' scale c (``"held_out"``; with the shared
growth, one multiple of each axis' training error); each calibrated on
the training runs farthest from the others and refitted on every run
(``DomainCalibratedHybrid``) — and prints, for each, 95 % coverage per
axis on the judged samples of the held-out runs by distance to the training inputs (the
demo's bins), the calibrated terms, and the force the χ² test needs there (√chi2_on · the
largest force-axis std, median over the bin's samples, with chi2_on calibrated on those same
samples for the scenario's budget, as the demo does).

    python benchmarks/domain_calibration.py            # ~4 min on 2 cores

One run, one machine: the coverage depends on which runs are held out, and the timings vary
2–3× on a shared machine.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from ftdrake.compensation.estimators.domain import DISTANCE_BINS
from ftdrake.compensation.estimators.domain_calibrated import DomainCalibratedHybrid
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.config import ScenarioConfig
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.experiments import demo
from ftdrake.offline.thresholds import chi2_on_for_false_positive_rate

AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")


def demo_data(config):
    """(X, Y, run labels) of the demo's training rows (every 4th, as it trains) and (X, Y)
    of the judged samples of its held-out runs."""
    data, held_out = demo._collect_free_motion(
        config, 4, 3, 20.0, demo.OTHER_KINDS, False, demo.TASK_COVERING_RUNS, False)
    validation_id = 4 + 3 - 1  # as run_demo: the last rehearsal is held out
    train = data[data["trajectory"] != validation_id]
    validation = data[data["trajectory"] == validation_id]
    every = 4
    X, Y = joint_state_layout(train)[::every], wrench_targets(train)[::every]
    groups = train["trajectory"].to_numpy()[::every]
    return (X, Y, groups), demo.held_out_rows(config, validation, held_out)


#: (name, shared_growth, in_domain); None: fitted alone, not calibrated.
VARIANTS = (("not calibrated", None, None),
            ("shared growth, σ_in from the cross-fit", True, "cross_fit"),
            ("growth per axis, σ_in from the cross-fit", False, "cross_fit"),
            ("growth per axis, σ_in and c from the held-out runs", False, "held_out"),
            ("shared growth and σ_in multiple, c, from the held-out runs (the demo)", True,
             "held_out"))


def fitted(shared_growth, in_domain, X, Y, groups):
    model = demo.demo_hybrid()
    started = time.perf_counter()
    if in_domain is None:
        model.fit(X, Y)
    else:
        model = DomainCalibratedHybrid(model, holdout=demo.DOMAIN_HOLDOUT_SHARE,
                                       shared_growth=shared_growth,
                                       in_domain=in_domain).fit(X, Y, groups=groups)
    return model, time.perf_counter() - started


def report(name, model, seconds, X_h, Y_h, config):
    bins = demo.domain_coverage(model, X_h, Y_h)
    std = model.predict_std(X_h)
    chi2_on = chi2_on_for_false_positive_rate(
        Y_h - model.predict(X_h), std, sample_rate_hz=config.sensor.spec().rate_hz,
        false_positives_per_hour=config.chain.detector.false_positives_per_hour)
    d = model.domain_distance(X_h)
    print(f"\n## {name} (fit {seconds:.0f} s)")
    length = model.domain_length_
    print(f"ℓ = {length:.3g}, c = {model._parameter_scale():.3g}; σ_in "
          + " ".join(f"{v:.3g}" for v in np.sqrt(model._noise_var()))
          + "; g " + " ".join(f"{v:.3g}" for v in model.domain_growth_)
          + f"; chi2_on {chi2_on:.1f}")
    print("| bin | samples | 95 % coverage " + " ".join(AXES) + " | min–max | χ² needs (N) |")
    for key, (lo, hi) in DISTANCE_BINS.items():
        b = bins[key]
        if not b["rows"]:
            continue
        rows = (d >= lo) & (d < hi)
        needs = np.sqrt(chi2_on) * np.median(std[rows, :3].max(axis=1))
        c = np.asarray(b["coverage_95"])
        print(f"| {key} | {b['rows']} | " + " ".join(f"{v:.3f}" for v in c)
              + f" | {c.min():.3f}–{c.max():.3f} | {needs:.2f} |")


def main():
    config = ScenarioConfig()
    started = time.perf_counter()
    (X, Y, groups), (X_h, Y_h) = demo_data(config)
    print(f"collected {len(X)} training rows, {len(X_h)} held-out samples in "
          f"{time.perf_counter() - started:.0f} s")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        for name, shared_growth, in_domain in VARIANTS:
            report(name, *fitted(shared_growth, in_domain, X, Y, groups), X_h, Y_h, config)


if __name__ == "__main__":
    main()
