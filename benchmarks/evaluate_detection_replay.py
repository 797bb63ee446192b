"""Wall time of the detection evaluation by replay against the same evaluation in the loop.

The same plan for two models (a forest and the hybrid, each trained on a little simulated
data first, not timed), run both ways in one process: by replay (each run simulated once,
both models' chains replayed over it; the default of ``ftdrake evaluate-detection``) and in
the loop (``--in-loop``: every run simulated once per model). The results are checked equal;
the table gives the wall times and their ratio, the JSON line the same with the machine.

    python benchmarks/evaluate_detection_replay.py [--minutes 1] [--jobs 2] [--repeats 1]
        [--replay-only]

``--replay-only`` times the replay alone (for the issue's goal of 10 simulated minutes of two
models in ≤ 6 minutes, where the loop's way would take about three times as long).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings

import numpy as np

from ftdrake import HybridCompensator, RandomForestCompensator, ScenarioConfig
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.experiments.detection import DetectionPlan, run_plan
from ftdrake.experiments.detection_replay import run_plan_by_replay
from ftdrake.sim.collection import collect


def models():
    data = collect(ScenarioConfig(), 2, kind="fourier", duration=8.0, progress=False)
    X, Y = joint_state_layout(data)[::4], wrench_targets(data)[::4]
    forest = RandomForestCompensator(features="q", n_estimators=30, per_output=False,
                                     random_state=0).fit(X, Y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hybrid = HybridCompensator(physics=PhysicsPayloadCompensator()).fit(X, Y)
    return {"forest": forest, "hybrid": hybrid}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=1.0,
                        help="simulated minutes of free motion (default 1)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1,
                        help="interleaved repeats of both ways (medians; default 1)")
    parser.add_argument("--replay-only", action="store_true",
                        help="time the replay alone (no in-loop comparison)")
    args = parser.parse_args()
    plan = DetectionPlan(free_minutes=args.minutes, kinds=("fourier", "random"),
                         depths_mm=(1.0, 12.0), surfaces=("table",), rehearsals=1,
                         calibration_runs_per_kind=0, events=None)
    named = models()
    config = ScenarioConfig()
    load = os.getloadavg()[0]
    ways = [("replay", run_plan_by_replay)] + ([] if args.replay_only
                                                else [("in the loop", run_plan)])
    walls, results = {way: [] for way, _ in ways}, {}
    for _ in range(args.repeats):  # interleaved: a shared machine's load hits both alike
        for way, run in ways:
            start = time.perf_counter()
            results[way] = run(named, config, plan, n_jobs=args.jobs, progress=False)
            walls[way].append(time.perf_counter() - start)
    times = {way: float(np.median(w)) for way, w in walls.items()}
    for name in named:
        for key in ("replayed_runs", "closed_loop_runs"):
            results["replay"][name].pop(key)
    same = results["replay"] == results["in the loop"] if not args.replay_only else None
    simulated_s = sum(r["free_motion_s"] + 14.0 * r["press_count"]
                      for r in results["replay"].values())
    ratio = times["in the loop"] / times["replay"] if not args.replay_only else None
    print(f"{len(named)} models, {args.minutes:g} min free motion + "
          f"{len(plan.depths_mm)} presses each, {args.jobs} jobs")
    print("| way | wall time | simulated per model |")
    print("| --- | --- | --- |")
    for way, seconds in times.items():
        print(f"| {way} | {seconds:.1f} s | {simulated_s / len(named):.0f} s |")
    if ratio is not None:
        print(f"ratio (in the loop / replay): {ratio:.2f}x; same results: {same}")
    print(json.dumps({
        "benchmark": "evaluate_detection_replay", "models": list(named),
        "free_minutes": args.minutes, "presses": len(plan.depths_mm), "jobs": args.jobs,
        "wall_s": {k: round(v, 2) for k, v in times.items()}, "repeats": args.repeats,
        "ratio": None if ratio is None else round(ratio, 3),
        "same_results": same, "cpus": os.cpu_count(), "load_before": round(load, 2),
        "machine": platform.platform(), "python": platform.python_version()}))


if __name__ == "__main__":
    main()
