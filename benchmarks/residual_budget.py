"""What the in-motion residual of the demo's sensor is made of, with a real log's stream
effects on, and how far it is from the goal (within 2× the resting noise).

The demo's arm and sensor (the default scenario: ATI Gamma preset, 400 Hz first-order filter,
random-walk and thermal drift) with the wrench stream lagging the joint states by
`--delay-ms` (``sensor.stream_delay_s``). The demo's hybrid (payload model with mounting and
cable weight + residual forest) is trained on Fourier runs and rehearsals collected with the
same sensor, then each held-out run (a Fourier run and a rehearsal, whose stops give rest
rows) is replayed through the whole chain (bias tracker included) and split by
:func:`ftdrake.offline.residual_budget.residual_budget`. Three models:

* ``as_logged``: trained on the log as it is (the delay not corrected);
* ``aligned``: the delay estimated on the training data and corrected (training rows
  aligned, the chain's delay line applying ``wrench_delay_s_``);
* ``no_delay``: the same sensor without the stream delay (the reference).

Prints one JSON document: per model and held-out run, per axis the in-motion RMS and what is
left over the resting noise (measured on the run's rest rows), the shares, the fitted delay
and filter cut-off.

    python benchmarks/residual_budget.py [--delay-ms 10] [--fourier 4] [--duration 20]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import os
import platform
import time
import warnings

import numpy as np
import pandas as pd

import ftdrake
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.data.stream_delay import delay_between, shift_wrench
from ftdrake.offline.residual_budget import residual_budget

EVERY = 4  # the demo trains on every 4th row of its 1 kHz logs


def logs(config, fourier, duration, rehearsals):
    """Training runs (Fourier and rehearsals) and two held-out runs."""
    train = pd.concat([
        ftdrake.collect(config, fourier, kind="fourier", duration=duration, progress=False),
        ftdrake.collect(config, rehearsals, kind="rehearsal", seed=100, progress=False)
        .assign(trajectory=lambda f: f["trajectory"] + fourier)], ignore_index=True)
    held_out = {
        "fourier": ftdrake.collect(config, 1, kind="fourier", seed=300, duration=duration,
                                   progress=False),
        "rehearsal": ftdrake.collect(config, 1, kind="rehearsal", seed=310, progress=False)}
    return train, held_out


def hybrid():
    return ftdrake.HybridCompensator(physics=ftdrake.PhysicsPayloadCompensator(
        identify_mounting=True, weight_without_inertia=True))


def fit(train, wrench_delay_s=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return hybrid().fit(ftdrake.joint_state_layout(train)[::EVERY],
                            ftdrake.wrench_targets(train)[::EVERY],
                            wrench_delay_s=wrench_delay_s)


def fit_aligned(train, model):
    """The delay of the training runs' wrench behind their joint states, with `model`'s
    physics part (fitted on them as they are; not the whole hybrid, whose forest fitted on
    these rows learnt their delayed reading), corrected; the model refitted on the aligned
    runs."""
    rows = train.iloc[::EVERY]
    estimate = delay_between(ftdrake.wrench_targets(rows),
                             model.physics_.predict(ftdrake.joint_state_layout(rows)),
                             rows["t"].to_numpy(), rows["trajectory"].to_numpy())
    aligned = pd.concat([shift_wrench(run, estimate.delay_s)
                         for _, run in train.groupby("trajectory")], ignore_index=True)
    return fit(aligned, wrench_delay_s=estimate.delay_s), estimate


def budgets(model, held_out):
    out = {}
    for name, run in held_out.items():
        log = run.drop(columns="trajectory")
        log.attrs = run.attrs
        budget = residual_budget(model, log).as_dict()
        out[name] = {k: budget[k] for k in (
            "motion_over_noise", "remainder_over_noise", "shares", "delay_s",
            "filter_cutoff_hz", "noise_std", "noise_source", "rows")}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delay-ms", type=float, default=10.0)
    parser.add_argument("--fourier", type=int, default=4)
    parser.add_argument("--rehearsals", type=int, default=2)
    parser.add_argument("--duration", type=float, default=20.0)
    args = parser.parse_args()
    started = time.perf_counter()
    reference = ftdrake.ScenarioConfig()
    delayed = dc.replace(reference, sensor=dc.replace(reference.sensor,
                                                      stream_delay_s=args.delay_ms / 1e3))
    result = {"delay_ms": args.delay_ms, "fourier": args.fourier,
              "rehearsals": args.rehearsals, "duration_s": args.duration,
              "machine": {"cpus": os.cpu_count(), "python": platform.python_version()}}
    train, held_out = logs(delayed, args.fourier, args.duration, args.rehearsals)
    result["training_rows"] = len(train) // EVERY
    as_logged = fit(train)
    aligned, estimate = fit_aligned(train, as_logged)
    result["training_delay_estimate"] = estimate.as_dict()
    result["training_delay_estimate_whole_hybrid_s"] = delay_between(
        ftdrake.wrench_targets(train.iloc[::EVERY]),
        as_logged.predict(ftdrake.joint_state_layout(train.iloc[::EVERY])),
        train["t"].to_numpy()[::EVERY], train["trajectory"].to_numpy()[::EVERY]).delay_s
    result["as_logged"] = budgets(as_logged, held_out)
    result["aligned"] = budgets(aligned, held_out)
    train0, held_out0 = logs(reference, args.fourier, args.duration, args.rehearsals)
    result["no_delay"] = budgets(fit(train0), held_out0)
    result["wall_s"] = round(time.perf_counter() - started, 1)
    print(json.dumps(result, indent=1, default=lambda v: np.asarray(v).tolist()))


if __name__ == "__main__":
    main()
