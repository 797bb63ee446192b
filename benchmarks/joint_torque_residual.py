"""The joint-torque hybrid's residual on the real UR3 logs: held-out nMSE per joint and the
model file's size, one factor of the residual at a time.

The hybrid on joint torques is the arm's rigid-body model (``ArmDynamicsCompensator``, drive
gains identified) plus a forest on its residual, predicting ``arm + w · residual`` with the
support weight w (:mod:`ftdrake.compensation.estimators.domain`: the residual *fades* to 0 away from
its training inputs). Factors compared against the arm alone:

* leaf size: ``min_samples_leaf`` 5 (the default residual before it kept 40 rows a leaf) or 40;
* fading: the support weight as fitted, or off (``domain_length_ = ∞``: w = 1 everywhere, the
  hybrid before the support term);
* features: the residual on ``q`` (default) or on ``q, q̇, q̈``;

and the residual ``train`` builds now for joint torques (``make_estimator("hybrid", ...)``).

Splits (each recording read as ``ftdrake train`` reads it: q̈ differentiated from q̇):
time-contiguous, the first 70 % of a recording for training and the last 30 % held out, on
``id1``, ``id2`` and ``prbs``; and across recordings, ``id1 → id2`` and ``id2 → id1``.
The arm's fit is the same for every residual of a split and is computed once per split.

    python benchmarks/joint_torque_residual.py [--source ../shared/realdata/ur3]
        [--splits id1,id2,prbs,id1>id2,id2>id1] [--every 1]

Prints a JSON record: per split and model the held-out nMSE per joint and its mean over
joints, and the model file's size (``save_model``) of each residual.
"""

from __future__ import annotations

import argparse
import functools
import json
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.io import loadmat

import ftdrake
from ftdrake.compensation.estimators.arm import ArmDynamicsCompensator, ExcitationWarning
from ftdrake.compensation.evaluation.metrics import nmse

ROOT = Path(__file__).resolve().parents[1]
UR3 = ftdrake.RobotOptions(robot=str(ROOT / "models" / "ur3.urdf"))
READ = ftdrake.ReadOptions(targets="tau_*", velocities="qd_*")
#: The residual forests: name → (min_samples_leaf, features, fading, trees, support rows).
#: FACTORS: the residual at eb9851c (leaf 40, q, fading, 50 trees, 4000 support rows) and one
#: factor changed at a time (leaf 5 as before 491b301; no fading as before 4572cf7).
FACTORS = {
    "eb9851c (leaf 40, q, fading)": (40, "q", True, 50, 4000),
    "leaf 5, q, fading": (5, "q", True, 50, 4000),
    "leaf 40, q, no fading": (40, "q", False, 50, 4000),
    "leaf 5, q, no fading (before both)": (5, "q", False, 50, 4000),
    "leaf 40, q,qd,qdd, fading": (40, "q,qd,qdd", True, 50, 4000),
    "leaf 5, q,qd,qdd, fading": (5, "q,qd,qdd", True, 50, 4000),
}
#: The joint-torque residual's candidates (q, q̇, q̈; fading), chosen on the validation splits.
#: Support rows None: the joint-torque default (at most 1000, every third row at least).
CANDIDATES = {f"q,qd,qdd, leaf {leaf}, {trees} trees, {points or 'default'} support": (
    leaf, "q,qd,qdd", True, trees, points)
    for leaf, trees, points in ((5, 25, None), (10, 25, None), (20, 25, None), (40, 25, None),
                                (10, 50, None), (20, 50, None), (20, 25, 4000))}
VARIANTS = {"factors": FACTORS, "candidates": CANDIDATES,
            "eb9851c": {k: v for k, v in FACTORS.items() if k.startswith("eb9851c")}}
#: Keys of each recording's arrays: time, q, q̇, measured torque.
KEYS = {"id1": ("mt", "mq", "mdq", "mtorque"), "id2": ("mt", "mq", "mdq", "mtorque"),
        "prbs": ("time", "q", "d_q", "m_torque")}
TRAIN_SHARE = 0.7


def recording(source: Path, name: str, folder: Path):
    """One recording as ftdrake's training data (X = [q, q̇, q̈], Y = joint torques)."""
    d = loadmat(source / f"{name}.mat")
    t, q, qd, tau = (np.asarray(d[k], dtype=float) for k in KEYS[name])
    frame = pd.DataFrame({"t": t.ravel()})
    for prefix, values in (("q", q), ("qd", qd), ("tau", tau)):
        for j in range(values.shape[1]):
            frame[f"{prefix}_{j}"] = values[:, j]
    path = folder / f"{name}.csv"
    frame.to_csv(path, index=False)
    return ftdrake.load_training_data(path, READ)


def split(data: dict, spec: str, every: int, validation: bool = False):
    """(X_train, Y_train, X_test, Y_test) of split `spec`: "A" (first 70 % of A → the
    rest) or "A>B" (all of A → all of B). With `validation` the training part alone, split
    again: its first 70 % → its rest (what a choice may be made on; the test rows unseen)."""
    if ">" in spec:
        a, b = spec.split(">")
        X, Y, X_test, Y_test = (*data[a], *data[b])
    else:
        X, Y = data[spec]
        cut = int(TRAIN_SHARE * len(X))
        X, Y, X_test, Y_test = X[:cut], Y[:cut], X[cut:], Y[cut:]
    if validation:
        cut = int(TRAIN_SHARE * len(X))
        X, Y, X_test, Y_test = X[:cut], Y[:cut], X[cut:], Y[cut:]
    return X[::every], Y[::every], X_test, Y_test


def _cached_arm_fit():
    """ArmDynamicsCompensator._fit memoised on its data (the residuals share one arm fit)."""
    original = ArmDynamicsCompensator._fit
    cache = {}

    @functools.wraps(original)
    def fit(self, Z, Y):
        key = (Z.tobytes(), Y.tobytes(), repr(sorted(self.get_params().items())))
        if key not in cache:
            original(self, Z, Y)
            cache[key] = {k: v for k, v in vars(self).items() if k.endswith("_")
                          or k in ("_null_directions",)}
        vars(self).update(cache[key])

    ArmDynamicsCompensator._fit = fit


def model(variant, names):
    """The unfitted hybrid of `variant` (None: as ``train`` builds it) and whether its
    residual fades."""
    hybrid = ftdrake.make_estimator("hybrid", target_names=names, robot=UR3,
                                    options={"drive_gains": "identify"})
    if variant is None:
        return hybrid, True
    leaf, features, fading, trees, points = variant
    residual = ftdrake.RandomForestCompensator(features=features, per_output=False,
                                               n_estimators=trees, min_samples_leaf=leaf,
                                               random_state=0)
    return hybrid.set_params(residual=residual, support_points=points), fading


def run_split(data, spec, every, names, folder: Path, variants, validation=False) -> dict:
    X, Y, X_test, Y_test = split(data, spec, every, validation)
    out = {"training_rows": len(X), "held_out_rows": len(X_test)}
    arm = ftdrake.make_estimator("arm", target_names=names, robot=UR3,
                                 options={"drive_gains": "identify"}).fit(X, Y)
    scores = nmse(Y_test, arm.predict(X_test))
    out["arm alone"] = {"nmse": scores.round(4).tolist(), "mean": round(float(scores.mean()), 4)}
    for name, variant in {"train's hybrid": None, **variants}.items():
        started = time.perf_counter()
        hybrid, fading = model(variant, names)
        hybrid.fit(X, Y)
        if not fading:
            hybrid.domain_length_ = np.inf
        scores = nmse(Y_test, hybrid.predict(X_test))
        path = ftdrake.save_model(hybrid, folder / "m.ftd", target_names=names,
                                  target_units=["N*m"] * len(names), sensor_frame="joints")
        out[name] = {"nmse": scores.round(4).tolist(), "mean": round(float(scores.mean()), 4),
                     "file_kB": round(path.stat().st_size / 1e3, 1),
                     "w_held_out_median": round(float(np.median(
                         hybrid.support_weight(X_test))), 3) if fading else 1.0,
                     "fit_s": round(time.perf_counter() - started, 1)}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, default=ROOT.parent / "shared/realdata/ur3")
    parser.add_argument("--splits", default="id1,id2,prbs,id1>id2,id2>id1")
    parser.add_argument("--every", type=int, default=1, help="keep every k-th training row")
    parser.add_argument("--variants", default="factors,candidates",
                        help="which residuals: factors, candidates, eb9851c (comma-separated)")
    parser.add_argument("--validation", action="store_true",
                        help="score on the validation split inside each training part "
                             "instead of the held-out test rows")
    args = parser.parse_args()
    _cached_arm_fit()
    specs = args.splits.split(",")
    variants = {k: v for group in args.variants.split(",") for k, v in VARIANTS[group].items()}
    needed = sorted({n for s in specs for n in s.split(">")})
    result = {"source": str(args.source), "train_share": TRAIN_SHARE, "every": args.every,
              "validation": args.validation, "splits": {}}
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        folder = Path(tmp)
        data = {}
        for name in needed:
            loaded = recording(args.source, name, folder)
            data[name] = (loaded.X, loaded.Y)
            names = loaded.target_names
        for spec in specs:
            result["splits"][spec] = run_split(data, spec, args.every, names, folder,
                                                variants, args.validation)
            print(json.dumps({spec: result["splits"][spec]}), flush=True)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
