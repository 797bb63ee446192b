"""The main job: collect → train → contact scenario with the compensator in the loop.

1. Collect free-motion data: Fourier excitation around the home pose, rehearsals of the
   task in the air (the contact scenario stopping 3 cm above the table), `TASK_COVERING_RUNS`
   runs planned to cover the task's approaches to every surface (``task_covering``) and one
   run of each of `OTHER_KINDS` — on a real robot you would record the same: the task's
   motions without contact, and motion covering the configurations the arm will visit. With
   ``other_surfaces`` (``demo --rehearse-all-surfaces``) also one rehearsal at each other
   surface of the task (the wall), trained on and held out; off by default.
2. Train, on the same data, the study's model — a multi-output random forest on joint
   positions, `quick` grid, folds grouped by trajectory segment — and the hybrid
   (:func:`demo_hybrid`): the rigid payload, the biases, the sensor's mounting rotation and
   cross-talk, a weight carried without inertia and the cable's pull (a tether) identified
   plus a forest on its residual, its std growing out of domain: the support term and the
   in-domain level are calibrated on the training runs farthest from the others
   (``DOMAIN_HOLDOUT_SHARE`` of the rows, held out for it), then the hybrid is refitted on
   every run (:class:`~ftdrake.compensation.estimators.domain_calibrated.DomainCalibratedHybrid`);
   the summary reports its coverage in and out of domain on the held-out runs below
   (``domain_coverage``). One rehearsal and one run of each free-motion kind are held out; each
   model's detector thresholds follow from its residual there (the samples the detector judges) and
   the scenario's false-positive budget, ``detector.false_positives_per_hour``
   (:func:`~ftdrake.offline.thresholds.thresholds_for_false_positive_rate`).
3. Run the same contact scenario, trajectory seed and sensor noise not seen in training, with
   each model and its detector in the loop at the sensor rate, and score both against the
   plant's ground truth. The summary says which did better and why.
"""

from __future__ import annotations

import dataclasses as dc
import json
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.math import RollPitchYaw, RotationMatrix

from .. import conventions as col
from ..compensation.estimators.domain import DISTANCE_BINS
from ..compensation.estimators.domain_calibrated import DomainCalibratedHybrid
from ..compensation.estimators.forest import RandomForestCompensator
from ..compensation.estimators.hybrid import HybridCompensator
from ..compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ..compensation.estimators.tuning import segment_groups, tune
from ..compensation.evaluation.metrics import coverage
from ..compensation.files.persistence import save_model
from ..config import ScenarioConfig
from ..data.dataset import joint_state_layout, wrench_targets
from ..data.logs import write_log
from ..io import atomic_path, staged_outputs
from ..offline.thresholds import armed, threshold_text, thresholds_for_false_positive_rate
from ..plots import plot_contact_comparison
from ..sim.collection import collect
from ..sim.evaluation import evaluate_detection
from ..sim.simulate import simulate
from ..sim.station import build_station
from ..systems.wrench_arrows import recording_meshcat
from ..version import result_provenance
from .stages import Stages

HELD_OUT_SEED = 1000
#: What the real-time factor the demo prints means.
REAL_TIME_FACTOR = ("real-time factor: seconds of the contact run simulated per second of wall "
                    "time, with the model and its detector in the loop (2× is twice as fast "
                    "as the robot's clock; below 1× the simulation ran slower than real time, "
                    "as on a busy machine)")
#: The share of the training rows (whole runs, those farthest from the others) the hybrid's
#: out-of-domain std is calibrated on (:class:`DomainCalibratedHybrid`).
DOMAIN_HOLDOUT_SHARE = 0.2


#: One free-motion run of each of these kinds joins the training data, so that held-out runs
#: of these kinds stay inside the training ranges the thresholds were calibrated on.
OTHER_KINDS = ("random", "z_rich", "reference")
#: Training runs of the ``task_covering`` kind (motion planned from the task: the approaches to
#: every surface, the wall's included; ``benchmarks/excitation_detection.py`` measures what
#: they change in detection, figures in docs, Derivations).
TASK_COVERING_RUNS = 2


def run_demo(out: Path, config: ScenarioConfig | None = None, *, fourier: int = 4,
             rehearsals: int = 3, duration: float = 20.0, other_kinds=OTHER_KINDS,
             other_surfaces: bool = False, task_covering: int = TASK_COVERING_RUNS,
             meshcat_html: bool = True, progress: bool = True) -> dict:
    """Runs the three steps of the module docstring; writes ``summary.json``, the contact
    logs, the models and ``contact.png`` (and ``replay.html`` with `meshcat_html`) into `out`
    and returns the summary."""
    config = config or ScenarioConfig()
    stages = Stages(4, label="[demo]", progress=progress)
    surfaces = len(config.task.surfaces) - 1 if other_surfaces else 0
    runs = (fourier + rehearsals + len(other_kinds) + surfaces + task_covering - 1,
            1 + len(other_kinds) + surfaces + 1)  # one rehearsal held out of training
    stages.start("collect", f"simulating {sum(runs)} free-motion runs of the arm at 1 kHz "
                 f"({runs[0]} to train on, {runs[1]} held out)")
    data, held_out = _collect_free_motion(config, fourier, rehearsals, duration, other_kinds,
                                          other_surfaces, task_covering, progress)
    validation_id = fourier + rehearsals - 1  # a rehearsal: free motion like the task's
    train = data[data["trajectory"] != validation_id]
    validation = data[data["trajectory"] == validation_id]
    stages.start("train", f"fitting the forest (a grid search, folds grouped by run) and the "
                 f"hybrid (payload, mounting, cross-talk, cable; then a forest) on "
                 f"{-(-len(train) // 4)} rows, then each model's detector thresholds on the "
                 "held-out runs")
    models, search, X, hybrid_fit_s = _train(train, progress)
    detectors = _calibrate_detectors(models, config, validation, held_out)

    stages.start("contact scenario", "simulating the contact scenario once with each model "
                 "and its detector in the loop")
    scenario = dc.replace(
        config,
        trajectory=dc.replace(config.trajectory, kind="contact", seed=HELD_OUT_SEED),
        sensor=dc.replace(config.sensor, seed=HELD_OUT_SEED),
    )
    results, logs, meshcat = _contact_runs(models, detectors, scenario, config, validation,
                                           meshcat_html, progress)
    _describe_models(results, models, search, hybrid_fit_s)
    results["hybrid"]["domain_coverage"] = domain_coverage(
        models["hybrid"], *held_out_rows(config, validation, held_out))

    stages.start("write", f"writing the summary, contact.png, the models and the logs to {out}")
    summary = {
        "models": results,
        "better": better_model(results),
        "contact_scenario_s": float(logs["forest"]["t"].iloc[-1]),
        "training_rows": len(X),
        "training_trajectories": int(train["trajectory"].nunique()),
        "false_positives_per_hour_budget": config.chain.detector.false_positives_per_hour,
        "sensor_preset": scenario.sensor.preset,
        "held_out_seed": HELD_OUT_SEED,
    }
    _write(out, summary, logs, models, meshcat, stages)
    stages.finish()
    return summary


def _collect_free_motion(config, fourier, rehearsals, duration, other_kinds, other_surfaces,
                         task_covering, progress):
    """The training data (Fourier runs, rehearsals, one run of each other kind, with
    `other_surfaces` a rehearsal at each other surface, and `task_covering` runs of that kind)
    and the held-out runs."""
    free = collect(config, fourier, kind="fourier", duration=duration, progress=progress)
    rehearsal = collect(config, rehearsals, kind="rehearsal", seed=100, progress=progress)
    rehearsal["trajectory"] += fourier
    others = []
    for i, kind in enumerate(other_kinds):
        run = collect(config, 1, kind=kind, seed=200 + i, duration=duration, progress=progress)
        run["trajectory"] += fourier + rehearsals + i
        others.append(run)
    # The task's other surfaces (the wall): one rehearsal each, trained on and held out.
    surfaces = [dc.replace(config, trajectory=dc.replace(config.trajectory, contact_target=name))
                for name in config.task.surfaces
                if other_surfaces and name != config.trajectory.contact_target]
    for j, surface in enumerate(surfaces):
        run = collect(surface, 1, kind="rehearsal", seed=150 + j, progress=progress)
        run["trajectory"] += fourier + rehearsals + len(other_kinds) + j
        others.append(run)
    if task_covering:  # the task's approaches, the wall's too: trained on, not held out
        run = collect(config, task_covering, kind="task_covering", duration=duration,
                      progress=progress)
        run["trajectory"] += fourier + rehearsals + len(other_kinds) + len(surfaces)
        others.append(run)
    data = pd.concat([free, rehearsal, *others], ignore_index=True)
    # Held out, with the held-out rehearsal: one run of each kind the arm will move in; the
    # thresholds are calibrated on all of it (a budget calibrated on rehearsals alone holds
    # for rehearsal-like motion only).
    held_out = pd.concat([
        *(collect(config, 1, kind=kind, seed=300 + i, duration=duration, progress=progress)
          for i, kind in enumerate(("fourier", *other_kinds))),
        *(collect(surface, 1, kind="rehearsal", seed=350 + j, progress=progress)
          for j, surface in enumerate(surfaces))], ignore_index=True)
    if data[col.CONTACT_TRUE].any() or held_out[col.CONTACT_TRUE].any():
        raise RuntimeError("training data touched the environment; it must be contact-free")
    return data, held_out


def _train(train, progress):
    """The study's forest (tuned, grouped folds) and the hybrid, on the same rows."""
    every = 4  # 250 Hz of a 1 kHz log is plenty for a position-only forest
    X, Y = joint_state_layout(train)[::every], wrench_targets(train)[::every]
    groups = segment_groups(train["trajectory"].to_numpy()[::every])
    forest, search = tune(
        RandomForestCompensator(features="q", per_output=False, random_state=0),
        X, Y, groups=groups, preset="quick", cv="grouped", n_jobs=-1, progress=progress,
    )
    with warnings.catch_warnings():
        # Excitation is reported in the summary (condition number), not as a warning here.
        warnings.simplefilter("ignore", ExcitationWarning)
        started = time.perf_counter()
        # One growth for all axes (in units of their training error): calibrated on two
        # or three runs, a growth per axis did not carry over to other runs (the guide).
        # σ²_in from the held-out runs too, one multiple of each axis' training error: the
        # cross-fit's, from rows about a run away, over-covered next to the data (the guide).
        hybrid = DomainCalibratedHybrid(demo_hybrid(), holdout=DOMAIN_HOLDOUT_SHARE,
                                        shared_growth=True, in_domain="held_out").fit(
            X, Y, groups=train["trajectory"].to_numpy()[::every])
        seconds = time.perf_counter() - started
    return {"forest": forest, "hybrid": hybrid}, search, X, seconds


def demo_hybrid() -> HybridCompensator:
    """The demo's hybrid, unfitted (what each option is for is said beside it)."""
    return HybridCompensator(physics=PhysicsPayloadCompensator(
        # A sensor is rarely mounted exactly as its model says; the rotation is identified
        # with the payload (default_residual on what is left).
        identify_mounting=True,
        # The sensor's cross-talk too, in the prediction of the readings (a contact is
        # still mapped to S by the rotation alone: reading_to_model_frame).
        identify_crosstalk=True,
        # A cable's hanging weight is not tool mass: its own 4 parameters, so the
        # payload's inertia is not inflated by it.
        weight_without_inertia=True,
        # Its pull depends on the configuration, which a residual on q learns only where
        # the data went: a tether, its far end found among the arm's frames.
        tether="auto"))


def domain_coverage(model, X, Y) -> dict:
    """The hybrid's 95 % coverage per axis on rows `X`, `Y` (held out, contact-free) in each
    distance bin of :data:`~ftdrake.compensation.estimators.domain.DISTANCE_BINS` (in domain, its
    edge, out of domain), with the bin's rows and their median distance d."""
    mean, std = model.predict(X), model.predict_std(X)
    d = model.domain_distance(X)
    out = {}
    for name, (lo, hi) in DISTANCE_BINS.items():
        rows = (d >= lo) & (d < hi)
        out[name] = {"distance": [lo, hi if np.isfinite(hi) else None],
                     "rows": int(rows.sum()),
                     "median_distance": float(np.median(d[rows])) if rows.any() else None,
                     "coverage_95": (coverage(Y[rows], mean[rows], std[rows]).round(4).tolist()
                                     if rows.any() else None)}
    return out


def held_out_rows(config, *frames):
    """(X, Y) of the samples the detector judges in the held-out runs `frames`."""
    data = pd.concat(frames, ignore_index=True)
    judged = armed(data[col.TIME].to_numpy(), config.chain.detector.arm_after_s)
    return joint_state_layout(data)[judged], wrench_targets(data)[judged]


def _calibrate_detectors(models, config, validation, held_out) -> dict:
    """Each model's thresholds from its residual on the judged samples of the validation
    rehearsal and the held-out runs, for the scenario's false-positive budget and the test
    ``detector.test`` gives that model (``auto``: χ² for the hybrid, norm for the forest)."""
    X_cal, Y_cal = held_out_rows(config, validation, held_out)
    rate_hz = config.sensor.spec().rate_hz
    detectors = {}
    for name, model in models.items():
        test = config.chain.detector.for_model(model, calibrating=True).test
        detectors[name] = thresholds_for_false_positive_rate(
            Y_cal - model.predict(X_cal), sample_rate_hz=rate_hz,
            false_positives_per_hour=config.chain.detector.false_positives_per_hour, test=test,
            std=model.predict_std(X_cal) if test == "chi2" else None)
    return detectors


def _contact_runs(models, detectors, scenario, config, validation, meshcat_html, progress):
    """Each model and its detector in the loop on the contact scenario, scored against the
    plant's truth; the hybrid's run recorded in Meshcat with `meshcat_html`."""
    judged = armed(validation[col.TIME].to_numpy(), config.chain.detector.arm_after_s)
    X_val, Y_val = joint_state_layout(validation)[judged], wrench_targets(validation)[judged]
    meshcat = None
    results, logs = {}, {}
    for name, model in models.items():
        if meshcat_html and name == "hybrid":
            meshcat = recording_meshcat()
            meshcat.StartRecording(set_visualizations_while_recording=False)
        run = simulate(build_station(scenario.with_chain(detector=detectors[name]), model,
                                     meshcat=meshcat if name == "hybrid" else None),
                       progress=progress)
        logs[name] = run.log
        residual = Y_val - model.predict(X_val)
        results[name] = {
            **evaluate_detection(run.log, scenario.sensor.spec().noise_std),
            "real_time_factor": run.timing["real_time_factor"],
            "detector": dc.asdict(detectors[name]),
            "validation_residual_rms": {
                "force_n": float(np.sqrt(np.mean(np.sum(residual[:, :3] ** 2, axis=1)))),
                "torque_nm": float(np.sqrt(np.mean(np.sum(residual[:, 3:] ** 2, axis=1)))),
            },
        }
    return results, logs, meshcat


def _describe_models(results: dict, models: dict, search, hybrid_fit_s: float) -> None:
    """What each model is, for the summary: the forest's tuned parameters, the hybrid's
    identified physics and its domain calibration (with the fit's time, s)."""
    hybrid = models["hybrid"]
    results["forest"]["model"] = {"class": "RandomForestCompensator", "features": "q",
                                  "per_output": False, **search.best_params[0]}
    results["forest"]["tuning"] = {"preset": "quick", "cv": "grouped",
                                   "n_candidates": search.n_candidates,
                                   "best_cv_mse": -search.mean_score[0]}
    results["hybrid"]["model"] = {
        "class": "HybridCompensator",
        "physics": ("dynamic payload + biases + weight without inertia + tether (22 "
                    "parameters) + mounting rotation"),
        "tether": hybrid.physics_.identified()["tether"],
        "weight_without_inertia": {
            "mass_kg": round(float(hybrid.physics_.parameters_[16]), 4),
            "first_moment_kgm": np.round(hybrid.physics_.parameters_[17:20], 5).tolist()},
        "payload_mass_kg": round(float(hybrid.physics_.parameters_[0]), 4),
        "mounting_rpy_deg": np.degrees(RollPitchYaw(RotationMatrix(
            hybrid.physics_.mounting_rotation_)).vector()).round(3).tolist(),
        "residual": {"class": "RandomForestCompensator", "features": "q",
                     **{k: hybrid.residual_.get_params()[k]
                        for k in ("n_estimators", "max_features", "min_samples_leaf")}},
        "physics_condition_number": hybrid.physics_.condition_number_,
        "domain_calibration": {**hybrid.domain_calibration_, "fit_time_s": hybrid_fit_s},
    }


def _write(out, summary, logs, models, meshcat, stages) -> None:
    with staged_outputs(out) as staging:
        plot_contact_comparison(logs, staging / "contact.png")
        for name, log in logs.items():
            write_log(log, staging / f"contact_log_{name}.parquet")
        for name, model in models.items():
            save_model(model, staging / f"model_{name}.ftd", target_names=col.WRENCH_AXES,
                       target_units=col.WRENCH_UNITS, sensor_frame="S")
        if meshcat is not None:
            meshcat.StopRecording()
            meshcat.PublishRecording()
            (staging / "replay.html").write_text(meshcat.StaticHtml())
        summary["wall_time_s"] = stages.clock() - stages.started
        summary["stage_times_s"] = stages.times()
        summary["provenance"] = result_provenance()
        with atomic_path(staging / "summary.json") as tmp:
            tmp.write_text(json.dumps(summary, indent=2))


def better_model(results: dict) -> str:
    """The model with fewer false positives and misses, then the lower worst free-motion
    error over the sensor noise (the detector's thresholds follow from that error)."""
    def key(name):
        r = results[name]
        return (r["false_positives"] + r["missed_contacts"],
                max(r["compensation_error_over_noise"]))
    return min(results, key=key)


def print_table(summary: dict) -> None:
    """The demo's headline numbers, the two models side by side."""
    names = list(summary["models"])
    results = [summary["models"][n] for n in names]
    head = "".join(f"{n + (' (better)' if n == summary['better'] else ''):>22}" for n in names)
    rows = [
        ("contacts detected / true",
         [f"{r['detected_contacts']} / {r['true_contacts']}" for r in results]),
        ("detection delay", [f"{_fmt(r['detection_delay_s'], 1000)} ms" for r in results]),
        ("false positives (free motion)", [str(r["false_positives"]) for r in results]),
        ("missed contacts", [str(r["missed_contacts"]) for r in results]),
        ("detector threshold", [threshold_text(r["detector"]) for r in results]),
        ("real-time factor, in the loop ¹", [f"{r['real_time_factor']:.1f}×" for r in results]),
    ]
    print(f"\n  {'':<34}{head}")
    for label, values in rows:
        print(f"  {label:<34}" + "".join(f"{v:>22}" for v in values))
    print(f"  ¹ {REAL_TIME_FACTOR}")
    print("\n  free-motion compensation error RMS / sensor noise σ, and contact error RMS after "
          "touchdown:")
    print(f"  {'axis':<6}" + "".join(f"{n + ' err/σ':>16}{n + ' contact':>20}" for n in names))
    for i, (axis, unit) in enumerate(zip(col.WRENCH_AXES, col.WRENCH_UNITS, strict=True)):
        cells = "".join(
            f"{r['compensation_error_over_noise'][i]:>16.2f}"
            f"{r['external_wrench_error_rms_after_touchdown'][i]:>15.4f} {unit:<4}"
            for r in results)
        print(f"  {axis:<6}{cells}")
    print()
    bins = summary["models"].get("hybrid", {}).get("domain_coverage")
    if bins:
        print("  hybrid's std, 95 % coverage per axis (Fx … Tz) on the held-out runs, by "
              "distance d to its training inputs:")
        for name, b in bins.items():
            lo, hi = b["distance"]
            where = f"{lo:g} ≤ d" + (f" < {hi:g}" if hi is not None else "")
            cells = ("–" if not b["rows"]
                     else " ".join(f"{c:.3f}" for c in b["coverage_95"]) + f"  ({b['rows']} rows)")
            print(f"  {name.replace('_', ' '):<15}{where:<12}{cells}")
        print()


def _fmt(value, scale):
    if value is None:
        return "–"
    if isinstance(value, list):
        return ", ".join(f"{v * scale:.0f}" for v in value)
    return f"{value * scale:.0f}"
