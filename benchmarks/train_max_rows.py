"""Training on a long 1 kHz log: wall time and held-out accuracy of ``train --max-rows``
against the fit on every row, for the physics and the hybrid model.

Simulates a Fourier log of `--minutes` at 1 kHz (the training log) and a 20 s one of another
seed (held out), then trains (:func:`ftdrake.train`, as ``ftdrake train`` does; no tuning
grid) on all rows and with ``max_rows`` (default 20 000), in one process, and prints the
wall times and the held-out RMS error per force axis with its ratio to the full fit's.

    python benchmarks/train_max_rows.py [--minutes 3] [--max-rows 20000] [--models physics,hybrid]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

import ftdrake


def simulated(minutes: float, seed: int, path: Path) -> object:
    scenario = ftdrake.ScenarioConfig()
    scenario.trajectory.kind, scenario.trajectory.duration_s = "fourier", 60.0 * minutes
    scenario.trajectory.seed = scenario.sensor.seed = seed
    log = ftdrake.simulate(ftdrake.build_station(scenario.validate()), progress=False).log
    ftdrake.save_dataset(log, path)
    return log


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--max-rows", type=int, default=20_000)
    parser.add_argument("--models", default="physics,hybrid")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="ftdrake_train_bench_"))
    simulated(args.minutes, 11, folder / "train.parquet")
    held_out = simulated(20.0 / 60.0, 12, folder / "held_out.parquet")
    X, Y = ftdrake.joint_state_layout(held_out), ftdrake.wrench_targets(held_out)
    rows, load = [], os.getloadavg()[0]
    for kind in args.models.split(","):
        result = {}
        for way, max_rows in (("all rows", None), ("max rows", args.max_rows)):
            out = folder / f"{kind}_{way.replace(' ', '_')}.ftd"
            start = time.perf_counter()
            trained = ftdrake.train(folder / "train.parquet", kind=kind, robot="ftdrake",
                                    preset="none", max_rows=max_rows)
            trained.save(out)
            wall = time.perf_counter() - start
            model = trained.model
            rms = np.sqrt(np.mean((Y - model.predict(X)) ** 2, axis=0))
            result[way] = {"wall_s": round(wall, 1), "rms_F": np.round(rms[:3], 4).tolist(),
                           "size_mb": round(out.stat().st_size / 1e6, 2)}
        ratio = (np.array(result["max rows"]["rms_F"]) / np.array(result["all rows"]["rms_F"]))
        rows.append({"model": kind, **result, "rms_ratio": np.round(ratio, 3).tolist()})
    n = int(60_000 * args.minutes)
    print(f"training log: {args.minutes:g} min at 1 kHz ({n} rows); --max-rows {args.max_rows}")
    print("| model | rows | wall time | held-out RMS Fx, Fy, Fz (N) | ratio to all rows |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        for way in ("all rows", "max rows"):
            ratio = "" if way == "all rows" else ", ".join(f"{x:.3f}" for x in r["rms_ratio"])
            print(f"| {r['model']} | {way} | {r[way]['wall_s']:.1f} s | "
                  f"{', '.join(f'{x:.3f}' for x in r[way]['rms_F'])} | {ratio} |")
    print(json.dumps({"benchmark": "train_max_rows", "minutes": args.minutes, "rows": n,
                      "max_rows": args.max_rows, "results": rows, "cpus": os.cpu_count(),
                      "load_before": round(load, 2), "machine": platform.platform()}))


if __name__ == "__main__":
    main()
