"""The bias tracker evaluated in the loop: a re-tare, a grasp and a slow push, in free motion.

Each event runs three times on the same seed (same trajectory, same sensor noise): with the
event and the tracker, with the event and no tracker, and without the event (the reference).
The difference between the first and the reference, ``d(t) = est_with(t) − est_ref(t)``, is
what the event leaves in the compensated wrench — model error and noise cancel, so the 2 σ
criterion is strict. Recovery time: from the event until ``|d_i| ≤ 2 σ_i`` on every axis for
the rest of the run (σ the sensor's noise per axis). For the grasp the motion itself changes a
little (the controller does not know the new weight), which stays in ``d``.

The push grows linearly (``events.push_force_W`` over ``events.push_ramp_s``): reported are
the time and the push's force at the first detection, and how much of it the tracker had
taken as bias by then (‖Δ bias_F‖ from the push's start to the detection).
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
from joblib import Parallel, delayed
from tqdm.auto import tqdm

from .. import conventions as col
from ..config import ScenarioConfig, dump_config, parse_config
from ..sim.simulate import simulate
from ..sim.station import build_station

EVENTS = ("retare", "grasp", "push")


@dc.dataclass
class EventPlan:
    """The event runs (free motion of one trajectory kind; the event at `event_at_s`)."""

    kind: str = "fourier"
    duration_s: float = 20.0
    event_at_s: float = 5.0
    seeds: tuple[int, ...] = (0,)  # trajectory and noise seeds (offset by the plan's seed)
    retare_offset: tuple[float, ...] = (2.9, -2.9, 2.9, 0.116, -0.116, 0.116)  # 5 N, 0.2 N·m
    grasp_mass_kg: float = 0.5
    # After the grasp the station's controller carries the tracker's payload estimate
    # (controller.adapt_to_payload), as a robot whose controller is told the payload would.
    adapt_controller: bool = True
    push_force_n: float = 5.0
    push_ramp_s: float = 5.0
    tolerance_sigmas: float = 2.0


def event_configs(base: ScenarioConfig, event: str, plan: EventPlan, seed: int) -> dict:
    """The scenario for `event`: ``with`` (tracker on), ``untracked`` (tracker off) and
    ``reference`` (no event, tracker on); same trajectory and noise."""
    if event not in EVENTS:
        raise ValueError(f"unknown event {event!r}; choose from {EVENTS}")
    trajectory = dc.replace(base.trajectory, kind=plan.kind, duration_s=plan.duration_s,
                            seed=seed)
    tracker = dc.replace(base.bias_tracker, enabled=True,
                         track_payload=event == "grasp" or base.bias_tracker.track_payload)
    reference = dc.replace(base, trajectory=trajectory, bias_tracker=tracker,
                           sensor=dc.replace(base.sensor, seed=seed),
                           events=dc.replace(base.events, retare_at_s=None, grasp_at_s=None,
                                             push_at_s=None))
    t = plan.event_at_s
    if event == "retare":
        events = dc.replace(reference.events, retare_at_s=t,
                            retare_offset=list(plan.retare_offset))
    elif event == "grasp":
        events = dc.replace(reference.events, grasp_at_s=t, grasp_mass_kg=plan.grasp_mass_kg)
        # The reference adapts too (to its estimate of no payload): the same controller.
        reference = dc.replace(reference, controller=dc.replace(
            reference.controller, adapt_to_payload=plan.adapt_controller))
    else:
        events = dc.replace(reference.events, push_at_s=t, push_ramp_s=plan.push_ramp_s,
                            push_force_W=[0.0, 0.0, -plan.push_force_n],
                            push_hold_s=max(0.0, plan.duration_s - t - plan.push_ramp_s))
    with_event = dc.replace(reference, events=events)
    untracked = dc.replace(with_event, bias_tracker=dc.replace(tracker, enabled=False),
                           controller=dc.replace(with_event.controller,
                                                 adapt_to_payload=False))
    return {"with": with_event, "untracked": untracked, "reference": reference}


def run_events(models: dict, config: ScenarioConfig, plan: EventPlan | None = None, *,
               seed: int = 0, n_jobs: int = -1, progress: bool = True) -> dict:
    """Runs every event for every model (name → fitted compensator; `config.detector` or a
    per-model detector in ``models[name] = (model, detector)``). Returns name → rows."""
    plan = plan or EventPlan()
    jobs = []
    for name, entry in models.items():
        model, detector = entry if isinstance(entry, tuple) else (entry, config.detector)
        base = dc.replace(config, detector=detector)
        for event in EVENTS:
            for s in plan.seeds:
                configs = event_configs(base, event, plan, seed + s)
                jobs.append((name, event, seed + s, model,
                             {k: dump_config(v) for k, v in configs.items()}))
    runs = Parallel(n_jobs=n_jobs, return_as="generator")(
        delayed(_event_run)(model, yamls, plan, event) for _, event, _, model, yamls in jobs)
    results: dict = {name: [] for name in models}
    for (name, event, s, _, _), row in zip(
            jobs, tqdm(runs, total=len(jobs), desc="tracker events", unit="run",
                       disable=not progress), strict=True):
        results[name].append({"event": event, "seed": s, **row})
    return results


def _event_run(model, yamls: dict, plan: EventPlan, event: str) -> dict:
    logs = {}
    for key, text in yamls.items():
        config = parse_config(text)
        logs[key] = simulate(build_station(config, model), progress=False).log
    sigma = np.asarray(config.sensor.spec().noise_std, dtype=float)
    if event == "push":
        return push_metrics(logs["with"], logs["reference"], plan)
    return recovery_metrics(logs["with"], logs["untracked"], logs["reference"], sigma, plan,
                            payload=event == "grasp")


def recovery_metrics(with_event, untracked, reference, sigma, plan: EventPlan, *,
                     payload: bool = False) -> dict:
    """How long the event shows in the compensated wrench, with and without the tracker."""
    t = with_event[col.TIME].to_numpy()
    after = t >= plan.event_at_s
    row = {}
    for key, log in (("tracked", with_event), ("untracked", untracked)):
        d = _estimate(log) - _estimate(reference)
        outside = (np.abs(d) > plan.tolerance_sigmas * sigma).any(axis=1) & after
        last = t[outside][-1] if outside.any() else None
        recovered = last is None or last < t[-1] - 0.5
        row[key] = {
            "recovered_after_s": (0.0 if last is None else float(last - plan.event_at_s))
            if recovered else None,
            "max_error_sigmas": float((np.abs(d[after]) / sigma).max()),
            "false_contact_s": float(_contact_seconds(log, after)),
        }
    row["reference_false_contact_s"] = float(_contact_seconds(reference, after))
    if payload and col.PAYLOAD_ESTIMATE[0] in with_event:
        row["payload_estimate"] = [float(with_event[c].iloc[-1]) for c in col.PAYLOAD_ESTIMATE]
    return row


def push_metrics(with_event, reference, plan: EventPlan) -> dict:
    """When the slow push was detected, at what force, and how much of it became bias."""
    t = with_event[col.TIME].to_numpy()
    start = np.searchsorted(t, plan.event_at_s)
    detected = with_event[col.DETECTED].to_numpy()[start:] > 0
    bias = with_event[col.wrench_columns(col.BIAS_ESTIMATE)[:3]].to_numpy()
    row = {"reference_false_contact_s": float(_contact_seconds(reference, t >= plan.event_at_s))}
    if not detected.any():
        return {**row, "detected": False, "delay_s": None, "force_at_detection_n": None,
                "bias_absorbed_n": float(np.linalg.norm(bias[-1] - bias[start]))}
    i = start + int(np.argmax(detected))
    return {**row, "detected": True, "delay_s": float(t[i] - plan.event_at_s),
            "force_at_detection_n": float(with_event[col.PUSH_FORCE].iloc[i]),
            "bias_absorbed_n": float(np.linalg.norm(bias[i] - bias[start]))}


def _estimate(log):
    return log[col.wrench_columns(col.ESTIMATED)].to_numpy()


def _contact_seconds(log, mask) -> float:
    t = log[col.TIME].to_numpy()
    period = float(np.median(np.diff(t)))
    return float((log[col.DETECTED].to_numpy()[mask] > 0).sum() * period)


def markdown(results: dict, plan: EventPlan) -> str:
    """One table per event kind: every model, tracked beside untracked."""
    lines = [(f"## The bias tracker in the loop (free motion `{plan.kind}`, event at "
             f"{plan.event_at_s:g} s of {plan.duration_s:g} s; tolerance "
             f"{plan.tolerance_sigmas:g} σ of the sensor noise)"), "",
             ("| model | event | seed | back within tolerance after (tracker) | false contact "
             "(tracker) | back within tolerance after (no tracker) | false contact (no "
             "tracker) |"), "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, rows in results.items():
        for r in rows:
            if r["event"] == "push":
                continue
            cells = []
            for key in ("tracked", "untracked"):
                after = r[key]["recovered_after_s"]
                cells += ["never" if after is None else f"{after:.2f} s",
                          f"{r[key]['false_contact_s']:.2f} s"]
            lines.append(f"| {name} | {_event_label(r['event'], plan)} | {r['seed']} | "
                         + " | ".join(cells) + " |")
    lines += ["", ("| model | slow push | seed | detected | after | push at detection | "
              "taken as bias by then |"), "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, rows in results.items():
        for r in rows:
            if r["event"] != "push":
                continue
            delay = "–" if r["delay_s"] is None else f"{r['delay_s']:.2f} s"
            force = ("–" if r["force_at_detection_n"] is None
                     else f"{r['force_at_detection_n']:.2f} N")
            lines.append(
                f"| {name} | {plan.push_force_n:g} N over {plan.push_ramp_s:g} s | {r['seed']} "
                f"| {'yes' if r['detected'] else '**no**'} | {delay} | {force} "
                f"| {r['bias_absorbed_n'] * 1000:.1f} mN |")
    return "\n".join(lines) + "\n"


def _event_label(event: str, plan: EventPlan) -> str:
    if event == "retare":
        f = np.linalg.norm(plan.retare_offset[:3])
        m = np.linalg.norm(plan.retare_offset[3:])
        return f"re-tare ({f:.1f} N, {m:.2f} N·m)"
    return f"grasp {plan.grasp_mass_kg:g} kg"
