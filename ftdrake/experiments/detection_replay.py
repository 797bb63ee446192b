"""The detection evaluation by replay: each run simulated once, every model replayed over it.

The runtime chain does not act on the arm — nothing in the station feeds the compensator's,
tracker's or detector's outputs back to the controller or the plant — so a run's motion,
contacts and sensor stream are the same whichever model is in the loop. :func:`run_plan_by_
replay` therefore simulates each run of a :class:`~.detection.DetectionPlan` once, without a
compensator, and replays each model's chain over the log
(:func:`ftdrake.offline.replay.replay` with the simulated station's pairing), which gives the
in-loop chain's numbers exactly (tests/offline/test_replay.py, to 1e-12). The held-out motion that
sets the thresholds is collected once for all models too.

A run goes through the loop (:func:`.detection._closed_loop_run`) instead when its replay
would not be the loop's numbers (:func:`replay_differs_from_loop`): today only with
``bias_tracker.track_payload``, whose tracker reads the apparent gravity from the plant's
kinematics in simulation but from the joint state in a replay. Should the station ever feed
the chain back (a controller reacting to contact, say), that test is where to say so. The
results count both kinds of run (``replayed_runs``, ``closed_loop_runs``).
"""

from __future__ import annotations

from joblib import Parallel, delayed
from tqdm.auto import tqdm

from ..config import ScenarioConfig, dump_config, parse_config
from ..errors import TrajectoryError
from ..offline.replay import replay
from ..sim.simulate import simulate
from ..sim.station import build_station
from .detection import (
    DetectionPlan,
    _closed_loop_run,
    _free_jobs,
    _press_jobs,
    held_out_motion,
    model_result,
    run_row,
    thresholds_from_held_out,
    with_test,
    with_tests,
)
from .detection_domain import (
    TESTS,
    detectable_force_vs_domain,
    free_motion_samples,
    has_domain,
)


def replay_differs_from_loop(config: ScenarioConfig) -> str | None:
    """Why a replay of `config`'s simulated run would not give the in-loop chain's numbers
    (None when it gives them): then the run needs the loop."""
    if config.chain.bias_tracker.enabled and config.chain.bias_tracker.track_payload:
        return ("bias_tracker.track_payload: in simulation the tracker's gravity comes from "
                "the plant's kinematics, in a replay from the joint state")
    return None


def run_plan_by_replay(models: dict, config: ScenarioConfig, plan: DetectionPlan, *,
                       n_jobs: int = -1, progress: bool = True) -> dict:
    """:func:`.detection.run_plan`'s results, each run simulated once for all `models`; for
    a model with a support (the hybrid) also ``detectable_force_vs_domain``
    (:mod:`.detection_domain`: the force the χ² and the norm test, each with the thresholds
    of the same budget, need in free motion against the distance to the training data)."""
    data = held_out_motion(config, plan, n_jobs)
    named = with_tests(models, plan)
    detectors = {name: thresholds_from_held_out(model, with_test(config, test), plan, n_jobs,
                                                data=data)
                 for name, (model, test) in named.items()}
    models = {name: model for name, (model, _) in named.items()}
    compared = {name: _both_tests(model, config, plan, data, detectors[name])
                for name, model in models.items() if has_domain(model)}
    jobs = _free_jobs(config, plan) + _press_jobs(config, plan)
    runs = Parallel(n_jobs=n_jobs, return_as="generator")(
        delayed(_simulated_once)(yaml_text, models, detectors, meta) for yaml_text, meta in jobs)
    per_run = list(tqdm(runs, total=len(jobs), desc="detection (replay)", unit="run",
                        disable=not progress))
    results = {}
    for name in models:
        rows = [run[name] for run in per_run]
        results[name] = model_result(detectors[name], [r for r, _, _ in rows])
        results[name]["replayed_runs"] = sum(1 for _, how, _ in rows if how == "replay")
        results[name]["closed_loop_runs"] = sum(1 for _, how, _ in rows if how == "loop")
        samples = [s for _, _, s in rows if s is not None]
        if samples:
            results[name]["detectable_force_vs_domain"] = detectable_force_vs_domain(
                samples, compared[name], 1.0 / config.sensor.spec().rate_hz)
    return results


def _both_tests(model, config: ScenarioConfig, plan: DetectionPlan, data, detector) -> dict:
    """{"chi2": …, "norm": …}: `detector` (the model's thresholds, of its test) and the
    other test's thresholds for the same budget from the same held-out motion."""
    return {test: (detector if test == detector.test else
                   thresholds_from_held_out(model, with_test(config, test), plan, data=data))
            for test in TESTS}


def _simulated_once(config_yaml: str, models: dict, detectors: dict, meta: dict) -> dict:
    """{model name: (row, "replay" | "loop", free-motion samples or None)} for one run of
    the plan (:func:`.detection_domain.free_motion_samples` for a free run, replayed)."""
    config = parse_config(config_yaml)
    tuned = {name: config.with_chain(detector=detectors[name]) for name in models}
    if replay_differs_from_loop(config) is not None:
        return {name: (_closed_loop_run(dump_config(tuned[name]), model, meta), "loop", None)
                for name, model in models.items()}
    try:
        station = build_station(config)
    except TrajectoryError as e:  # e.g. a press the arm cannot reach within its limits
        return {name: ({**meta, "skipped": str(e)}, "replay", None) for name in models}
    log = simulate(station, progress=False).log
    out = {}
    for name, model in models.items():
        replayed = replay(model, log, tuned[name].chain_config(), pairing="simulated")
        samples = (free_motion_samples(model, log, replayed, config.chain.detector.arm_after_s)
                   if meta["kind"] != "contact" else None)
        out[name] = (run_row(log, tuned[name], meta, replayed), "replay", samples)
    return out
