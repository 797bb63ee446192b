"""Learned joint-torque models on the real UR3 logs, by feature set: q, q+q̇, q+q̇+q̈.

Issue 13 reported that on held-out runs the GP with velocity features and the SVR tuned with
the ``quick`` preset broke without warning. This script measures, on the UR3 recordings
(``/work/shared/realdata/ur3``, or ``--ur3 DIR``; the small copies in ``tests/data/ur3`` when
the full files are missing):

* ``id1→id2``: trained on identification run id1 (5200 rows), scored on run id2 (3754 rows),
  a held-out run (99 % of its rows outside id1's joint ranges);
* ``id1 70/30``: trained on the first 70 % of id1, scored on the last 30 % (within one run);
* ``faster``: synthetic gravity torques (a function of q alone) of a 6-joint chain, trained on
  a 60 s run and scored on the same path driven 1.5× faster (:func:`chain_run`): q stays in
  range, q̇ and q̈ do not. What a held-out run that is new only in its velocities does;
* ``two speeds``: the same, trained on the path at 1× (60 s) and at 2× (30 s): the 1.5× run's
  velocities now lie between runs the model has seen.

Each log is read as ``ftdrake train`` reads it (``--targets 'tau_*' --velocities 'qd_*'``;
q̈ by Savitzky–Golay of q). Models: ``gpr`` (defaults), ``svr`` (defaults, ``--preset none``),
``svr-quick`` (tuned with the ``quick`` grid and grouped 5-fold CV, as ``train`` does) and
``rf`` (defaults, for reference). Per model and feature set it prints the nMSE per joint, the
GP's 95 % coverage and the share of rows ``evaluate`` would flag: predictive std above
``UNCERTAIN_STD_FACTOR`` × the training residual (GP), predictions outside the training
torque range widened by ``TARGET_RANGE_MARGIN`` (every model), inputs outside the training
range. The residual is computed here from the training rows, so the script also runs on
older versions of ftdrake (how the doc's "before" columns were made:
``PYTHONPATH=<old tree> python benchmarks/velocity_features.py``).

    nice -n 5 python benchmarks/velocity_features.py [--models gpr,svr,svr-quick,rf]
        [--features q,q+qd,q+qd+qdd] [--scenarios ...] [--json OUT]
    nice -n 5 python benchmarks/velocity_features.py --svr-grid   # CV vs held-out, 28 SVRs

Prints a table and a JSON line. Fit times on a shared 2-core machine are indicative only.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import norm

from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.gpr import GPRCompensator
from ftdrake.compensation.estimators.svr import SVRCompensator
from ftdrake.compensation.estimators.tuning import segment_groups, tune
from ftdrake.compensation.evaluation.metrics import nmse
from ftdrake.data.training import ReadOptions, load_training_data

REPO = Path(__file__).resolve().parents[1]
UR3 = Path("/work/shared/realdata/ur3")
SMALL = REPO / "tests" / "data" / "ur3"
STD_FACTOR = 2.0  # as ftdrake.compensation.evaluation.metrics.UNCERTAIN_STD_FACTOR
RANGE_MARGIN = 0.1  # as ftdrake.compensation.evaluation.metrics.TARGET_RANGE_MARGIN
READ = ReadOptions(targets="tau_*", velocities="qd_*")


def read_runs(source: Path) -> dict:
    """{"id1": TrainingData, "id2": TrainingData}, read as ``ftdrake train`` reads them."""
    if (source / "id1.mat").is_file():
        import pandas as pd
        from scipy.io import loadmat

        runs = {}
        with tempfile.TemporaryDirectory() as tmp:
            for name in ("id1", "id2"):
                d = loadmat(source / f"{name}.mat")
                frame = pd.DataFrame({"t": d["mt"].ravel()})
                for prefix, key in (("q", "mq"), ("qd", "mdq"), ("tau", "mtorque")):
                    for j in range(d[key].shape[1]):
                        frame[f"{prefix}_{j}"] = d[key][:, j]
                path = Path(tmp) / f"{name}.csv"
                frame.to_csv(path, index=False, float_format="%.6f")
                runs[name] = load_training_data(path, READ)
        return runs
    print(f"{source}: no id1.mat; using the 750-row copies in {SMALL}", file=sys.stderr)
    return {name: load_training_data(SMALL / f"{name}.csv", READ) for name in ("id1", "id2")}


def scenarios(runs: dict) -> dict:
    id1, id2 = runs["id1"], runs["id2"]
    cut = int(0.7 * len(id1.X))
    slow, fast = chain_run(6000, speed=1.0, seed=0), chain_run(4000, speed=1.5, seed=1)
    twice = chain_run(3000, speed=2.0, seed=2)
    return {
        "id1→id2": ((id1.X, id1.Y, id1.groups), (id2.X, id2.Y)),
        "id1 70/30": ((id1.X[:cut], id1.Y[:cut], id1.groups[:cut]), (id1.X[cut:], id1.Y[cut:])),
        "faster": ((*slow, np.zeros(len(slow[0]))), fast),
        "two speeds": ((*(np.vstack(a) for a in zip(slow, twice, strict=True)),
                        np.repeat([0, 1], [len(slow[0]), len(twice[0])])), fast),
    }


def chain_run(n: int, speed: float, seed: int, joints: int = 6):
    """Synthetic (X, Y): gravity torques of a planar chain of `joints` pitch joints (1 kg,
    0.3 m links: ``tau_j = g Σ_{k≥j} m l cos(q_1 + … + q_k)``, N·m), a function of q alone,
    plus white noise of 0.05 N·m, along a sum of 5 sines per joint sampled at 100 Hz. The
    path depends on the trajectory seed 0 only; `speed` runs it faster (q̇ ×speed, q̈
    ×speed²) and `seed` draws the noise. "faster": trained on 60 s at speed 1, scored on the
    same path at 1.5× (q stays in range, q̇ and q̈ do not).
    """
    rng = np.random.default_rng(0)
    w, a, phase = (rng.uniform(lo, hi, (5, joints))
                   for lo, hi in ((0.1, 0.6), (0.05, 0.2), (0.0, 2 * np.pi)))
    arg = w * (np.arange(n) / 100.0 * speed)[:, None, None] + phase
    q = (a * np.sin(arg)).sum(axis=1)
    qd = speed * (a * w * np.cos(arg)).sum(axis=1)
    qdd = -(speed**2) * (a * w**2 * np.sin(arg)).sum(axis=1)
    link = 9.81 * 1.0 * 0.3 * np.cos(np.cumsum(q, axis=1))  # gravity moment of each link
    tau = np.cumsum(link[:, ::-1], axis=1)[:, ::-1]  # joint j carries links j..n
    noise = 0.05 * np.random.default_rng(seed + 1).standard_normal(tau.shape)
    return np.hstack([q, qd, qdd]), tau + noise


def fit(model: str, features: str, X, Y, groups):
    if model == "gpr":
        return GPRCompensator(features=features, random_state=0).fit(X, Y)
    if model == "svr":
        return SVRCompensator(features=features).fit(X, Y)
    if model == "svr-quick":
        tuned, _ = tune(SVRCompensator(features=features), X, Y, groups=segment_groups(groups),
                        preset="quick", cv="grouped", n_jobs=2, progress=False)
        return tuned
    if model == "rf":
        return RandomForestCompensator(features=features, n_jobs=1, random_state=0).fit(X, Y)
    raise ValueError(f"unknown model {model!r}")


def score(dut, train, test) -> dict:
    (Xa, Ya, _), (Xb, Yb) = train, test
    P = np.asarray(dut.predict(Xb)).reshape(Yb.shape)
    lo, hi = Ya.min(axis=0), Ya.max(axis=0)
    pad = RANGE_MARGIN * (hi - lo)
    row = {
        "nmse": nmse(Yb, P).round(4).tolist(),
        "outside_target_range": np.mean((P < lo - pad) | (P > hi + pad), axis=0).round(3).tolist(),
        "inputs_out_of_range": float(np.mean(dut.out_of_domain(Xb))),
    }
    flagged = (P < lo - pad) | (P > hi + pad) | dut.out_of_domain(Xb)[:, None]
    if getattr(dut, "provides_std", False) and getattr(dut, "std_includes_noise", False):
        S = np.asarray(dut.predict_std(Xb)).reshape(Yb.shape)
        residual = np.sqrt(np.mean((np.asarray(dut.predict(Xa)).reshape(Ya.shape) - Ya) ** 2, 0))
        z95 = norm.ppf(0.975)
        row["coverage_95"] = np.mean(np.abs(Yb - P) <= z95 * S, axis=0).round(3).tolist()
        row["uncertain"] = np.mean(S > STD_FACTOR * residual, axis=0).round(3).tolist()
        row["std_over_residual_median"] = np.median(S / residual, axis=0).round(2).tolist()
        flagged |= S > STD_FACTOR * residual
    if hasattr(dut, "length_scale_"):  # GP: shortest ARD length scale per input group
        n, ls = dut.n_joints_, dut.length_scale_
        row["gp_min_length_scale"] = {
            group: np.round(ls[:, b * n:(b + 1) * n].min(axis=1), 2).tolist()
            for b, group in enumerate(("q", "qd", "qdd")[: ls.shape[1] // n])}
    # Does a flag mean a larger error? RMS error on the flagged and on the other rows.
    row["flagged"] = flagged.mean(axis=0).round(3).tolist()
    row["rmse_flagged"] = [_rms(Yb[f, j] - P[f, j]) for j, f in enumerate(flagged.T)]
    row["rmse_trusted"] = [_rms(Yb[~f, j] - P[~f, j]) for j, f in enumerate(flagged.T)]
    return row


def _rms(e: np.ndarray) -> float | None:
    return round(float(np.sqrt(np.mean(e**2))), 4) if e.size else None


def svr_grid(runs: dict, features: str = "q,qd") -> list[dict]:
    """Grouped 5-fold CV nMSE inside id1 against nMSE on id2, for an SVR C × gamma grid."""
    from sklearn.model_selection import ParameterGrid

    from ftdrake.compensation.estimators.tuning import cv_splits

    (Xa, Ya, groups), (Xb, Yb) = scenarios(runs)["id1→id2"]
    splits = cv_splits(len(Xa), groups=segment_groups(groups))
    rows = []
    for params in ParameterGrid({"C": [0.1, 1.0, 10.0, 100.0],
                                 "gamma": [0.03, 0.1, 0.3, 1.0, 3.0, "scale", "auto"]}):
        cv = np.mean([nmse(Ya[te], SVRCompensator(features=features, **params)
                           .fit(Xa[tr], Ya[tr]).predict(Xa[te])) for tr, te in splits], axis=0)
        dut = SVRCompensator(features=features, **params).fit(Xa, Ya)
        held_out = nmse(Yb, dut.predict(Xb))
        rows.append({**params, "features": features, "cv_nmse": cv.round(4).tolist(),
                     "id2_nmse": held_out.round(4).tolist()})
        print(f"C {params['C']:<6g} gamma {params['gamma']!s:<6} CV nMSE median "
              f"{np.median(cv):.3f} max {cv.max():.3f} | id2 median {np.median(held_out):.2f}"
              f" max {held_out.max():.2f}", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ur3", type=Path, default=UR3)
    parser.add_argument("--models", default="gpr,svr,svr-quick,rf")
    parser.add_argument("--features", default="q,q+qd,q+qd+qdd",
                        help="comma-separated, '+' inside a set")
    parser.add_argument("--scenarios", default="id1→id2,id1 70/30,faster,two speeds")
    parser.add_argument("--svr-grid", action="store_true",
                        help="instead: CV inside id1 vs id2 for an SVR C × gamma grid (q,qd)")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON")
    args = parser.parse_args()
    feature_sets = [f.replace("+", ",") for f in args.features.split(",")]
    runs = read_runs(args.ur3)
    if args.svr_grid:
        result = {"benchmark": "velocity_features/svr_grid", "rows": svr_grid(runs)}
        if args.json is not None:
            args.json.write_text(json.dumps(result, indent=1))
        print(json.dumps(result))
        return
    rows = []
    print(f"{'scenario':<11}{'model':<10}{'features':<10}{'fit s':>7}  {'nMSE per joint':<44}"
          f"{'cov95':>6}{'uncert.':>8}{'pred>rng':>9}{'in>rng':>7}")
    chosen = args.scenarios.split(",")
    for name, (train, test) in scenarios(runs).items():
        if name not in chosen:
            continue
        for model in args.models.split(","):
            for features in feature_sets:
                start = time.perf_counter()
                dut = fit(model, features, *train)
                seconds = time.perf_counter() - start
                row = {"scenario": name, "model": model, "features": features,
                       "fit_s": round(seconds, 1), **score(dut, train, test)}
                rows.append(row)
                cov = f"{np.median(row['coverage_95']):6.2f}" if "coverage_95" in row else "     –"
                unc = f"{np.median(row['uncertain']):8.2f}" if "uncertain" in row else "       –"
                print(f"{name:<11}{model:<10}{features:<10}{seconds:7.1f}  "
                      + " ".join(f"{v:6.2f}" for v in row["nmse"]).ljust(44)
                      + f"{cov}{unc}{np.median(row['outside_target_range']):9.2f}"
                      f"{row['inputs_out_of_range']:7.2f}", flush=True)
    print("(cov95, uncert., pred>rng: medians over joints of the 95 % coverage, the share of "
          f"rows with std > {STD_FACTOR:g}× training residual, of predictions outside the "
          "training torque range; in>rng: share of rows with an input outside its range)")
    result = {"benchmark": "velocity_features", "rows": rows, "machine": platform.machine(),
              "cpus": os.cpu_count(), "python": platform.python_version()}
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
