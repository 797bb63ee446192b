"""Joint-torque models on the real UR3 logs: a black box against the arm's rigid-body model.

Trains on trajectory id1 and evaluates on id2 (95 % of whose rows lie outside id1's ranges)
with ftdrake's Python API — the models ``ftdrake train`` builds (``make_estimator``), scored
as ``ftdrake evaluate`` scores them (``evaluate_model``) — for

* ``rf``: the random forest on q, q̇, q̈ (defaults, no tuning);
* ``arm``: the UR3's rigid-body dynamics from ``models/ur3.urdf`` (Universal Robots' published
  DH parameters and masses) + joint friction, identified physically consistent, with a drive
  gain per joint (``drive_gains="identify"``: the logged efforts are not N·m);
* ``hybrid``: ``arm`` + a forest on its residual: the joint-torque default (on q, q̇, q̈,
  ``ftdrake.compensation.estimators.hybrid.joint_torque_residual``), and the same forest on q
  alone;

and prints one markdown table of variance scores per joint (and the 95 % coverage of the
models' std). By default it reads the 6 s copies in ``tests/data/ur3``; ``--source DIR``
reads the full recordings (``id1.mat``, ``id2.mat``, as in ../shared/realdata/ur3)::

    python examples/ur3_torque_models.py [--source ../shared/realdata/ur3] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import pandas as pd
from scipy.io import loadmat

import ftdrake

ROOT = Path(__file__).resolve().parents[1]
UR3 = ftdrake.RobotOptions(robot=str(ROOT / "models" / "ur3.urdf"))
IDENTIFY_GAINS = {"drive_gains": "identify"}
# name → (registry name, make_estimator's keyword arguments)
MODELS = {
    "rf": ("rf", {}),
    "arm": ("arm", {"robot": UR3, "options": IDENTIFY_GAINS}),
    "hybrid (default, on q,qd,qdd)": ("hybrid", {"robot": UR3, "options": IDENTIFY_GAINS}),
    "hybrid (residual on q)": ("hybrid", {"robot": UR3, "options": IDENTIFY_GAINS,
                                          "features": "q"}),
}
# The logs' columns: joint torques tau_*, measured velocities qd_* (q̈ is differentiated).
READ = ftdrake.ReadOptions(targets="tau_*", velocities="qd_*")


def mat_to_csv(mat: Path, out: Path) -> Path:
    """A whole identification recording (keys mt, mq, mdq, mtorque) as ftdrake's CSV."""
    d = loadmat(mat)
    frame = pd.DataFrame({"t": d["mt"].ravel()})
    for prefix, key in (("q", "mq"), ("qd", "mdq"), ("tau", "mtorque")):
        for j in range(d[key].shape[1]):
            frame[f"{prefix}_{j}"] = d[key][:, j]
    frame.to_csv(out, index=False)
    return out


def run(train_csv: Path, test_csv: Path, out: Path | None = None) -> dict:
    """Each model of MODELS fitted on `train_csv` and evaluated on `test_csv`; with `out`,
    its model file and evaluation (JSON) are written there."""
    train = ftdrake.load_training_data(train_csv, READ)
    test = ftdrake.load_training_data(test_csv, READ)
    names = train.target_names
    ranges = ftdrake.target_ranges(train.Y, names)
    results = {}
    for name, (kind, settings) in MODELS.items():
        model = ftdrake.make_estimator(kind, target_names=names, **settings)
        model.fit(train.X, train.Y)
        results[name] = {"rows": test.rows, **ftdrake.evaluate_model(
            model, test.X, test.Y, target_names=names, training_ranges=ranges)}
        if out is not None:
            stem = f"{kind}_{len(results) - 1}"
            ftdrake.save_model(model, out / f"{stem}.ftd", target_names=names,
                               target_units=["N*m"] * len(names), sensor_frame="joints")
            (out / f"{stem}.json").write_text(json.dumps(results[name], indent=2))
    return results


def table(results: dict) -> str:
    first = next(iter(results.values()))
    targets = list(first["metrics"]["all"])
    lines = ["| model | " + " | ".join(targets) + " | 95 % coverage |",
             "| --- |" + " --- |" * (len(targets) + 1)]
    for name, res in results.items():
        metrics = res["metrics"]["all"]
        scores = " | ".join(f"{metrics[t]['variance_score']:.3f}" for t in targets)
        cover = [metrics[t].get("coverage_95") for t in targets]
        cover = (f"{min(cover):.2f}–{max(cover):.2f}" if None not in cover else "–")
        lines.append(f"| {name} | {scores} | {cover} |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--source", type=Path,
                        help="folder with the full id1.mat and id2.mat (default: the 6 s "
                             "CSV copies in tests/data/ur3)")
    parser.add_argument("--out", type=Path, help="keep the models and reports here")
    args = parser.parse_args()
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        if args.source:
            folder = args.out or Path(tmp)
            train = mat_to_csv(args.source / "id1.mat", folder / "id1.csv")
            test = mat_to_csv(args.source / "id2.mat", folder / "id2.csv")
        else:
            train, test = ROOT / "tests/data/ur3/id1.csv", ROOT / "tests/data/ur3/id2.csv"
        results = run(train, test, args.out)
    first = next(iter(results.values()))
    print(f"\ntrained on {train.name}, evaluated on {test.name}: {first['rows']['used']} "
          f"rows, {100 * first['out_of_domain_fraction']:.1f} % outside the training "
          "range; variance score per joint\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
