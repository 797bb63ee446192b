"""How the model files in this folder were made: run at commit eb9851c (compensation/ still one
flat package, so every file names its classes by the old module paths, e.g.
``ftdrake.compensation.forest.RandomForestCompensator``), with that checkout first on the path:

    PYTHONPATH=<checkout of eb9851c> python3 tests/data/model_kinds_eb9851c/make_models.py \
        tests/data/model_kinds_eb9851c

One small model of every kind a model file may hold (forest, SVR, GP, per-axis SVRs, the
physics payload model identified consistently with a prior, the hybrid, the whole-arm model of
the UR3 and calibrate's orientation model), fitted on a few hundred synthetic rows, saved with
``save_model``; and in ``predictions.npz`` for each the query rows ``X_<name>`` and what that
code predicted for them, ``mean_<name>`` and ``std_<name>`` (``predict``/``predict_std``).
tests/test_model_files_eb9851c.py loads them with today's code and compares.
"""

import sys  # noqa: I001 (the old module paths this script imports are not in this tree)
import warnings
from pathlib import Path

import numpy as np

import ftdrake
from ftdrake.compensation.arm import ArmDynamicsCompensator
from ftdrake.compensation.orientation_model import OrientationPayloadCompensator
from ftdrake.compensation.tuning import PerOutputCompensator
from ftdrake.physics.arm_dynamics import ArmDynamics, ArmModel
from ftdrake.testing import THETA, TRUE_PAYLOAD, pose_tables, readings, sinusoids

ROOT = Path(ftdrake.__file__).resolve().parents[1]  # the checkout that writes the files
UR3 = str(ROOT / "models" / "ur3.urdf")


def arm_rows(rng, rows):
    """Random UR3 states and the file's dynamics with viscous friction, plus noise."""
    ur3 = ArmDynamics(ArmModel(UR3).build_plant())
    q, v, vd = (rng.uniform(-a, a, (rows, 6)) for a in (np.pi, 2.0, 4.0))
    tau = ur3.regressor(q, v, vd) @ ur3.model_parameters() + 2.0 * v
    return np.hstack([q, v, vd]), tau + 0.05 * rng.standard_normal(tau.shape)


def models(rng):
    """(name, unfitted model, X, Y) of every kind."""
    X = sinusoids(rng, range(7), n=400, duration=20.0)
    Y = readings(X, rng, THETA)
    cable = 0.3 * np.sin(3 * X[:, :1]) * np.array([1, -0.5, 0.8, 0.01, 0.02, -0.01])
    out = [
        ("forest", ftdrake.RandomForestCompensator(n_estimators=4, min_samples_leaf=8,
                                                   n_jobs=1, random_state=0), X, Y),
        ("svr", ftdrake.SVRCompensator(features="q", C=10.0), X[:200], Y[:200]),
        ("gpr", ftdrake.GPRCompensator(features="q", max_points=60, optimize_points=40,
                                       random_state=0), X[:200], Y[:200]),
        ("per_output", PerOutputCompensator([ftdrake.SVRCompensator(features="q", C=c)
                                             for c in (1, 2, 3, 4, 5, 6)]), X[:200], Y[:200]),
        ("physics", ftdrake.PhysicsPayloadCompensator(identification="consistent",
                                                      prior=TRUE_PAYLOAD), X, Y),
        ("hybrid", ftdrake.HybridCompensator(residual=ftdrake.RandomForestCompensator(
            n_estimators=4, min_samples_leaf=8, n_jobs=1, random_state=0)), X, Y + cable),
    ]
    Xa, Ya = arm_rows(rng, 300)
    out.append(("arm", ArmDynamicsCompensator(robot=UR3), Xa, Ya))
    _, rotation, _ = pose_tables(seed=3, n=60)
    o = rotation[["qw", "qx", "qy", "qz"]].to_numpy()
    Xo = np.hstack([o, 0 * o, 0 * o])
    Yo = rotation[[f"meas_{a}" for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")]].to_numpy()
    out.append(("orientation", OrientationPayloadCompensator(), Xo, Yo))
    return out


def main(folder: Path) -> None:
    print(f"ftdrake from {ROOT}")
    rng = np.random.default_rng(0)
    arrays = {}
    for name, model, X, Y in models(rng):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # excitation notes on these small data sets
            model.fit(X, Y)
        names = ({} if name != "arm" else
                 {"target_names": [f"tau_{j}" for j in range(6)], "target_units": ["N*m"] * 6})
        ftdrake.save_model(model, folder / f"{name}.ftd", **names)
        query = X[::7]
        arrays[f"X_{name}"] = query
        arrays[f"mean_{name}"] = model.predict(query)
        arrays[f"std_{name}"] = model.predict_std(query)
    np.savez(folder / "predictions.npz", **arrays)


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve())
