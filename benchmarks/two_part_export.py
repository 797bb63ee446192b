"""The exported correction applied in simulation against the in-memory one, on the same holes.

Learns the two-part compensation (timed tool measurement) on the benchmark's hole for a few
iterations (:func:`ftdrake.experiments.contour.run_contour_experiment`, methods ``timed``
only), saves the model (one file), loads it, exports the reference correction along the
learned hole and along a new hole at the controller's rate (1 kHz CSV), and runs each hole:

* ``none``: no correction;
* ``in_memory``: the loaded model's reference and torque feedforward (what the experiment runs);
* ``csv_plus_ff``: the CSV's offsets as the reference offset, plus the torque feedforward;
* ``csv_only``: the CSV's offsets alone (a controller with no torque feedforward);
* ``in_memory_reference_only``: the model's reference alone, for the same comparison.

Prints the hole's radial RMS error (mm) per case and the largest difference between the
CSV's offsets and the in-memory reference's (rad). Writes the model and the CSVs to --out.

    python benchmarks/two_part_export.py [--iterations 2] [--out out/two_part_export]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import time
from pathlib import Path

import numpy as np

from ftdrake.config import ScenarioConfig
from ftdrake.experiments.contour import (
    ContourPlan,
    HoleRunner,
    contour_scenario,
    run_contour_experiment,
)
from ftdrake.experiments.reference_correction import corrected_reference
from ftdrake.experiments.two_part_model import TwoPartModel, export_reference_csv, offset_from_csv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/two_part_export"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    plan = dc.replace(ContourPlan(), iterations=args.iterations, methods=("timed",))
    model_file = args.out / "two_part.ftd"
    summary = run_contour_experiment(None, plan, args.out, progress=False, model_out=model_file)
    model = TwoPartModel.load(model_file)
    runner = HoleRunner(contour_scenario(ScenarioConfig()))
    result = {"learned": summary["task"]["timed"]["radial_rms_mm"],
              "model_bytes": model_file.stat().st_size}
    for name, hole in (("task", plan.hole), ("new", plan.new_hole)):
        task = runner.task(hole)
        csv = args.out / f"correction_{name}.csv"
        table = export_reference_csv(model, task.trajectory, 1000.0, csv)
        in_memory = model.reference(task.trajectory)
        from_csv = corrected_reference(task.trajectory, offset_from_csv(csv, model.n))
        t = table["time"].to_numpy()
        offsets = table[[f"offset_{j}" for j in range(model.n)]].to_numpy()
        exact = (in_memory.vector_values(t) - task.trajectory.vector_values(t)).T
        replayed = (from_csv.vector_values(t) - in_memory.vector_values(t)).T
        runs = {"none": runner.run(task),
                "in_memory": runner.run(task, in_memory, model.feedforward()),
                "csv_plus_ff": runner.run(task, from_csv, model.feedforward()),
                "csv_only": runner.run(task, from_csv, None),
                "in_memory_reference_only": runner.run(task, in_memory, None)}
        result[name] = {
            "radial_rms_mm": {k: v["radial_rms_mm"] for k, v in runs.items()},
            "csv_offset_vs_in_memory_max_rad": float(np.abs(offsets - exact).max()),
            "replayed_reference_vs_in_memory_max_rad": float(np.abs(replayed).max()),
            "offset_max_rad": float(np.abs(offsets).max()),
            "offset_std_max_rad": float(table.filter(like="offset_std").to_numpy().max()),
        }
        print(name, json.dumps(result[name], indent=1))
    result["wall_time_s"] = time.perf_counter() - start
    print(json.dumps(result))
    (args.out / "export.json").write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
