"""The bias tracker evaluated in the loop: a re-tare, a grasp and a slow push, in free motion.

Each event runs three times on the same seed (same trajectory, same sensor noise): with the
event and the tracker, with the event and no tracker, and without the event (the reference).
The difference between the first and the reference, ``d(t) = est_with(t) − est_ref(t)``, is
what the event leaves in the compensated wrench — model error and noise cancel, so the 2 σ
criterion is strict. Recovery time: from the event until ``|d_i| ≤ 2 σ_i`` on every axis for
the rest of the run (σ the sensor's noise per axis). For the grasp the motion itself changes a
little (the controller adapts to the tracker's estimate of the weight, not to the truth),
which stays in ``d``.

For a grasp two more figures judge the window from ``judged_after_s`` after the grasp on
(the plan's, 5 s: the tracker's default payload settle window): the largest |d_i|/σ_i and
the share of samples within tolerance on every axis — for the tracker, and for the *best
constant payload in hindsight* (:func:`constant_payload_floor`): a bias and a rigid payload
fitted by least squares to every sample after the grasp that the tracker learns from. It
has all the data at once, which no tracker has, and still takes up the compensator's own
error as a tracker does, so the two figures say how much of what is left is the tracker's
and how much the compensator's.

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
from ..compensation.identification.payload_identification import payload_regressor
from ..compensation.identification.payload_kinematics import kinematics_for
from ..config import ScenarioConfig, dump_config, parse_config
from ..physics.scenario_robot import robot_description
from ..runtime.chain import model_payload_map
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
    events: tuple[str, ...] = EVENTS  # which of EVENTS run
    retare_offset: tuple[float, ...] = (2.9, -2.9, 2.9, 0.116, -0.116, 0.116)  # 5 N, 0.2 N·m
    grasp_mass_kg: float = 0.5
    # After the grasp the station's controller carries the tracker's payload estimate
    # (controller.adapt_to_payload), as a robot whose controller is told the payload would.
    adapt_controller: bool = True
    push_force_n: float = 5.0
    push_ramp_s: float = 5.0
    tolerance_sigmas: float = 2.0
    # A grasp is also judged from this long after it on (the settled figures).
    judged_after_s: float = 5.0


def event_configs(base: ScenarioConfig, event: str, plan: EventPlan, seed: int) -> dict:
    """The scenario for `event`: ``with`` (tracker on), ``untracked`` (tracker off) and
    ``reference`` (no event, tracker on); same trajectory and noise."""
    if event not in EVENTS:
        raise ValueError(f"unknown event {event!r}; choose from {EVENTS}")
    trajectory = dc.replace(base.trajectory, kind=plan.kind, duration_s=plan.duration_s,
                            seed=seed)
    tracker = dc.replace(base.chain.bias_tracker, enabled=True,
                         track_payload=event == "grasp" or base.chain.bias_tracker.track_payload)
    reference = dc.replace(base.with_chain(bias_tracker=tracker), trajectory=trajectory,
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
    untracked = dc.replace(
        with_event.with_chain(bias_tracker=dc.replace(tracker, enabled=False)),
        controller=dc.replace(with_event.controller, adapt_to_payload=False))
    return {"with": with_event, "untracked": untracked, "reference": reference}


def run_events(models: dict, config: ScenarioConfig, plan: EventPlan | None = None, *,
               seed: int = 0, n_jobs: int = -1, progress: bool = True) -> dict:
    """Runs every event for every model (name → fitted compensator; `config.chain.detector` or a
    per-model detector in ``models[name] = (model, detector)``). Returns name → rows."""
    plan = plan or EventPlan()
    unknown = sorted(set(plan.events) - set(EVENTS))
    if unknown:
        raise ValueError(f"EventPlan.events: unknown {unknown}; choose from {EVENTS}")
    jobs = []
    for name, entry in models.items():
        model, detector = entry if isinstance(entry, tuple) else (entry, config.chain.detector)
        base = config.with_chain(detector=detector)
        for event in plan.events:
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
    row = recovery_metrics(logs["with"], logs["untracked"], logs["reference"], sigma, plan,
                           payload=event == "grasp")
    if event == "grasp":
        judged_from = plan.event_at_s + plan.judged_after_s
        row["settled"] = settled_metrics(logs["with"], logs["reference"], sigma, judged_from,
                                         plan.tolerance_sigmas)
        row["best_constant_payload"] = constant_payload_floor(
            logs["with"], logs["reference"], sensor_regressor(logs["with"], config),
            model_payload_map(model), sigma, plan.event_at_s, judged_from, plan.tolerance_sigmas)
    return row


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
    if payload and col.PAYLOAD[0] in with_event:
        row["payload_estimate"] = [float(with_event[c].iloc[-1]) for c in col.PAYLOAD]
    return row


def settled_metrics(with_event, reference, sigma, judged_from_s: float,
                    tolerance_sigmas: float) -> dict:
    """The largest |d_i|/σ_i from `judged_from_s` on and the share of those samples within
    `tolerance_sigmas` on every axis (d as in the module docstring)."""
    t = with_event[col.TIME].to_numpy()
    z = (_estimate(with_event) - _estimate(reference))[t >= judged_from_s] / sigma
    return _judged(z, tolerance_sigmas)


def sensor_regressor(log, config: ScenarioConfig) -> np.ndarray:
    """(N, 6, 16) rigid-payload regressor of `log`'s samples, ``[payload (10) | bias (6)]``
    (:func:`~ftdrake.compensation.identification.payload_identification.payload_regressor`), from
    the plant's true q, q̇, q̈ (columns ``q_i``, ``qd_i``, ``qdd_i``): S's motion in S."""
    q, v, vdot = (log[col.joint_columns(prefix)].to_numpy() for prefix in ("q", "qd", "qdd"))
    kin = kinematics_for(robot_description(config.models), col.GRAVITY_W).evaluate(q, v, vdot)
    return payload_regressor(kin.w_WS_S, kin.alpha_WS_S, kin.a_WSo_S - kin.g_S)


def constant_payload_floor(with_event, reference, regressor, payload_map, sigma,
                           event_at_s: float, judged_from_s: float,
                           tolerance_sigmas: float) -> dict:
    """What the best constant payload leaves: d's figures (:func:`settled_metrics`) as they
    would be had the tracker subtracted, in both runs, a constant estimated in hindsight from
    every sample after the event that the tracker learns from (the compensator's
    ``out_of_domain`` and ``fault`` < 0.5, where the log has them) — in the event's run a
    bias and a rigid payload read through `payload_map` (K, 6 × 6; the compensator's map of
    a wrench at the sensor), in the reference a bias; each by least squares on that run's
    compensated wrench, rows weighted by 1/σ. `regressor`: :func:`sensor_regressor` of the
    event's run. Figures are None when fewer than 16 samples are left to fit.

    The fit sees what a tracker sees (the compensated wrench, model error included), so the
    payload takes up the part of the compensator's pose-dependent error its regressor can
    express, as any tracker of a constant payload does over that run; with the error
    absent it is the payload's wrench, and d's figures are the noise-free ~0."""
    t = with_event[col.TIME].to_numpy()
    fitted = (t > event_at_s) & _trusted(with_event)
    K = np.eye(6) if payload_map is None else np.asarray(payload_map, dtype=float)
    A = np.concatenate([np.einsum("ij,njk->nik", K, regressor[:, :, :10]),
                        regressor[:, :, 10:]], axis=2) / sigma[None, :, None]
    compensated = with_event[col.wrench_columns(col.WRENCH_COMPENSATED)].to_numpy() / sigma
    fitted_reference = (reference[col.TIME].to_numpy() > event_at_s) & _trusted(reference)
    if min(fitted.sum(), fitted_reference.sum()) < 16:
        return {**_judged(np.empty((0, 6)), tolerance_sigmas), "payload": None}
    theta = np.linalg.lstsq(A[fitted].reshape(-1, 16), compensated[fitted].reshape(-1),
                            rcond=None)[0]
    left = compensated - A @ theta
    left_reference = reference[col.wrench_columns(col.WRENCH_COMPENSATED)].to_numpy() / sigma
    left_reference = left_reference - left_reference[fitted_reference].mean(axis=0)
    row = _judged((left - left_reference)[t >= judged_from_s], tolerance_sigmas)
    return {**row, "payload": [float(x) for x in theta[:4]]}


def _trusted(log) -> np.ndarray:
    trusted = np.ones(len(log), dtype=bool)
    for flag in (col.OUT_OF_DOMAIN, col.FAULT):
        if flag in log:
            trusted &= ~(log[flag].to_numpy() >= 0.5)  # NaN counts as set, as in the tracker
    return trusted


def _judged(z, tolerance_sigmas: float) -> dict:
    if len(z) == 0:
        return {"max_error_sigmas": None, "within_tolerance": None}
    return {"max_error_sigmas": float(np.abs(z).max()),
            "within_tolerance": float((np.abs(z) <= tolerance_sigmas).all(axis=1).mean())}


def push_metrics(with_event, reference, plan: EventPlan) -> dict:
    """When the slow push was detected, at what force, and how much of it became bias."""
    t = with_event[col.TIME].to_numpy()
    start = np.searchsorted(t, plan.event_at_s)
    detected = with_event[col.CONTACT].to_numpy()[start:] > 0
    bias = with_event[col.wrench_columns(col.BIAS)[:3]].to_numpy()
    row = {"reference_false_contact_s": float(_contact_seconds(reference, t >= plan.event_at_s))}
    if not detected.any():
        return {**row, "detected": False, "delay_s": None, "force_at_detection_n": None,
                "bias_absorbed_n": float(np.linalg.norm(bias[-1] - bias[start]))}
    i = start + int(np.argmax(detected))
    return {**row, "detected": True, "delay_s": float(t[i] - plan.event_at_s),
            "force_at_detection_n": float(with_event[col.PUSH_FORCE].iloc[i]),
            "bias_absorbed_n": float(np.linalg.norm(bias[i] - bias[start]))}


def _estimate(log):
    return log[col.wrench_columns(col.WRENCH_CONTACT)].to_numpy()


def _contact_seconds(log, mask) -> float:
    t = log[col.TIME].to_numpy()
    period = float(np.median(np.diff(t)))
    return float((log[col.CONTACT].to_numpy()[mask] > 0).sum() * period)


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
    lines += _settled_table(results, plan)
    if not any(r["event"] == "push" for rows in results.values() for r in rows):
        return "\n".join(lines) + "\n"
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


def _settled_table(results: dict, plan: EventPlan) -> list[str]:
    """The grasp's judged window (from `judged_after_s` after it on): the tracker beside the
    best constant payload in hindsight."""
    rows = [(name, r) for name, rs in results.items() for r in rs if "settled" in r]
    if not rows:
        return []
    lines = ["", (f"| model | grasp | seed | from {plan.judged_after_s:g} s after it on: largest "
                  f"effect, within {plan.tolerance_sigmas:g} σ (tracker) | the same, best "
                  f"constant payload in hindsight | its payload |"),
             "| --- | --- | --- | --- | --- | --- |"]
    for name, r in rows:
        cells = [_judged_cell(r["settled"]), _judged_cell(r["best_constant_payload"]),
                 _payload_cell(r["best_constant_payload"]["payload"])]
        lines.append(f"| {name} | {plan.grasp_mass_kg:g} kg | {r['seed']} | "
                     + " | ".join(cells) + " |")
    return lines


def _payload_cell(payload) -> str:
    if payload is None:
        return "–"
    dm, *mc = payload
    com = " ".join(f"{1000 * x / dm:.1f}" for x in mc) if dm else "–"
    return f"{dm:.4f} kg at ({com}) mm"


def _judged_cell(row: dict) -> str:
    if row["max_error_sigmas"] is None:
        return "–"
    return f"{row['max_error_sigmas']:.1f} σ, {100 * row['within_tolerance']:.1f} %"


def _event_label(event: str, plan: EventPlan) -> str:
    if event == "retare":
        f = np.linalg.norm(plan.retare_offset[:3])
        m = np.linalg.norm(plan.retare_offset[3:])
        return f"re-tare ({f:.1f} N, {m:.2f} N·m)"
    return f"grasp {plan.grasp_mass_kg:g} kg"
