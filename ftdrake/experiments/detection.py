"""Contact detection evaluated like a safety function, on seeds no model was trained on.

For each compensator:

1. **Thresholds** from the false-positive budget (``detector.false_positives_per_hour``):
   held-out rehearsals of
   the task and held-out runs of each free-motion kind give the residual, and
   :func:`~ftdrake.offline.thresholds.thresholds_for_false_positive_rate` the thresholds
   (the norm test's, or with ``detector.test: chi2`` the χ² test's on the residual whitened
   by the model's std).
2. **False positives**: long free motion (default 10 simulated minutes) of several trajectory
   kinds, compensator and detector in the loop; every detection is a false positive.
3. **Misses and delays**: the contact scenario on the table and on the wall, commanded from
   1.5 mm above to 20 mm into the surface, which the controller's stiffness turns into contact
   forces from a fraction of a newton to about 100 N. Each press counts as detected when the
   detector fires while the tool touches; its force is the median true contact force ‖F‖
   after the touchdown transient. A run whose tool never touches counts only for false
   positives; a press the arm cannot make within its joint limits is reported, not run.
4. **Re-tare, grasp, slow push** (:mod:`ftdrake.experiments.tracking`): with the bias tracker
   and without it, against the same run without the event.

The loop runs as ``config`` says: with the bias tracker when ``bias_tracker.enabled``.
:func:`run_plan` simulates each model in the loop; :mod:`.detection_replay` simulates each
run once and replays every model's chain over it (the in-loop numbers, as the chain does not
move the arm; what ``ftdrake evaluate-detection`` does unless ``--in-loop``).

Every run is independent and runs in parallel (joblib); each worker builds its station from
the config's YAML. Outputs: ``detection.json``, ``detection.md`` (tables) and
``detection_rate.png`` (detection rate against contact force per model, like an ROC); with
the replay and a model that has a support (the hybrid) also
``detectable_force_vs_domain.png`` (:mod:`.detection_domain`).
"""

from __future__ import annotations

import dataclasses as dc
import itertools
import json
from pathlib import Path

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from tqdm.auto import tqdm

from .. import conventions as col
from ..config import (
    DetectorConfig,
    ScenarioConfig,
    dump_config,
    model_has_reading_std,
    parse_config,
)
from ..data.dataset import joint_state_layout, wrench_targets
from ..errors import TrajectoryError
from ..io import atomic_path, staged_outputs
from ..offline.thresholds import armed, threshold_text, thresholds_for_false_positive_rate
from ..plots import plt
from ..sim.collection import collect
from ..sim.evaluation import TOUCHDOWN_S, evaluate_detection
from ..sim.simulate import simulate
from ..sim.station import build_station
from ..version import result_provenance
from . import tracking
from .detection_domain import markdown as domain_markdown
from .detection_domain import plot_detectable_force_vs_domain

FREE_KINDS = ("fourier", "random", "z_rich", "reference")
# Commanded depth into the surface (mm). The controller's model of the tool is 15 % too light,
# so the arm sags and already presses ~2 N at 0.1 mm on the table; light touches need a
# command slightly above the surface (negative), and some of those never touch.
DEPTHS_MM = (-1.5, -1.0, -0.6, -0.3, 0.0, 0.3, 1.0, 3.0, 6.0, 12.0, 20.0)
SURFACES = ("table", "wall")
FREE_RUN_S = 30.0  # free motion is cut into runs this long (parallel, and several seeds)
CALIBRATION_RUN_S = 20.0  # held-out runs of each kind that set the thresholds
SEED = 5000  # trajectories and noise from here on: never used by demo, study or tests


@dc.dataclass
class DetectionPlan:
    """What to run; the defaults: 10 simulated minutes of free motion, presses on table and
    wall."""

    free_minutes: float = 10.0
    kinds: tuple[str, ...] = FREE_KINDS
    depths_mm: tuple[float, ...] = DEPTHS_MM
    surfaces: tuple[str, ...] = SURFACES
    # Overrides the scenario's detector.false_positives_per_hour (None: keep it).
    false_positives_per_hour: float | None = None
    rehearsals: int = 2  # held-out rehearsals that set the thresholds ...
    # ... with this many held-out runs (CALIBRATION_RUN_S) of each of `kinds`: the motion the
    # detector will see (seeds of their own, not the evaluation's).
    calibration_runs_per_kind: int = 1
    seed: int = SEED
    # The tracker's events (re-tare, grasp, slow push); None skips them.
    events: tracking.EventPlan | None = dc.field(default_factory=tracking.EventPlan)
    # The detector tests each model is evaluated with, e.g. ("norm", "chi2"): one result per
    # model and test, named "model (test)"; None: the scenario's detector.test alone.
    tests: tuple[str, ...] | None = None

    @classmethod
    def quick(cls, free_minutes: float = 2.0, **changes) -> DetectionPlan:
        """A short plan: `free_minutes` of free motion, five presses per surface (from a
        light touch to 20 mm), one held-out rehearsal and run per kind for the thresholds,
        no tracker events; a few minutes on two cores instead of the full plan's hour."""
        return cls(free_minutes=free_minutes, depths_mm=(-0.6, 0.0, 1.0, 6.0, 20.0),
                   rehearsals=1, events=None, **changes)


def with_tests(models: dict, plan: DetectionPlan) -> dict:
    """{result name: (model, test or None)}: each model once (the scenario's test), or with
    `plan.tests` once per test, named "model (test)" — the χ² test only for models whose
    std is that of a reading (a forest's is not: the chain refuses it)."""
    if not plan.tests:
        return {name: (model, None) for name, model in models.items()}
    for test in plan.tests:
        if test not in ("norm", "chi2"):
            raise ValueError(f"DetectionPlan.tests: {test!r} is not 'norm' or 'chi2'")
    return {f"{name} ({test})": (model, test) for name, model in models.items()
            for test in plan.tests if test != "chi2" or model_has_reading_std(model)}


def with_test(config: ScenarioConfig, test: str | None) -> ScenarioConfig:
    """`config` with its detector's test set to `test` (None: as it is)."""
    if test is None:
        return config
    return config.with_chain(detector=dc.replace(config.chain.detector, test=test))


def thresholds_from_held_out(model, config: ScenarioConfig, plan: DetectionPlan,
                             n_jobs: int = -1, data: pd.DataFrame | None = None
                             ) -> DetectorConfig:
    """Detector thresholds for `model` from held-out free motion — the plan's rehearsals and
    runs of each of its kinds, on seeds the evaluation does not use — and the scenario's
    budget, ``config.chain.detector.false_positives_per_hour``. The runs of each kind are there
    because a budget calibrated on rehearsals alone holds on rehearsal-like motion only.
    `data`: that motion (:func:`held_out_motion`) when already collected."""
    data = held_out_motion(config, plan, n_jobs) if data is None else data
    judged = armed(data[col.TIME].to_numpy(), config.chain.detector.arm_after_s)
    X = joint_state_layout(data)[judged]
    residual = wrench_targets(data)[judged] - model.predict(X)
    # "auto" resolved for this model; the χ² test whitens by its std on the same rows.
    test = config.chain.detector.for_model(model, calibrating=True).test
    return thresholds_for_false_positive_rate(
        residual, sample_rate_hz=config.sensor.spec().rate_hz,
        false_positives_per_hour=config.chain.detector.false_positives_per_hour, test=test,
        std=model.predict_std(X) if test == "chi2" else None)


def held_out_motion(config: ScenarioConfig, plan: DetectionPlan, n_jobs: int = -1
                    ) -> pd.DataFrame:
    """The held-out free motion the thresholds come from (no model in it: collect once for
    every model)."""
    runs = [collect(config, plan.rehearsals, kind="rehearsal", seed=plan.seed + 900,
                    n_jobs=n_jobs, progress=False)]
    for k, kind in enumerate(plan.kinds):
        if plan.calibration_runs_per_kind:
            runs.append(collect(config, plan.calibration_runs_per_kind, kind=kind,
                                seed=plan.seed + 950 + 10 * k, duration=CALIBRATION_RUN_S,
                                n_jobs=n_jobs, progress=False))
    return pd.concat(runs, ignore_index=True)


def run_plan(models: dict, config: ScenarioConfig, plan: DetectionPlan, *, n_jobs: int = -1,
             progress: bool = True) -> dict:
    """Runs the plan for each named model with that model in the loop; returns thresholds,
    free-motion and press results (:func:`.detection_replay.run_plan_by_replay` gives the
    same numbers faster: the detector does not move the arm)."""
    results = {}
    for name, (model, test) in with_tests(models, plan).items():
        detector = thresholds_from_held_out(model, with_test(config, test), plan, n_jobs)
        base = config.with_chain(detector=detector)
        jobs = _free_jobs(base, plan) + _press_jobs(base, plan)
        runs = Parallel(n_jobs=n_jobs, return_as="generator")(
            delayed(_closed_loop_run)(yaml_text, model, meta) for yaml_text, meta in jobs)
        rows = list(tqdm(runs, total=len(jobs), desc=f"detection ({name})", unit="run",
                         disable=not progress))
        results[name] = model_result(detector, rows)
    return results


def model_result(detector: DetectorConfig, rows: list[dict]) -> dict:
    """One model's results from its runs' rows: thresholds, summary, runs, skipped runs."""
    skipped = [r for r in rows if "skipped" in r]
    rows = [r for r in rows if "skipped" not in r]
    free = [r for r in rows if r["kind"] != "contact" or not r["true_contacts"]]
    presses = [r for r in rows if r["kind"] == "contact" and r["true_contacts"]]
    return {"detector": dc.asdict(detector), **summarise(free, presses),
            "runs_not_made": len(skipped), "free_runs": free, "presses": presses,
            "skipped": skipped}


def summarise(free: list[dict], presses: list[dict]) -> dict:
    """False-positive rate, misses, delays and the smallest reliably detected force."""
    free_s = sum(r["duration_s"] for r in free)
    # Every run counts its detections outside true contact (± 0.5 s), presses included.
    false_positives = sum(r["false_positives"] for r in free + presses)
    detected = [p for p in presses if p["detected"]]
    forces = sorted(p["force_n"] for p in presses)
    # The smallest force from which on every press (at that force or more) was detected.
    reliable = None
    for f in reversed(forces):
        if all(p["detected"] for p in presses if p["force_n"] >= f):
            reliable = f
    strong = [p["delay_s"] for p in detected if p["force_n"] >= 5.0]
    return {
        "free_motion_s": free_s,
        "false_positives": false_positives,
        "false_positives_per_hour": false_positives / free_s * 3600 if free_s else None,
        "press_count": len(presses),
        "missed": len(presses) - len(detected),
        "smallest_reliably_detected_force_n": reliable,
        "max_delay_s_presses_from_5n": max(strong) if strong else None,
    }


def _free_jobs(base: ScenarioConfig, plan: DetectionPlan) -> list:
    per_kind = plan.free_minutes * 60.0 / len(plan.kinds)
    runs = max(1, round(per_kind / FREE_RUN_S))
    jobs = []
    for k, kind in enumerate(plan.kinds):
        for i in range(runs):
            seed = plan.seed + 100 * k + i
            config = _with(base, kind=kind, duration_s=per_kind / runs, seed=seed)
            jobs.append((dump_config(config), {"kind": kind, "seed": seed}))
    return jobs


def _press_jobs(base: ScenarioConfig, plan: DetectionPlan) -> list:
    jobs = []
    for s, surface in enumerate(plan.surfaces):
        for d, depth in enumerate(plan.depths_mm):
            seed = plan.seed + 1000 + 100 * s + d
            config = _with(base, kind="contact", seed=seed, contact_target=surface,
                           press_depth_m=depth / 1000.0)
            jobs.append((dump_config(config), {"kind": "contact", "surface": surface,
                                               "depth_mm": depth, "seed": seed}))
    return jobs


def _with(base: ScenarioConfig, *, seed: int, **trajectory) -> ScenarioConfig:
    return dc.replace(base, trajectory=dc.replace(base.trajectory, seed=seed, **trajectory),
                      sensor=dc.replace(base.sensor, seed=seed))


def _closed_loop_run(config_yaml: str, model, meta: dict) -> dict:
    config = parse_config(config_yaml)
    try:
        station = build_station(config, model)
    except TrajectoryError as e:  # e.g. a press the arm cannot reach within its limits
        return {**meta, "skipped": str(e)}
    return run_row(simulate(station, progress=False).log, config, meta)


def run_row(log: pd.DataFrame, config: ScenarioConfig, meta: dict,
            replayed: pd.DataFrame | None = None) -> dict:
    """A run's row from its log (and the chain's outputs `replayed` over it, if given)."""
    metrics = evaluate_detection(log, config.sensor.spec().noise_std, replayed)
    row = {**meta, "duration_s": float(log[col.TIME].iloc[-1]),
           "false_positives": metrics["false_positives"]}
    if meta["kind"] == "contact":
        t = log[col.TIME].to_numpy()
        touching = log[col.CONTACT_TRUE].to_numpy().astype(bool)
        onset = t[np.argmax(touching)] if touching.any() else np.inf
        steady = touching & (t >= onset + TOUCHDOWN_S)
        force = np.linalg.norm(log[col.wrench_columns(col.EXTERNAL_TRUE)[:3]].to_numpy(), axis=1)
        row.update(
            force_n=float(np.median(force[steady])) if steady.any() else 0.0,
            detected=metrics["missed_contacts"] == 0 and metrics["true_contacts"] > 0,
            delay_s=metrics["detection_delay_s"] if metrics["true_contacts"] == 1 else None,
            true_contacts=metrics["true_contacts"],
        )
    return row


# -- report ------------------------------------------------------------------------------------
def markdown(results: dict, plan: DetectionPlan) -> str:
    """Tables of the evaluation: per model, then every press. The title's budget is the
    plan's, or (without one) what each model's detector was calibrated for."""
    budgets = ([plan.false_positives_per_hour] if plan.false_positives_per_hour is not None
               else sorted({r["detector"]["false_positives_per_hour"] for r in results.values()}))
    title = (f"# Contact detection, evaluated on unseen seeds (budget "
             f"{', '.join(f'{b:g}' for b in budgets)} false positive per hour)")
    lines = [title, "",
             ("| model | thresholds | free motion | false positives | presses missed | "
              "smallest force detected (and every larger one) | worst delay, presses ≥ 5 N | "
              "runs not made |"),
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name, r in results.items():
        d = r["detector"]
        delay = r["max_delay_s_presses_from_5n"]
        smallest = r["smallest_reliably_detected_force_n"]
        lines.append(
            f"| {name} | {threshold_text(d)} "
            f"| {r['free_motion_s'] / 60:.1f} min | {r['false_positives']} "
            f"| {r['missed']} of {r['press_count']} "
            f"| {'–' if smallest is None else f'{smallest:.2f} N'} "
            f"| {'–' if delay is None else f'{delay * 1000:.0f} ms'} "
            f"| {_not_made(r)} |")
    for name, r in results.items():
        for run in r.get("skipped", []):
            lines.append(f"\n{name}: run not made ({run['kind']}, {run.get('surface', '')} "
                         f"{run.get('depth_mm', '')} mm, seed {run['seed']}): {run['skipped']}")
    lines += ["", ("| model | surface | commanded depth | contact force | detected | delay |"),
              "| --- | --- | --- | --- | --- | --- |"]
    for name, r in results.items():
        for p in r["presses"]:
            delay = "–" if p["delay_s"] is None else f"{p['delay_s'] * 1000:.0f} ms"
            lines.append(f"| {name} | {p['surface']} | {p['depth_mm']:g} mm "
                         f"| {p['force_n']:.2f} N | {'yes' if p['detected'] else '**no**'} "
                         f"| {delay} |")
    return "\n".join(lines) + "\n" + domain_markdown(results)


def _not_made(result: dict) -> str:
    """The runs of a model's plan that could not be made, as the table's cell: how many and
    of which kinds (the reasons follow the table); 0 when all were made."""
    skipped = result.get("skipped", [])
    if not skipped:
        return "0"
    kinds = sorted({f"{r['kind']} {r.get('surface', '')}".strip() for r in skipped})
    return f"**{len(skipped)}** ({', '.join(kinds)})"


def plot_detection_rate(results: dict, path: Path) -> None:
    """Detection rate against contact force (log scale), one line per model."""
    fig, ax = plt.subplots(figsize=(7, 4))
    edges = np.logspace(np.log10(0.1), np.log10(100), 13)
    centres = np.sqrt(edges[:-1] * edges[1:])
    for name, r in results.items():
        forces = np.array([p["force_n"] for p in r["presses"]])
        hits = np.array([p["detected"] for p in r["presses"]], dtype=float)
        rate = [hits[(forces >= a) & (forces < b)].mean() if ((forces >= a) & (forces < b)).any()
                else np.nan for a, b in itertools.pairwise(edges)]
        ax.plot(centres, rate, "o-", label=f"{name} ({r['false_positives']} false positives in "
                f"{r['free_motion_s'] / 60:.0f} min)")
    ax.set_xscale("log")
    ax.set_xlabel("contact force ‖F‖ [N]")
    ax.set_ylabel("detection rate")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("contact detection on unseen seeds (table and wall)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_detection_evaluation(out: Path, models: dict, config: ScenarioConfig | None = None,
                             plan: DetectionPlan | None = None, *, n_jobs: int = -1,
                             progress: bool = True, run=None) -> dict:
    """Runs `plan` for `models` (name → fitted compensator); writes the JSON, tables, plot.
    `run`: how the plan runs, :func:`run_plan` (each model in the loop; the default) or
    :func:`.detection_replay.run_plan_by_replay` (each run simulated once, every model
    replayed over it)."""
    config = config or ScenarioConfig()
    plan = plan or DetectionPlan()
    if plan.false_positives_per_hour is not None:
        config = config.with_chain(detector=dc.replace(
            config.chain.detector, false_positives_per_hour=plan.false_positives_per_hour))
    run = run or run_plan
    results = run(models, config, plan, n_jobs=n_jobs, progress=progress)
    events = None
    if plan.events is not None:
        tuned = {name: (model, DetectorConfig(**results[name]["detector"]))
                 for name, (model, _) in with_tests(models, plan).items()}
        events = tracking.run_events(tuned, config, plan.events, seed=plan.seed + 2000,
                                     n_jobs=n_jobs, progress=progress)
    with staged_outputs(out) as staging:
        with atomic_path(staging / "detection.json") as tmp:
            tmp.write_text(json.dumps({"plan": dc.asdict(plan), "models": results,
                                       "tracker_events": events,
                                       "provenance": result_provenance()}, indent=2))
        text = markdown(results, plan)
        if events is not None:
            text += "\n" + tracking.markdown(events, plan.events)
        (staging / "detection.md").write_text(text)
        plot_detection_rate(results, staging / "detection_rate.png")
        plot_detectable_force_vs_domain(results, staging / "detectable_force_vs_domain.png")
    return results
