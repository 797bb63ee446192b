"""Does training on ``task_covering`` motion cut the false positives on the wall approaches?

Hybrids (the demo's: rigid payload with the mounting rotation and a weight carried without
inertia, forest residual), trained on the demo's data with one difference (``VARIANTS``): the
4 × 20 s runs of the default excitation (``fourier``), 4 × 20 s of ``task_covering`` instead
(the same seeds), or both (2 × 20 s of ``task_covering`` added); all also get 3 rehearsals
at the table and one 20 s run each of ``random``, ``z_rich`` and ``reference``. Then the
detection evaluation by replay (as
:func:`~ftdrake.experiments.detection_replay.run_plan_by_replay` runs it: thresholds from
held-out motion for the scenario's 1-per-hour budget, free motion of the four kinds, presses
on the table and the wall, on the evaluation's own seeds) on a short plan: each run
simulated once and every model's chain replayed over it, each with its own thresholds and
with the others' (a model that sets higher thresholds is quieter for that reason alone; the
cross terms separate the two). Prints per model and thresholds the false positives in free
motion and in the press runs per surface (the wall's are those of its approaches: outside
true contact), the presses missed and the smallest force detected; the JSON line has the
same and the physics fit's condition number and identified mass.

    nice -n 5 python benchmarks/excitation_detection.py [--minutes 4] [--jobs 2] [--variants …]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import itertools
import json
import time
import warnings

import pandas as pd
from joblib import Parallel, delayed

from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.config import ScenarioConfig, parse_config
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.experiments.detection import (
    DetectionPlan,
    _free_jobs,
    _press_jobs,
    held_out_motion,
    model_result,
    run_row,
    thresholds_from_held_out,
)
from ftdrake.offline.replay import replay
from ftdrake.offline.thresholds import threshold_text
from ftdrake.sim.collection import collect
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station

OTHER_KINDS = ("random", "z_rich", "reference")
DEPTHS_MM = (-0.6, 0.0, 0.3, 1.0, 3.0, 6.0, 12.0)


#: What replaces (or joins) the demo's 4 × 20 s Fourier runs: kind → runs of 20 s.
VARIANTS = {
    "fourier": {"fourier": 4},  # the demo's data
    "task_covering": {"task_covering": 4},
    "fourier + task_covering": {"fourier": 4, "task_covering": 2},
}


def training_data(config: ScenarioConfig, excitation: dict, jobs: int) -> pd.DataFrame:
    """The demo's training runs with the runs of `excitation` (kind → count) in place of its
    Fourier runs."""
    runs, next_id = [], 0
    for kind, count in excitation.items():
        run = collect(config, count, kind=kind, duration=20.0, n_jobs=jobs, progress=False)
        run["trajectory"] += next_id
        next_id += count
        runs.append(run)
    rehearsal = collect(config, 3, kind="rehearsal", seed=100, n_jobs=jobs, progress=False)
    rehearsal["trajectory"] += next_id
    runs.append(rehearsal)
    for i, kind in enumerate(OTHER_KINDS):
        run = collect(config, 1, kind=kind, seed=200 + i, duration=20.0, n_jobs=jobs,
                      progress=False)
        run["trajectory"] += next_id + 3 + i
        runs.append(run)
    return pd.concat(runs, ignore_index=True)


def fit(data: pd.DataFrame) -> HybridCompensator:
    X, Y = joint_state_layout(data)[::4], wrench_targets(data)[::4]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return HybridCompensator(physics=PhysicsPayloadCompensator(
            identify_mounting=True, weight_without_inertia=True)).fit(X, Y)


def run_job(config_yaml: str, meta: dict, models: dict, detectors: dict) -> dict:
    """One run of the plan, simulated once: {(model, thresholds' model): its row}."""
    config = parse_config(config_yaml)
    log = simulate(build_station(config), progress=False).log
    rows = {}
    for name, model in models.items():
        for owner, detector in detectors.items():
            tuned = config.with_chain(detector=detector)
            replayed = replay(model, log, tuned.chain_config(), pairing="simulated")
            rows[name, owner] = run_row(log, tuned, meta, replayed)
    return rows


def place(row: dict) -> str:
    return row["surface"] if row["kind"] == "contact" else "free motion"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=4.0,
                        help="simulated minutes of free motion in the evaluation")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS),
                        help="the training data to compare (each model's chain is replayed "
                             "with every model's thresholds)")
    args = parser.parse_args()
    config = ScenarioConfig()
    started = time.perf_counter()
    data = {name: training_data(config, VARIANTS[name], args.jobs) for name in args.variants}
    models = {name: fit(data[name]) for name in data}
    fits = {name: {"condition_number": float(m.physics_.condition_number_),
                   "tool_mass_kg": float(m.physics_.parameters_[0])}
            for name, m in models.items()}
    plan = DetectionPlan(free_minutes=args.minutes, depths_mm=DEPTHS_MM, events=None)
    held_out = held_out_motion(config, plan, args.jobs)
    detectors = {name: thresholds_from_held_out(m, config, plan, args.jobs, data=held_out)
                 for name, m in models.items()}
    # The evaluation's own runs and seeds (those of evaluate-detection's plan).
    jobs = _free_jobs(config, plan) + _press_jobs(config, plan)
    runs = Parallel(n_jobs=args.jobs)(delayed(run_job)(yaml_text, meta, models, detectors)
                                      for yaml_text, meta in jobs)
    summary = {}
    print("| trained on | thresholds from | thresholds | false positives: free motion | "
          "table press runs | wall press runs | presses missed | smallest force detected |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, owner in itertools.product(models, detectors):
        rows = [run[name, owner] for run in runs]
        result = model_result(detectors[owner], rows)
        counts = {}
        for row in rows:
            counts[place(row)] = counts.get(place(row), 0) + row["false_positives"]
        d, smallest = detectors[owner], result["smallest_reliably_detected_force_n"]
        print(f"| {name} | {owner} | {threshold_text(dc.asdict(d))} "
              f"| {counts.get('free motion', 0)} in {result['free_motion_s'] / 60:.1f} min "
              f"| {counts.get('table', 0)} | {counts.get('wall', 0)} "
              f"| {result['missed']} of {result['press_count']} "
              f"| {'–' if smallest is None else f'{smallest:.2f} N'} |")
        summary[f"{name} / thresholds of {owner}"] = {
            "false_positives": counts, "detector": dc.asdict(d),
            "missed": result["missed"], "press_count": result["press_count"],
            "smallest_reliably_detected_force_n": smallest}
    print(json.dumps({"plan_minutes": args.minutes, "depths_mm": DEPTHS_MM, "fits": fits,
                      "wall_s": round(time.perf_counter() - started, 1),
                      "results": summary}, default=float))


if __name__ == "__main__":
    main()
