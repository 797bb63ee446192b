"""The main job: collect → train → contact scenario with the compensator in the loop.

1. Collect free-motion data: Fourier excitation around the home pose, plus rehearsals of the
   task in the air (the contact scenario stopping 3 cm above the table) — on a real robot you
   would record the same: the task's motions without contact.
2. Train a multi-output random forest on joint positions (the study's best feature set for
   slow motion) with the `quick` grid and folds grouped by trajectory segment. One rehearsal
   is held out to set the detector's thresholds from the free-motion residual on the task.
3. Run the contact scenario with a trajectory seed and sensor noise not seen in training,
   compensator and detector in the loop at the sensor rate, and score it against the plant's
   ground truth.
"""

from __future__ import annotations

import dataclasses as dc
import json
import time
from pathlib import Path

import numpy as np

from .. import conventions as col
from ..compensation.forest import RandomForestCompensator
from ..compensation.persistence import save_model
from ..compensation.tuning import segment_groups, tune
from ..config import DetectorConfig, ScenarioConfig
from ..data.dataset import joint_state_layout, wrench_targets
from ..io import atomic_path, staged_outputs
from ..sim.collection import collect
from ..sim.evaluation import evaluate_detection
from ..sim.simulate import simulate
from ..sim.station import build_station

HELD_OUT_SEED = 1000


def run_demo(out: Path, config: ScenarioConfig | None = None, *, fourier: int = 4,
             rehearsals: int = 3, duration: float = 20.0, meshcat_html: bool = True,
             progress: bool = True) -> dict:
    config = config or ScenarioConfig()
    started = time.perf_counter()
    stages = {}

    def stage(name):
        stages[name] = time.perf_counter()
        if progress:
            print(f"[demo] {name} …", flush=True)

    stage("collect")
    free = collect(config, fourier, kind="fourier", duration=duration, progress=progress)
    rehearsal = collect(config, rehearsals, kind="rehearsal", seed=100, progress=progress)
    rehearsal["trajectory"] += fourier
    import pandas as pd

    data = pd.concat([free, rehearsal], ignore_index=True)
    if data[col.CONTACT].any():
        raise RuntimeError("training data touched the environment; it must be contact-free")

    stage("train")
    validation_id = fourier + rehearsals - 1  # a rehearsal: free motion like the task's
    train = data[data["trajectory"] != validation_id]
    validation = data[data["trajectory"] == validation_id]
    every = 4  # 250 Hz of a 1 kHz log is plenty for a position-only forest
    X, Y = joint_state_layout(train)[::every], wrench_targets(train)[::every]
    groups = segment_groups(train["trajectory"].to_numpy()[::every])
    model, search = tune(
        RandomForestCompensator(features="q", per_output=False, random_state=0),
        X, Y, groups=groups, preset="quick", cv="grouped", n_jobs=-1, progress=progress,
    )
    residual = wrench_targets(validation) - model.predict(joint_state_layout(validation))
    force_rms = float(np.sqrt(np.mean(np.sum(residual[:, :3] ** 2, axis=1))))
    torque_rms = float(np.sqrt(np.mean(np.sum(residual[:, 3:] ** 2, axis=1))))
    detector = DetectorConfig.from_residuals(residual)

    stage("contact scenario")
    scenario = dc.replace(
        config,
        trajectory=dc.replace(config.trajectory, kind="contact", seed=HELD_OUT_SEED),
        sensor=dc.replace(config.sensor, seed=HELD_OUT_SEED),
        detector=detector,
    )
    meshcat = None
    if meshcat_html:
        from pydrake.geometry import Meshcat

        meshcat = Meshcat()
        meshcat.StartRecording(set_visualizations_while_recording=False)
    result = simulate(build_station(scenario, model, meshcat=meshcat), progress=progress)
    log, timing = result.log, result.timing
    metrics = evaluate_detection(log, scenario.sensor.spec().noise_std)

    stage("write")
    summary = {
        **metrics,
        "real_time_factor": timing["real_time_factor"],
        "contact_scenario_s": timing["duration_s"],
        "training_rows": len(X),
        "training_trajectories": int(train["trajectory"].nunique()),
        "model": {"class": "RandomForestCompensator", "features": "q", "per_output": False,
                  **search.best_params[0]},
        "tuning": {"preset": "quick", "cv": "grouped", "n_candidates": search.n_candidates,
                   "best_cv_mse": -search.mean_score[0]},
        "detector": detector.__dict__,
        "validation_residual_rms": {"force_n": force_rms, "torque_nm": torque_rms},
        "sensor_preset": scenario.sensor.preset,
        "held_out_seed": HELD_OUT_SEED,
    }
    from ..plots import plot_contact

    with staged_outputs(out) as staging:
        plot_contact(log, staging / "contact.png")
        log.to_parquet(staging / "contact_log.parquet", index=False)
        save_model(model, staging / "model.ftd", target_names=col.WRENCH_AXES,
                   target_units=col.WRENCH_UNITS, sensor_frame="S")
        if meshcat is not None:
            meshcat.StopRecording()
            meshcat.PublishRecording()
            (staging / "replay.html").write_text(meshcat.StaticHtml())
        summary["wall_time_s"] = time.perf_counter() - started
        summary["stage_times_s"] = _durations(stages, time.perf_counter())
        with atomic_path(staging / "summary.json") as tmp:
            tmp.write_text(json.dumps(summary, indent=2))
    return summary


def _durations(stages: dict, end: float) -> dict:
    names = list(stages)
    times = [stages[n] for n in names] + [end]
    return {n: round(times[i + 1] - times[i], 2) for i, n in enumerate(names)}


def print_table(summary: dict) -> None:
    """The demo's headline numbers as a small table."""
    rows = [
        ("contact detected / true", f"{summary['detected_contacts']} / {summary['true_contacts']}"),
        ("detection delay", f"{_fmt(summary['detection_delay_s'], 1000)} ms"),
        ("false positives (free motion)", str(summary["false_positives"])),
        ("missed contacts", str(summary["missed_contacts"])),
        ("real-time factor (in the loop)", f"{summary['real_time_factor']:.1f}×"),
    ]
    print()
    for name, value in rows:
        print(f"  {name:<34}{value:>16}")
    print(f"\n  {'axis':<6}{'free motion: comp. err RMS':>28}{'/ noise σ':>10}"
          f"{'contact: ext. err RMS':>23}{'after touchdown':>17}")
    for i, (axis, unit) in enumerate(zip(col.WRENCH_AXES, col.WRENCH_UNITS)):
        print(f"  {axis:<6}{summary['compensation_error_rms'][i]:>23.4f} {unit:<4}"
              f"{summary['compensation_error_over_noise'][i]:>10.1f}"
              f"{summary['external_wrench_error_rms'][i]:>18.4f} {unit:<4}"
              f"{summary['external_wrench_error_rms_after_touchdown'][i]:>12.4f} {unit}")
    print()


def _fmt(value, scale):
    if value is None:
        return "–"
    if isinstance(value, list):
        return ", ".join(f"{v * scale:.0f}" for v in value)
    return f"{value * scale:.0f}"
