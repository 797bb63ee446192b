"""Per-control-step cost of the two-part compensation's two corrections, each with its std.

Part one (the torque feedforward, ``LearnedFeedforward.evaluate_one``) and part two (the
motor-reference correction, ``ReferenceCorrection.evaluate_one``): one GP per joint each
(m = 200 kept rows by farthest-point selection, inputs [q_d, q̇_d, q̈_d] of a 7-joint arm),
mean, std and the confidence rule in one compiled call each. Fitted on synthetic smooth
trajectories (a torque-like and a deflection-like target), timed one row per call on an unseen
stretch, as a 1 kHz loop would call them. In the hole-cutting experiment the reference
correction is evaluated ahead of the run on 100 Hz knots (the path is known in advance); its
cost per row is the same call. Medians in µs; on a shared machine only ratios travel.
Goal: ≤ 50 µs per step for both, with their std.

    python benchmarks/two_part_latency.py
"""

from __future__ import annotations

import json
import os
import platform

import numpy as np

from ftdrake.experiments.reference_correction import ReferenceCorrection
from ftdrake.systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp
from ftdrake.testing import median_us_per_row, sine_path

N_JOINTS = 7
RATE_HZ = 1000.0


def trajectory(seconds: float, seed: int) -> np.ndarray:
    """[q, q̇, q̈] (N × 21) of a sum of sines per joint, sampled at 1 kHz."""
    return sine_path(seconds, seed, RATE_HZ, N_JOINTS)


def main() -> None:
    X = trajectory(14.0, seed=0)
    q, qd, qdd = np.split(X, 3, axis=1)
    torque = 2 * np.sin(q) + 0.5 * np.tanh(qd / 0.3) + 0.2 * qdd  # N·m
    deflection = 1e-4 * np.cos(q) + 2e-5 * qdd  # rad: a gravity- and inertia-like twist
    rows = trajectory(2.0, seed=0)[::2] + 0.01  # near, not on, the training trajectory
    part_one = LearnedFeedforward(fit_feedforward_gp(X, torque, max_points=200,
                                                     optimize_points=200))
    part_two = ReferenceCorrection(fit_feedforward_gp(X, deflection, max_points=200,
                                                      optimize_points=200))
    # The fused calls equal the batch evaluation (mean, std and rule).
    c, s, k = part_two.evaluate(rows[:50])
    fused = np.array([part_two.evaluate_one(x).copy() for x in rows[:50]])
    assert np.allclose(fused, np.hstack([c, s, k]), rtol=1e-9, atol=1e-12)
    out1, out2 = np.empty(3 * N_JOINTS), np.empty(3 * N_JOINTS)
    one = median_us_per_row(lambda x: part_one.evaluate_one(x, out1), rows)
    two = median_us_per_row(lambda x: part_two.evaluate_one(x, out2), rows)

    def both(x):
        part_one.evaluate_one(x, out1)
        part_two.evaluate_one(x, out2)

    total = median_us_per_row(both, rows)
    print(f"{'part one (torque)':>24} {one:8.1f} µs/step")
    print(f"{'part two (reference)':>24} {two:8.1f} µs/step")
    print(f"{'both':>24} {total:8.1f} µs/step (goal ≤ 50 µs: "
          f"{'met' if total <= 50 else 'NOT met'})")
    print(json.dumps({
        "benchmark": "two_part_latency", "n_joints": N_JOINTS, "inputs": 3 * N_JOINTS,
        "max_points": 200, "part_one_us": one, "part_two_us": two, "both_us": total,
        "goal_us": 50.0, "met": total <= 50.0,
        "cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
        "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
