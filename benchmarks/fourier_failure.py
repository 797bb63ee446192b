"""Why the learned torque feedforward can make tracking worse on a short Fourier task.

Runs the feedforward experiment's GP loop (``learn-feedforward --trajectory fourier
--duration 3``, rigid joints, friction on) and, per iteration, compares what the GP feeds
forward with the torque a perfect feedforward would add, computed from the true plant:
``τ* = [M q̈ + C q̇ − τ_g]_true − [M̂ q̈ + Ĉ q̇ − τ̂_g]_model + friction(q̇)`` at the desired
state (the cable's spring and weight are left out of τ*). Columns:

* tip_mm: the run's tool-tip RMS;
* need: RMS of τ* at the desired states (N·m, all joints);
* label_err: RMS of (training target − τ* at the *actual* state the row was logged at): how
  wrong the data the GP learns from are;
* fit_err: RMS of (GP mean − τ*) at the training rows' actual states;
* pred_err: RMS of (GP mean − τ*) at the desired states of the next run (before scaling);
* applied_err: RMS of (confidence · mean − τ*) there: what the next run actually gets;
* scaled: share of desired rows whose correction was scaled down;
* dist: median distance of desired rows to the nearest training row in the GP's metric.

``--plain-subset`` chooses the GP's data subset the way it was chosen before the subset moved
to the kernels' metric (farthest points in plain standardised units), to test whether that
choice was what made the GP fail on this task.

    python benchmarks/fourier_failure.py [--duration 3] [--iterations 5] [--plain-subset]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.spatial import cKDTree

from ftdrake.compensation.estimators.gpr import GPRCompensator
from ftdrake.config import ScenarioConfig
from ftdrake.experiments.feedforward import FeedforwardPlan, Tracker, task_scenario
from ftdrake.systems.friction import JointFriction
from ftdrake.systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp


def dynamics(plant, context, X, instance=None) -> np.ndarray:
    """M q̈ + C q̇ − τ_g per row of X = [q, q̇, q̈] (N·m)."""
    n = X.shape[1] // 3
    out = np.empty((len(X), n))
    for i, x in enumerate(X):
        if instance is None:
            plant.SetPositions(context, x[:n])
            plant.SetVelocities(context, x[n:2 * n])
        else:
            plant.SetPositions(context, instance, x[:n])
            plant.SetVelocities(context, instance, x[n:2 * n])
        out[i] = (plant.CalcMassMatrix(context) @ x[2 * n:] + plant.CalcBiasTerm(context)
                  - plant.CalcGravityGeneralizedForces(context))
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--iterations", type=int, default=5)
    parser.add_argument("--max-points", type=int, default=200)
    parser.add_argument("--plain-subset", action="store_true",
                        help="farthest points in standardised units, not the kernels' metric")
    args = parser.parse_args()
    if args.plain_subset:
        choose = GPRCompensator._choose_subset

        def plain(self, Z_metric, rng):  # undo the division by the length scales
            return choose(self, Z_metric * self.length_scale_.min(axis=0), rng)

        GPRCompensator._choose_subset = plain
    plan = FeedforwardPlan(iterations=args.iterations, trajectory="fourier",
                           duration_s=args.duration, max_points=args.max_points)
    scenario = task_scenario(ScenarioConfig(), plan)
    tracker = Tracker(scenario)
    n = tracker.n
    friction = JointFriction(scenario.friction, n)
    true_plant, true_context = tracker._plant, tracker._context
    model_plant = tracker.control_plant
    model_context = model_plant.CreateDefaultContext()

    def needed(X):
        return (dynamics(true_plant, true_context, X, tracker.scene.arm)
                - dynamics(model_plant, model_context, X) + friction.torque(X[:, n:2 * n]))

    def rms(a):
        return float(np.sqrt(np.mean(np.sum(a**2, axis=1))))

    run = tracker.run(tracker.task)
    X_d = run["X_desired"]
    need_d = needed(X_d)
    rows, data = [], []
    print(f"{'it':>3} {'tip_mm':>8} {'need':>7} {'label_err':>9} {'fit_err':>8} "
          f"{'pred_err':>8} {'applied_err':>11} {'scaled':>7} {'dist':>6}")
    for k in range(1, args.iterations + 1):
        X_a, y = run["X_actual"], run["model_error"]
        label_err = rms(y - needed(X_a))
        data.append((X_a, y))
        X_train, y_train = np.vstack([d[0] for d in data]), np.vstack([d[1] for d in data])
        t0 = time.perf_counter()
        model = fit_feedforward_gp(X_train, y_train, max_points=plan.max_points,
                                   optimize_points=plan.optimize_points, random_state=k)
        fit_s = time.perf_counter() - t0
        ff = LearnedFeedforward(model, n_joints=n, trust_ratio=plan.trust_ratio,
                                reject_ratio=plan.reject_ratio)
        fit_err = rms(model.predict(X_a) - needed(X_a))
        mean = model.predict(X_d)
        applied, _, confidence = ff.evaluate(X_d)
        # Distance in the GP's metric (standardised inputs / shortest length scale per input).
        scale = model.input_scale_ * model.length_scale_.min(axis=0)
        tree = cKDTree((X_train - model.input_mean_) / scale)
        dist = float(np.median(tree.query((X_d - model.input_mean_) / scale)[0]))
        row = {"iteration": k, "tip_mm_before": run["tip_rms_mm"], "need": rms(need_d),
               "label_err": label_err, "fit_err": fit_err, "pred_err": rms(mean - need_d),
               "applied_err": rms(applied - need_d),
               "scaled": float((confidence < 1).any(axis=1).mean()), "dist": dist,
               "fit_s": fit_s}
        rows.append(row)
        print(f"{k:>3} {run['tip_rms_mm']:8.3f} {row['need']:7.2f} {label_err:9.2f} "
              f"{fit_err:8.2f} {row['pred_err']:8.2f} {row['applied_err']:11.2f} "
              f"{row['scaled']:7.2f} {dist:6.2f}")
        run = tracker.run(tracker.task, ff)
    print(f"final tip RMS {run['tip_rms_mm']:.3f} mm")
    # The perfect feedforward, for scale: τ* fed forward at the desired state.
    print(json.dumps({"benchmark": "fourier_failure", "duration_s": args.duration,
                      "plain_subset": args.plain_subset,
                      "rows": rows, "final_tip_rms_mm": run["tip_rms_mm"]}))


if __name__ == "__main__":
    main()
