"""End to end on this machine: ``ftdrake simulate --lcm URL --realtime`` and ``ftdrake serve``
as two processes over UDP multicast (ttl=0) for 60 s at 1 kHz, with this script as a third
listener on every channel.

Prints: messages published by the simulation, received/processed/published by serve and seen
here (none lost, none twice); the largest difference between serve's ``wrench_compensated`` and the
in-simulation compensator's ``wrench_compensated`` for the same stream (the same scenario simulated
in-process with the compensator in the loop); whether serve's contact flag equals the
in-simulation detector's sample for sample, and both against the ground truth ``contact``
(agreement, first detection); serve's own arrival → publication latency (p50/p99) and the
load average.

Scenario: the shipped contact scenario stretched to 60 s (48 s of free motion, then the press
on the table); model: ``ftdrake train``'s rf defaults on 20 s of simulated free motion.

    nice -n 5 python benchmarks/live_end_to_end.py [--duration 60] [--port 7745]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import lcm
import numpy as np

from ftdrake import ScenarioConfig, make_estimator, save_model
from ftdrake.config import save_config
from ftdrake.conventions import (
    MEASURED,
    QD,
    QDD,
    WRENCH_AXES,
    WRENCH_UNITS,
    Q,
    joint_columns,
    wrench_columns,
)
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import decode_contact_state, decode_wrench
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station


def first(flags, t):
    hits = np.flatnonzero(flags)
    return float(t[hits[0]]) if len(hits) else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--port", type=int, default=7745)
    args = parser.parse_args()
    url = f"udpm://239.255.76.67:{args.port}?ttl=0"
    work = Path(tempfile.mkdtemp(prefix="ftdrake-live-"))
    free = ScenarioConfig()
    free.trajectory.kind, free.trajectory.duration_s = "fourier", 20.0
    log = simulate(build_station(free), progress=False).log
    X = log[[*joint_columns(Q, 7), *joint_columns(QD, 7), *joint_columns(QDD, 7)]].to_numpy()
    model = make_estimator("rf").fit(X, log[wrench_columns(MEASURED)].to_numpy())
    save_model(model, work / "model.ftd", target_names=[f"meas_{a}" for a in WRENCH_AXES],
               target_units=list(WRENCH_UNITS))
    scenario = ScenarioConfig()
    scenario.trajectory.duration_s = args.duration
    save_config(scenario, work / "scenario.yaml")

    hardware = HardwareConfig(lcm_url=url)
    lc = lcm.LCM(url)
    got = {c: [] for c in (hardware.joint_state_channel, hardware.ft_channel,
                           hardware.output_channel("wrench_compensated"),
                           hardware.output_channel("contact"))}
    for channel, messages in got.items():
        lc.subscribe(channel, lambda _c, d, m=messages: m.append(d)).set_queue_capacity(10**6)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    err_path = work / "serve.err"
    with open(err_path, "w") as err:
        serve = subprocess.Popen([sys.executable, "-m", "ftdrake", "serve", "--model",
                                  work / "model.ftd", "--config", work / "scenario.yaml",
                                  "--lcm", url], stdout=subprocess.PIPE, stderr=err, text=True,
                                 env=env)
    while "  out: " not in err_path.read_text():
        time.sleep(0.1)
    load_start = os.getloadavg()
    sim = subprocess.Popen([sys.executable, "-m", "ftdrake", "simulate", "--config",
                            work / "scenario.yaml", "--lcm", url, "--realtime", "--out",
                            work / "sim", "--quiet"], stdout=subprocess.PIPE, text=True, env=env)
    while sim.poll() is None:
        lc.handle_timeout(50)
    load_end = os.getloadavg()
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        lc.handle_timeout(20)
    serve.send_signal(signal.SIGINT)
    out, _ = serve.communicate(timeout=60)
    while lc.handle_timeout(0) > 0:
        pass
    summary = json.loads(out.strip().splitlines()[-1])
    sim_out = sim.stdout.read()
    sim_summary = json.loads(sim_out[sim_out.index("{"):])
    K = sim_summary["published"]["ft"]

    wrenches = [decode_wrench(d) for d in got[hardware.output_channel("wrench_compensated")]]
    contacts = [c for c in map(decode_contact_state, got[hardware.output_channel("contact")])
                if not c.fault]
    sent = [decode_wrench(d).t for d in got[hardware.ft_channel]]
    in_sim = simulate(build_station(scenario, model), progress=False).log
    expected = in_sim[[f"wrench_compensated_{a}" for a in WRENCH_AXES]].to_numpy()
    got_w = np.array([w.wrench for w in wrenches])
    n = min(len(got_w), len(expected))
    diff = float(np.abs(got_w[:n] - expected[:n]).max())
    detected_live = np.array([c.contact for c in contacts])
    detected_sim = in_sim["contact"].to_numpy().astype(bool)
    truth = in_sim["contact_true"].to_numpy().astype(bool)
    t = in_sim["t"].to_numpy()
    m = min(len(detected_live), len(truth))
    result = {
        "duration_s": args.duration, "url": url,
        "sim": {"published": sim_summary["published"],
                "real_time_factor": sim_summary["real_time_factor"]},
        "serve": {k: summary[k] for k in ("received", "accepted", "rejected", "processed",
                                          "published_wrench", "fault_episodes", "latency_ms")},
        "listener": {"ft": len(sent), "joint": len(got[hardware.joint_state_channel]),
                     "wrench": len(wrenches), "contact_fresh": len(contacts)},
        "lost_or_twice": {"wrench_times_equal_sent": [w.t for w in wrenches] == sent,
                          "processed_equals_sent": summary["processed"] == K},
        "max_abs_diff_vs_in_sim_compensator": diff,
        "contact_equals_in_sim_detector": bool(
            len(detected_live) == len(detected_sim)
            and (detected_live == detected_sim).all()),
        "agreement_with_truth": {"live": float((detected_live[:m] == truth[:m]).mean()),
                                 "in_sim": float((detected_sim == truth).mean())},
        "first_contact_s": {"truth": first(truth, t), "live": first(detected_live[:m], t[:m]),
                            "in_sim": first(detected_sim, t)},
        "load_avg_1min": {"start": load_start[0], "end": load_end[0]},
    }
    print(json.dumps(result, indent=2))
    print(json.dumps({"benchmark": "live_end_to_end", **result}))


if __name__ == "__main__":
    main()
