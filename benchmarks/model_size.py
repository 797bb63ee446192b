"""The demo's hybrid model file: its size and its held-out accuracy, for residual forests of
different sizes.

Collects the demo's training data (``ftdrake.experiments.demo``: Fourier runs, rehearsals,
one run of each other kind; every 4th row, as the demo trains) and held-out runs of the same
kinds with other seeds, trains the demo's hybrid (payload model with mounting and cable
weight + residual forest) with each residual below, saves it with ``save_model`` and reports
the file size and the held-out RMS error per axis in units of the sensor's noise σ
(``sqrt(noise_std² + resolution²/12)`` of the scenario's sensor).

    python benchmarks/model_size.py [--fourier 4] [--rehearsals 3] [--duration 20]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

import ftdrake
from ftdrake.compensation.estimators.physics import ExcitationWarning
from ftdrake.experiments.demo import OTHER_KINDS

EVERY = 4
#: The residual forests: (trees, min_samples_leaf); None: the library's default_residual.
RESIDUALS = (None, (50, 5), (50, 20), (50, 40), (25, 20))


def data(config, fourier, rehearsals, duration):
    """(training rows, held-out runs): the demo's kinds of free motion."""
    runs = [ftdrake.collect(config, fourier, kind="fourier", duration=duration, progress=False),
            ftdrake.collect(config, rehearsals, kind="rehearsal", seed=100, progress=False)]
    runs += [ftdrake.collect(config, 1, kind=kind, seed=200 + i, duration=duration,
                             progress=False) for i, kind in enumerate(OTHER_KINDS)]
    train = pd.concat(runs, ignore_index=True)
    held_out = pd.concat(
        [ftdrake.collect(config, 1, kind=kind, seed=300 + i, duration=duration, progress=False)
         for i, kind in enumerate(("fourier", *OTHER_KINDS))]
        + [ftdrake.collect(config, 1, kind="rehearsal", seed=310, progress=False)],
        ignore_index=True)
    return train.iloc[::EVERY], held_out


def hybrid(residual):
    physics = ftdrake.PhysicsPayloadCompensator(identify_mounting=True,
                                                weight_without_inertia=True)
    if residual is None:
        return ftdrake.HybridCompensator(physics=physics)
    trees, leaf = residual
    forest = ftdrake.RandomForestCompensator(features="q", per_output=False, random_state=0,
                                             n_estimators=trees, min_samples_leaf=leaf)
    return ftdrake.HybridCompensator(physics=physics, residual=forest)


def measure(model, X_test, Y_test, sigma, folder: Path, name: str) -> dict:
    path = ftdrake.save_model(model, folder / f"{name}.ftd", target_names=ftdrake.WRENCH_AXES,
                              target_units=ftdrake.WRENCH_UNITS)
    started = time.perf_counter()
    ftdrake.load_model(path)
    load_s = time.perf_counter() - started
    rms = np.sqrt(np.mean((Y_test - model.predict(X_test)) ** 2, axis=0)) / sigma
    forest = model.residual_.forests_[0]
    return {"file_MB": round(path.stat().st_size / 1e6, 3),
            "nodes": int(sum(tree.tree_.node_count for tree in forest.estimators_)),
            "load_s": round(load_s, 2),
            "held_out_rms_over_sigma": dict(zip(ftdrake.WRENCH_AXES, rms.round(3).tolist(),
                                                strict=True))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fourier", type=int, default=4)
    parser.add_argument("--rehearsals", type=int, default=3)
    parser.add_argument("--duration", type=float, default=20.0)
    args = parser.parse_args()
    config = ftdrake.ScenarioConfig()
    spec = config.sensor.spec()
    sigma = np.sqrt(np.asarray(spec.noise_std) ** 2 + np.asarray(spec.resolution) ** 2 / 12)
    train, held_out = data(config, args.fourier, args.rehearsals, args.duration)
    X, Y = ftdrake.joint_state_layout(train), ftdrake.wrench_targets(train)
    X_test, Y_test = ftdrake.joint_state_layout(held_out), ftdrake.wrench_targets(held_out)
    result = {"training_rows": len(X), "held_out_rows": len(X_test),
              "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
              "models": {}}
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        folder = Path(tmp)
        for i, residual in enumerate(RESIDUALS):
            name = "default" if residual is None else f"{residual[0]} trees, leaf {residual[1]}"
            started = time.perf_counter()
            model = hybrid(residual).fit(X, Y)
            fit_s = time.perf_counter() - started
            entry = measure(model, X_test, Y_test, sigma, folder, f"m{i}")
            entry["fit_s"] = round(fit_s, 1)
            result["models"][name] = entry
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
