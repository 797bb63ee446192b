"""Single-row latency of a random-forest compensator: ours vs scikit-learn vs ONNX Runtime.

Trains, on synthetic joint states of a 7-joint arm (21 features [q, q̇, q̈] → 6 wrench axes),
a 100-tree multi-output forest and a per-axis variant (6 forests of 100 trees, the study's and
``RandomForestCompensator``'s default), then times one prediction per call, the way a 1 kHz
control loop calls it:

* ours: ``CompiledForest.predict_one`` (numba),
* sklearn: ``forest.predict`` on a 1 × 21 array (``np.column_stack`` of 6 for per-axis),
* onnxruntime: ``InferenceSession.run`` on a 1 × 21 array, one intra-op thread.

Then a Gaussian-process compensator (``GPRCompensator``, m = 500 kept rows, one kernel per
axis) on the same data: its mean and standard deviation for one row, ours
(``CompiledGaussianProcess.predict_one_with_std``) vs the model's ``predict`` +
``predict_std``; the std costs O(axes · m²) per row whatever the code.

Then the physics payload model and the hybrid (physics + forest residual) on ftdrake's own arm
(7 joints, the same synthetic joint states, readings made from a known payload): one row
through

* Drake's per-row path: ``sensor_kinematics`` (Drake's Jacobian and bias acceleration of S),
  the numpy regressor, the product with the parameters — the physics model before the
  compiled chain,
* the compiled physics: ``PhysicsPayloadCompensator.predict_row`` and its ``row_predictor``
  (one numba kernel: serial-chain kinematics, regressor row, product),
* the hybrid's ``row_predictor`` (one numba call: payload kernel and forest residual,
  ``compiled/hybrid.py``), with HybridCompensator's default residual
  (``hybrid.default_residual``: one multi-output forest of 50 trees on q), with a
  multi-output residual of 100 trees and with per-axis forests (6 × 100 trees, the study's
  layout), and as the demo's (mounting rotation and weight without inertia, 20 parameters;
  with a tether and the cross-talk, ``demo.demo_hybrid``); for the default residual also the
  fused kernel writing into preallocated buffers (what ``CompensatorSystem`` does) and the
  two-call row it replaced (the payload row, the forest row, combined in numpy),

beside the compiled forests of the first part (the per-axis one is RandomForestCompensator's
default, the demo's forest). The residual here is the noise of the synthetic readings, so its
trees are deep (a worst case for the hybrid). The
compiled and Drake rows are checked equal to 1e-12 before timing, the hybrid rows (mean and
std) equal to its ``predict`` and ``predict_std`` to 1e-12.

Rows are consecutive samples of an unseen stretch of trajectory at 1 kHz (successive rows take
nearly the same paths through the trees, as in a control loop), and for ours also random
rows (cold paths, the worst case). Medians in µs; on a shared machine only the ratios travel.

    python benchmarks/compensator_latency.py
"""

from __future__ import annotations

import copy
import json
import os
import platform
import tempfile
import time
import warnings

import numba
import numpy as np
import onnxruntime
import sklearn
from sklearn.ensemble import RandomForestRegressor

from ftdrake.compensation.compiled import CompiledForest, CompiledGaussianProcess
from ftdrake.compensation.compiled.hybrid import hybrid_row
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.estimators.gpr import GPRCompensator
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import (
    ExcitationWarning,
    PhysicsPayloadCompensator,
    payload_regressor,
)
from ftdrake.compensation.files.onnx_export import export_onnx
from ftdrake.config import DetectorConfig
from ftdrake.experiments import demo
from ftdrake.physics.rigid_body import sensor_kinematics
from ftdrake.runtime.detector import chi2_threshold, detect_chi2

N_JOINTS, N_OUTPUTS, N_TREES, TRAIN_ROWS = 7, 6, 100, 3000
GP_POINTS = 500
GOAL_US = 10.0  # issue 10: one row of a compensator, mean + std


def excitation(t: np.ndarray, seed: int = 0) -> np.ndarray:
    """[q, q̇, q̈] (len(t), 21) of a 5-harmonic Fourier trajectory per joint (base 0.05 Hz)."""
    rng = np.random.default_rng(seed)
    harmonics = np.arange(1, 6)
    w = 2 * np.pi * 0.05 * harmonics  # rad/s
    a, b = rng.normal(scale=0.8 / harmonics, size=(2, N_JOINTS, len(harmonics)))
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))  # (T, harmonics)
    q = s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return np.hstack([q, qd, qdd])


def internal_wrench(X: np.ndarray, seed: int = 1) -> np.ndarray:
    """A smooth stand-in (N, 6) for the gravity and inertia of a tool seen by the sensor."""
    rng = np.random.default_rng(seed)
    q, qd, qdd = np.split(X, 3, axis=1)
    angles = np.cumsum(q, axis=1)  # orientation-like angles along the chain
    W = rng.normal(size=(4, N_JOINTS, N_OUTPUTS))
    return 5 * np.sin(angles) @ W[0] + 3 * np.cos(angles) @ W[1] + 0.3 * qd**2 @ W[2] + qdd @ W[3]


def median_us(call, rows: np.ndarray, repeats: int) -> float:
    """Median wall time of call(row) in µs, cycling through rows after a few warm-up calls."""
    for row in rows[:5]:
        call(row)
    times = np.empty(repeats)
    for i in range(repeats):
        row = rows[i % len(rows)]
        start = time.perf_counter_ns()
        call(row)
        times[i] = time.perf_counter_ns() - start
    return float(np.median(times)) / 1e3


def batch_ms(call, X: np.ndarray) -> float:
    """Best of 3 wall times of call(X) in ms."""
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        call(X)
        best = min(best, time.perf_counter() - start)
    return best * 1e3


def machine() -> dict:
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        pass
    return {
        "cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
        "numpy": np.__version__, "sklearn": sklearn.__version__, "numba": numba.__version__,
        "onnxruntime": onnxruntime.__version__,
    }


def main() -> None:
    X_train = excitation(np.linspace(0, 60, TRAIN_ROWS))  # 50 Hz
    Y_train = internal_wrench(X_train)
    smooth = excitation(70 + np.arange(2000) * 1e-3)  # unseen, 1 kHz
    random_rows = np.random.default_rng(2).uniform(X_train.min(0), X_train.max(0), (2000, 21))

    def forest(y):
        # min_samples_leaf=2 is RandomForestCompensator's default; predict single-threaded.
        f = RandomForestRegressor(N_TREES, min_samples_leaf=2, random_state=0, n_jobs=2)
        return f.fit(X_train, y).set_params(n_jobs=None)

    start = time.perf_counter()
    variants = {
        "multi-output": [forest(Y_train)],
        "per-axis": [forest(Y_train[:, j]) for j in range(N_OUTPUTS)],
    }
    print(f"trained in {time.perf_counter() - start:.0f} s on {TRAIN_ROWS} rows")

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, forests in variants.items():
            ours = CompiledForest(forests, "q,qd,qdd")
            path = export_onnx(forests, os.path.join(tmp, "forest.onnx"), N_JOINTS, "q,qd,qdd")
            session = onnxruntime.InferenceSession(str(path), options)
            out = np.empty(N_OUTPUTS)
            calls = {
                "ours": lambda x, ours=ours, out=out: ours.predict_one(x, out),
                "sklearn": lambda x, fs=forests: np.column_stack(
                    [f.predict(x[None, :]) for f in fs]
                ),
                "onnxruntime": lambda x, s=session: s.run(None, {"X": np.atleast_2d(x)})[0],
            }
            reference = np.column_stack([f.predict(smooth) for f in forests])
            assert np.allclose(ours.predict(smooth), reference, rtol=0, atol=1e-9)
            assert np.allclose(calls["onnxruntime"](smooth), reference, rtol=0, atol=1e-9)
            depth = np.mean([e.tree_.max_depth for f in forests for e in f.estimators_])
            results[name] = {
                "trees": sum(len(f.estimators_) for f in forests),
                "mean_depth": round(float(depth), 1),
                "ours_us": median_us(calls["ours"], smooth, 20000),
                "sklearn_us": median_us(calls["sklearn"], smooth, 200),
                "onnxruntime_us": median_us(calls["onnxruntime"], smooth, 5000),
                "ours_random_rows_us": median_us(calls["ours"], random_rows, 20000),
                "batch_1000_ms": {
                    "ours": batch_ms(ours.predict, smooth[:1000]),
                    "sklearn": batch_ms(lambda X, fs=forests: [f.predict(X) for f in fs],
                                        smooth[:1000]),
                    "onnxruntime": batch_ms(calls["onnxruntime"], smooth[:1000]),
                },
            }

    print(f"\nsingle-row latency, median µs ({N_TREES} trees per forest, 21 features, "
          f"{N_OUTPUTS} outputs, rows of a 1 kHz trajectory)")
    print(f"{'variant':<14}{'trees':>6}{'depth':>7}{'ours':>9}{'sklearn':>10}{'onnxrt':>9}"
          f"{'sk/ours':>9}{'ort/ours':>9}{'ours, random rows':>19}")
    for name, r in results.items():
        print(f"{name:<14}{r['trees']:>6}{r['mean_depth']:>7}{r['ours_us']:>9.1f}"
              f"{r['sklearn_us']:>10.0f}{r['onnxruntime_us']:>9.1f}"
              f"{r['sklearn_us'] / r['ours_us']:>9.0f}{r['onnxruntime_us'] / r['ours_us']:>9.1f}"
              f"{r['ours_random_rows_us']:>19.1f}")
    print("\nbatch of 1000 rows, best of 3, ms")
    for name, r in results.items():
        b = r["batch_1000_ms"]
        print(f"{name:<14} ours {b['ours']:.1f}  sklearn {b['sklearn']:.1f}  "
              f"onnxruntime {b['onnxruntime']:.1f}")
    gp = gp_latency(X_train, Y_train, smooth)
    physics = physics_latency(X_train, smooth)
    forest_us = results["per-axis"]["ours_us"]
    print("\nphysics payload model on ftdrake's arm, one row, median µs (ratios: this run)")
    print(f"{'path':<38}{'µs':>9}{'Drake row /':>13}{'/ per-axis forest':>19}")
    rows_table = [
        ("forest, compiled, per-axis (default)", forest_us),
        ("forest, compiled, multi-output", results["multi-output"]["ours_us"]),
        ("physics, Drake per-row kinematics", physics["drake_row_us"]),
        ("physics, predict_row (compiled)", physics["predict_row_us"]),
        ("physics, row_predictor (compiled)", physics["row_predictor_us"]),
        ("hybrid, default residual (50 trees)", physics["hybrid_row_us"]),
        ("hybrid, default, no support term", physics["hybrid_no_support_row_us"]),
        ("χ² test of the detector, one sample", physics["chi2_test_us"]),
        ("hybrid as the demo's (mounting, 20 p.)", physics["hybrid_demo_row_us"]),
        ("hybrid as the demo's, tether + cross-talk", physics["hybrid_tether_row_us"]),
        ("hybrid, default, kernel into buffers", physics["hybrid_kernel_us"]),
        ("hybrid, default, two calls (before)", physics["hybrid_two_call_row_us"]),
        ("hybrid, multi-output residual, 100 t.", physics["hybrid_multi_output_row_us"]),
        ("hybrid, per-axis residual, 6 × 100 t.", physics["hybrid_per_axis_row_us"]),
    ]
    for name, us in rows_table:
        print(f"{name:<38}{us:>9.2f}{physics['drake_row_us'] / us:>12.1f}×"
              f"{us / forest_us:>18.2f}×")
    print(f"\nhybrid (default residual) row_predictor: {physics['hybrid_row_us']:.2f} µs, goal "
          f"<= {GOAL_US:.0f} µs: {'met' if physics['hybrid_row_us'] <= GOAL_US else 'NOT met'}"
          f"; two-call row / fused: "
          f"{physics['hybrid_two_call_row_us'] / physics['hybrid_row_us']:.2f}× "
          f"(load average {os.getloadavg()[0]:.2f})")
    print(f"\nGaussian process (m = {GP_POINTS}, 6 kernels), mean + std of one row, median µs: "
          f"ours {gp['ours_us']:.0f}, predict + predict_std {gp['predict_and_std_us']:.0f}")
    multi = results["multi-output"]
    print(json.dumps({
        "ours_us": round(multi["ours_us"], 2),
        "sklearn_us": round(multi["sklearn_us"], 1),
        "onnxruntime_us": round(multi["onnxruntime_us"], 2),
        "ours_random_rows_us": round(multi["ours_random_rows_us"], 2),
        "per_axis": {k: round(v, 2) for k, v in results["per-axis"].items()
                     if k.endswith("_us")},
        "batch_1000_ms": {name: {k: round(v, 2) for k, v in r["batch_1000_ms"].items()}
                          for name, r in results.items()},
        "gp": gp,
        "physics": {
            **{k: round(v, 2) for k, v in physics.items()},
            "forest_per_axis_us": round(forest_us, 2),
            "forest_multi_output_us": round(results["multi-output"]["ours_us"], 2),
            "drake_over_compiled": round(physics["drake_row_us"] / physics["predict_row_us"], 1),
            "compiled_over_forest": round(physics["predict_row_us"] / forest_us, 2),
            "hybrid_default_over_forest_per_axis": round(physics["hybrid_row_us"] / forest_us,
                                                         2),
            "hybrid_multi_output_over_forest_multi_output": round(
                physics["hybrid_multi_output_row_us"] / results["multi-output"]["ours_us"], 2),
            "hybrid_two_call_over_fused": round(
                physics["hybrid_two_call_row_us"] / physics["hybrid_row_us"], 2),
            "hybrid_goal_us": GOAL_US,
            "hybrid_goal_met": physics["hybrid_row_us"] <= GOAL_US,
        },
        "load_average_1min": round(os.getloadavg()[0], 2),
        "n_trees": N_TREES, "n_features": 3 * N_JOINTS, "n_outputs": N_OUTPUTS,
        "train_rows": TRAIN_ROWS, "machine": machine(),
    }))


def physics_latency(X_train, rows) -> dict:
    """Single-row µs of the physics model (Drake's row path and the compiled one) and the
    hybrid, on ftdrake's arm, with readings made from a known payload."""
    physics = PhysicsPayloadCompensator()  # ftdrake's arm
    phi = np.array([1.5, 0.03, 0.01, 0.13, 0.012, 0.0, 0.001, 0.012, 0.0, 0.004,
                    0.6, -0.4, 1.2, 0.01, -0.02, 0.005])
    rng = np.random.default_rng(3)
    Y = physics.regressor(X_train) @ phi + rng.normal(0, 0.02, (len(X_train), 6))
    physics.fit(X_train, Y)
    hybrids = {
        per_output: HybridCompensator(residual=RandomForestCompensator(
            features="q", n_estimators=N_TREES, min_samples_leaf=5, per_output=per_output,
            random_state=0, n_jobs=2)).fit(X_train, Y)
        for per_output in (True, False)
    }
    hybrids["default"] = HybridCompensator().fit(X_train, Y)
    # The default without its support term (the std's out-of-domain growth): what it costs.
    hybrids["no_support"] = copy.deepcopy(hybrids["default"])
    hybrids["no_support"].domain_support_ = None
    hybrids["no_support"].domain_length_ = np.inf
    # The demo's: mounting rotation (the rotated kernel path) and the weight carried without
    # inertia (20 parameters).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)  # no weight in these readings
        hybrids["demo"] = HybridCompensator(physics=PhysicsPayloadCompensator(
            identify_mounting=True, weight_without_inertia=True)).fit(X_train, Y)
        # The demo's now (demo.demo_hybrid): a tether as well (22 parameters; the frames of
        # the arm's joints in S and the tether's columns in the kernel) and the cross-talk
        # (the reading matrix). No cable in these readings: the search fits one to noise,
        # which costs the same per row.
        hybrids["tether"] = demo.demo_hybrid().fit(X_train, Y)

    plant, frame_S = physics.robot_description().build_plant()
    context = plant.CreateDefaultContext()
    gravity = np.asarray(physics.gravity)
    theta = physics.parameters_

    def drake_row(x):
        kin = sensor_kinematics(plant, context, frame_S, x[None, :N_JOINTS],
                                x[None, N_JOINTS:2 * N_JOINTS], x[None, 2 * N_JOINTS:])
        g_S = kin.R_WS[0].T @ gravity
        return payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - g_S)[0] @ theta

    row_predictor = physics.row_predictor()
    hybrid_rows = {k: h.row_predictor() for k, h in hybrids.items()}
    default = hybrids["default"]
    kernel_arrays = default.compiled_predictor().arrays
    mean_buffer, std_buffer = np.empty(6), np.empty(6)

    def hybrid_kernel(x):
        hybrid_row(x, *kernel_arrays, mean_buffer, std_buffer)

    two_calls = two_call_row(default)
    expected = np.array([drake_row(x) for x in rows[:200]])
    got = np.array([physics.predict_row(x) for x in rows[:200]])
    assert np.allclose(got, expected, rtol=0, atol=1e-12 * max(1, np.abs(expected).max()))
    assert np.allclose(physics.predict(rows[:200]), expected, rtol=0, atol=1e-11)
    for k, hybrid in hybrids.items():
        got = [hybrid_rows[k](x) for x in rows[:200]]
        mean = hybrid.predict(rows[:200])
        assert np.allclose([m for m, _ in got], mean, rtol=0,
                           atol=1e-12 * max(1, np.abs(mean).max()))
        assert np.allclose([s for _, s in got], hybrid.predict_std(rows[:200]), rtol=0,
                           atol=1e-12)
    # The two-call row has no support term: equal to the hybrid without it.
    assert np.allclose([two_calls(x)[0] for x in rows[:200]],
                       hybrids["no_support"].predict(rows[:200]), rtol=0, atol=1e-9)
    w, std = np.zeros(6), default.predict_std(rows[:1])[0]
    constants = np.array([chi2_threshold(DetectorConfig(test="chi2"), 1e-3), 0.6, 3, 25])
    flag, counter, force = np.zeros(1), np.zeros(1), np.zeros(1)

    def chi2_test(_row):
        detect_chi2(w, std, constants, flag, counter, force)

    return {
        "drake_row_us": median_us(drake_row, rows, 1000),
        "predict_row_us": median_us(physics.predict_row, rows, 20000),
        "row_predictor_us": median_us(row_predictor, rows, 20000),
        "hybrid_row_us": median_us(hybrid_rows["default"], rows, 20000),
        "hybrid_no_support_row_us": median_us(hybrid_rows["no_support"], rows, 20000),
        "chi2_test_us": median_us(chi2_test, rows, 20000),
        "hybrid_demo_row_us": median_us(hybrid_rows["demo"], rows, 20000),
        "hybrid_tether_row_us": median_us(hybrid_rows["tether"], rows, 20000),
        "hybrid_kernel_us": median_us(hybrid_kernel, rows, 20000),
        "hybrid_two_call_row_us": median_us(two_calls, rows, 20000),
        "hybrid_multi_output_row_us": median_us(hybrid_rows[False], rows, 20000),
        "hybrid_per_axis_row_us": median_us(hybrid_rows[True], rows, 20000),
        "batch_1000_ms": batch_ms(physics.predict, rows[:1000]),
    }


def two_call_row(hybrid):
    """The hybrid's row before the fused kernel: the payload row (parameter std), the
    residual forest's row, combined in numpy."""
    physics = hybrid.physics_.row_predictor(include_noise=False)
    residual = hybrid.residual_.row_predictor()
    noise_var = hybrid.residual_noise_var_

    def predict(row):
        mean, physics_std = physics(row)
        internal, _ = residual(row)
        return mean + internal, np.sqrt(physics_std * physics_std + noise_var)

    return predict


def gp_latency(X_train, Y_train, rows) -> dict:
    model = GPRCompensator(max_points=GP_POINTS, random_state=0).fit(X_train, Y_train)
    ours = CompiledGaussianProcess(model)
    mean, std = ours.predict_with_std(rows[:50])
    assert np.allclose(mean, model.predict(rows[:50]), rtol=1e-9, atol=1e-9)
    # Variances, to 1e-9 of the signal variance: with noise-free data the std is the root of
    # a difference that cancels to ~1e-10 of its terms, for sklearn's formula as for ours.
    signal = (model.signal_variance_ * model.target_scale_**2).max()
    assert np.allclose(std**2, model.predict_std(rows[:50]) ** 2, rtol=1e-9, atol=1e-9 * signal)
    return {
        "points": GP_POINTS,
        "ours_us": median_us(ours.predict_one_with_std, rows, 2000),
        "predict_and_std_us": median_us(
            lambda x: (model.predict(x[None, :]), model.predict_std(x[None, :])), rows, 300),
    }


if __name__ == "__main__":
    main()
