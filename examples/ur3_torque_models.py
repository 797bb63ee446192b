"""Joint-torque models on the real UR3 logs: a black box against the arm's rigid-body model.

Trains on trajectory id1 and evaluates on id2 (95 % of whose rows lie outside id1's ranges)
with ftdrake's own commands, ``ftdrake train`` and ``ftdrake evaluate``, for

* ``rf``: the random forest on q, q̇, q̈ (defaults, ``--preset none``);
* ``arm``: the UR3's rigid-body dynamics from ``models/ur3.urdf`` (Universal Robots' published
  DH parameters and masses) + joint friction, identified physically consistent, with a drive
  gain per joint (``--drive-gains identify``: the logged efforts are not N·m);
* ``hybrid``: ``arm`` + a forest on its residual (on q, and on q, q̇, q̈);

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

ROOT = Path(__file__).resolve().parents[1]
MODELS = {
    "rf": ["--model", "rf", "--preset", "none"],
    "arm": ["--model", "arm", "--robot", str(ROOT / "models" / "ur3.urdf"),
            "--drive-gains", "identify"],
    "hybrid (residual on q)": ["--model", "hybrid", "--robot", str(ROOT / "models" / "ur3.urdf"),
                               "--drive-gains", "identify"],
    "hybrid (residual on q,qd,qdd)": ["--model", "hybrid", "--features", "q,qd,qdd",
                                      "--robot", str(ROOT / "models" / "ur3.urdf"),
                                      "--drive-gains", "identify"],
}


def mat_to_csv(mat: Path, out: Path) -> Path:
    """A whole identification recording (keys mt, mq, mdq, mtorque) as ftdrake's CSV."""
    import pandas as pd
    from scipy.io import loadmat

    d = loadmat(mat)
    frame = pd.DataFrame({"t": d["mt"].ravel()})
    for prefix, key in (("q", "mq"), ("qd", "mdq"), ("tau", "mtorque")):
        for j in range(d[key].shape[1]):
            frame[f"{prefix}_{j}"] = d[key][:, j]
    frame.to_csv(out, index=False)
    return out


def run(train_csv: Path, test_csv: Path, out: Path) -> dict:
    from ftdrake.cli.main import main

    results = {}
    common = ["--targets", "tau_*", "--velocities", "qd_*", "--quiet"]
    for name, flags in MODELS.items():
        model = out / f"{name.split()[0]}_{len(results)}.ftd"
        if main(["train", "--data", str(train_csv), *common, *flags, "--out", str(model)]):
            raise SystemExit(f"train failed for {name}")
        report = out / f"{model.stem}.json"
        if main(["evaluate", "--model", str(model), "--data", str(test_csv), "--json",
                 str(report)]):
            raise SystemExit(f"evaluate failed for {name}")
        results[name] = json.loads(report.read_text())
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
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        if args.source:
            train = mat_to_csv(args.source / "id1.mat", out / "id1.csv")
            test = mat_to_csv(args.source / "id2.mat", out / "id2.csv")
        else:
            train, test = ROOT / "tests/data/ur3/id1.csv", ROOT / "tests/data/ur3/id2.csv"
        results = run(train, test, out)
        first = next(iter(results.values()))
        print(f"\ntrained on {train.name}, evaluated on {test.name}: {first['rows']['used']} "
              f"rows, {100 * first['out_of_domain_fraction']:.1f} % outside the training "
              "range; variance score per joint\n")
        print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
