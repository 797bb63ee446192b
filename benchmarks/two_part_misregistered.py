"""The two-part compensation learned from mis-registered tool measurements, registered back.

The tracker 1.5 m from the base, rotated 0.4 rad, its clock 21 ms ahead and 50 ppm fast,
registered by its fiducials (frame) and the path (clock); the contour scan rotated 0.3 rad
and offset by 54 mm, registered by its datum points. Runs the timed and contour methods on
the benchmark's hole and prints the radial RMS per iteration and on the new hole (mm).

    python benchmarks/two_part_misregistered.py [--iterations 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json

from ftdrake.config.contour import ContourScanConfig, TrackerConfig
from ftdrake.experiments.contour import ContourPlan, run_contour_experiment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=2)
    parser.add_argument("--out", default="out/two_part_misregistered")
    args = parser.parse_args()
    plan = dc.replace(
        ContourPlan(), iterations=args.iterations, methods=("timed", "contour"),
        tracker=TrackerConfig(frame_rotation_rad=[0.003, -0.002, 0.4],
                              frame_offset_m=[1.5, -0.4, 0.2], clock_offset_s=0.021,
                              clock_skew=5e-5),
        contour_scan=ContourScanConfig(frame_rotation_rad=0.3, frame_offset_m=[0.05, -0.02]))
    summary = run_contour_experiment(None, plan, args.out, progress=True)
    print(json.dumps({"task": {k: v["radial_rms_mm"] for k, v in summary["task"].items()},
                      "new": summary["generalisation"]}))


if __name__ == "__main__":
    main()
