"""A payload change told from a contact (``payload_state``): decisions and delays printed for
an unsignalled grasp, a press, a slow push and a straight-down push in the simulated loop,
and for a short log of three held poses (static gravity, the monitor alone) — the table of
docs/results/tracking.md, "A payload change or a contact".

    python benchmarks/payload_decision.py

Delays: from the event (the grasp; the detector's first contact for a push) and from the
moment g_S has turned 20° in S since then (from the logged joint angles and the plant's
kinematics); negative: decided before the tool had turned 20°.
"""

from __future__ import annotations

import dataclasses as dc
import sys
from pathlib import Path

import numpy as np

from ftdrake import conventions as col

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "runtime"))
import test_payload_change as held
import test_tracker_in_loop as loop

NAMES = {0.0: "none", 1.0: "undecided", 2.0: "payload change", 3.0: "contact"}


def first_time(t, mask) -> float:
    return float(t[np.argmax(mask)]) if np.any(mask) else float("nan")


def loop_row(name, truth, model, config, since) -> list:
    """The run's first decision (2 or 3) after the event, its delays and the final Δm."""
    log = loop.run(config, model)
    t = log[col.TIME].to_numpy()
    state, contact = log[col.PAYLOAD_STATE].to_numpy(), log[col.CONTACT].to_numpy()
    if since is None:  # a push: from the detector's first contact
        since = first_time(t, contact > 0)
    after = t >= since
    decided = after & (state >= 2.0)
    at = first_time(t, decided)
    sequence = [float(v) for v in state[decided]]
    sequence = [v for k, v in enumerate(sequence) if k == 0 or v != sequence[k - 1]]
    decision = " → ".join(NAMES[v] for v in sequence) if sequence else "undecided"
    turn_t, turn = loop.gravity_turn_deg(config, log, since)
    turned = first_time(turn_t, turn >= 20.0)
    late_contact = float(np.mean(contact[t > at + 1.0])) if decided.any() else float("nan")
    dm = float(log["payload_dm"].to_numpy()[-200:].mean())
    return [name, truth, decision, f"{at - since:.2f}", f"{at - turned:+.2f}",
            f"{late_contact:.2f}", f"{dm:.3f}"]


def held_rows() -> list:
    t, pose, R_SW, g = held.held_poses()
    rows = []
    for what, wrench in (("weight", held.payload_wrench(g)),
                         ("press", held.press(R_SW, [4.905, 0.0, 0.0]))):
        _, estimate, state = held.run_monitor(wrench + held.noise(len(g), 6), g,
                                              np.ones(len(g)), with_state=True)
        decided = state >= 2.0
        at = first_time(t, decided)
        arrived = first_time(t, pose == 1)
        decision = NAMES[float(state[decided][0])] if decided.any() else "undecided"
        dm = f"{estimate[np.argmax(decided), 0]:.3f}" if decision == "payload change" else "–"
        rows.append([f"three held poses, {what}", "payload" if what == "weight" else "contact",
                     decision, f"{at:.2f}", f"{at - arrived:+.2f}", "–", dm])
    # One pose only: no rotation, nothing decided.
    still = np.tile(g[0], (len(g), 1))
    _, _, state = held.run_monitor(held.payload_wrench(still), still, np.ones(len(g)),
                                   with_state=True)
    rows.append(["one held pose, weight", "payload", NAMES[float(state.max())], "–", "–", "–",
                 "–"])
    return rows


def main() -> None:
    model, config = loop.fitted(loop.collect(loop.ScenarioConfig(), 1, kind=loop.PLAN.kind,
                                             seed=0, duration=loop.PLAN.duration_s, n_jobs=1,
                                             progress=False),
                                loop.PhysicsPayloadCompensator())
    rows = []
    grasp = loop.unsignalled(config, "grasp")
    rows.append(loop_row(f"unsignalled grasp, {grasp.events.grasp_mass_kg} kg", "payload",
                         model, grasp, grasp.events.grasp_at_s))
    weight = grasp.events.grasp_mass_kg * 9.81
    for name, force, ramp in (("press along x", [weight, 0, 0], 0.2),
                              ("slow push along x", [weight, 0, 0], 4.0),
                              ("slow push 45° down", [weight / 2**0.5, 0, -weight / 2**0.5], 4.0),
                              ("slow push straight down", [0, 0, -weight], 4.0)):
        push = loop.unsignalled(config, "push")
        push = dc.replace(push, events=dc.replace(push.events, push_force_W=list(force),
                                                  push_ramp_s=ramp))
        rows.append(loop_row(f"{name} ({weight:.1f} N, ramp {ramp} s)",
                             "payload (to gravity)" if "straight" in name else "contact",
                             model, push, None))
    rows += held_rows()
    print("| case | truth | decisions in order | first decision's delay from the event (s) | "
          "from the 20° turn (s) | contact > 1 s after (share) | Δm tracked / estimated (kg) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
