"""Per-control-step latency of the learned feedforward: mean, std and confidence of 7 GPs.

Fits ``fit_feedforward_gp`` (one GP per joint, m = 200 kept rows by farthest-point selection,
inputs [q_d, q̇_d, q̈_d] of a 7-joint arm: 21 features → 7 torques) on synthetic smooth joint
trajectories, then times one row per call, as the 1 kHz loop calls it:

* ours: ``LearnedFeedforward.evaluate_one`` — one numba call for the GPs' mean and std and
  the confidence rule (what the system's cache entry runs each step),
* compiled GP + numpy rule: ``CompiledGaussianProcess.predict_one_with_std`` (its input
  checks) and the rule in numpy,
* the model's own ``predict`` + ``predict_std`` on a 1 × 21 array (scikit-learn style).

Rows are consecutive 1 kHz samples of an unseen stretch of trajectory. Medians in µs; on a
shared machine only the ratios travel. Also m = 100 and 400 for the cost's growth (O(n·m²)
for the std). Goal: ≤ 50 µs per step with the std.

    python benchmarks/feedforward_latency.py
"""

from __future__ import annotations

import json
import os
import platform

import numpy as np

from ftdrake.systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp
from ftdrake.testing import median_us_per_row, sine_path

N_JOINTS = 7
RATE_HZ = 1000.0


def trajectory(seconds: float, seed: int) -> np.ndarray:
    """[q, q̇, q̈] (N × 21) of a sum of sines per joint, sampled at 1 kHz."""
    return sine_path(seconds, seed, RATE_HZ, N_JOINTS)


def torque(X: np.ndarray) -> np.ndarray:
    """A smooth stand-in for a model error: gravity-like, friction-like and inertia-like."""
    q, qd, qdd = np.split(X, 3, axis=1)
    return 2 * np.sin(q) + 0.5 * np.tanh(qd / 0.3) + 0.2 * qdd


def main() -> None:
    X = trajectory(14.0, seed=0)
    rows = trajectory(2.0, seed=0)[::2] + 0.01  # near, not on, the training trajectory
    results = {}
    print(f"{'m':>5} {'ours (fused)':>14} {'compiled + numpy':>17} {'predict+std':>12}  µs/row")
    for m in (100, 200, 400):
        model = fit_feedforward_gp(X, torque(X), max_points=m, optimize_points=200)
        ff = LearnedFeedforward(model)
        out = np.empty(3 * N_JOINTS)
        gp = ff._gp
        # The fused call equals the model's own mean, std and rule.
        c, s, k = ff.evaluate(rows[:50])
        ref_mean, ref_std = model.predict(rows[:50]), model.predict_std(rows[:50])
        assert np.allclose(s, ref_std, rtol=1e-6, atol=1e-9)
        fused = np.array([ff.evaluate_one(x).copy() for x in rows[:50]])
        assert np.allclose(fused[:, :N_JOINTS], c, rtol=1e-9, atol=1e-9)
        assert np.allclose(c, k * ref_mean, rtol=1e-6, atol=1e-9)

        def compiled(x, gp=gp, ff=ff):
            mean, std = gp.predict_one_with_std(x)
            return ff._confidence(std) * mean

        def sklearn_style(x, model=model):
            x = x[None, :]
            return model.predict(x), model.predict_std(x)

        ours = median_us_per_row(lambda x, ff=ff, out=out: ff.evaluate_one(x, out), rows)
        comp = median_us_per_row(compiled, rows)
        slow = median_us_per_row(sklearn_style, rows[:300], repeat=1)
        results[m] = {"ours_us": ours, "compiled_numpy_us": comp, "predict_std_us": slow}
        print(f"{m:>5} {ours:>14.1f} {comp:>17.1f} {slow:>12.1f}")
    default = results[200]
    print(f"default m = 200: {default['ours_us']:.1f} µs per step with std "
          f"(goal ≤ 50 µs: {'met' if default['ours_us'] <= 50 else 'NOT met'}); "
          f"{default['predict_std_us'] / default['ours_us']:.0f}× faster than predict + "
          "predict_std")
    print(json.dumps({
        "benchmark": "feedforward_latency", "n_joints": N_JOINTS, "inputs": 3 * N_JOINTS,
        "results_us": results, "goal_us": 50.0, "met": default["ours_us"] <= 50.0,
        "cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
        "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
