"""A driver whose clock restarts, live: ``ftdrake serve`` in its own process fed a log of
free motion played in a loop (as ``ros2 bag play --loop`` or ``lcm-logplayer --loop``
play one), the stamps starting again at each pass while serve runs on.

The driver is ``live_rate.py``'s (ROS 2 over loopback DDS, or LCM with ``--transport
lcm``), as is the model (trained on simulated free motion of ftdrake's arm) and the log
(another stretch of it, resampled to the rate). Printed: F/T messages sent, processed and
published by serve (a restart's settle window publishes nothing for 0.1 s), the contact
states received and the false contact episodes among them (the log holds no contact),
serve's rejections, drops, fault episodes and clock restarts, and its warnings of
restarts. The last line is one JSON object with those numbers.

    python benchmarks/looped_bag.py [--transport ros2|lcm] [--model physics|hybrid]
                                    [--seconds 4] [--loops 3] [--rate 1000]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import tempfile
import time
from pathlib import Path

import live_rate as lr

from ftdrake import RobotOptions, make_estimator
from ftdrake.conventions import WRENCH_AXES
from ftdrake.sim.ros2_publisher import arm_joint_names


def play(driver, log, rate: float, per_loop: int, loops: int) -> None:
    """Sends the log `loops` times at `rate`, its stamps 1/rate … per_loop/rate each time."""
    q, v, w = log
    start = time.perf_counter()
    for k in range(per_loop * loops):
        due = start + k / rate
        while (now := time.perf_counter()) < due:
            driver.wait(due - now)
        j = k % per_loop
        driver.send((j + 1) / rate, q[j], v[j], w[j])
        driver.poll(0)
    end = time.monotonic() + 5
    while len(driver.contacts) < per_loop * loops and time.monotonic() < end:
        driver.poll(10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--transport", choices=("ros2", "lcm"), default="ros2")
    parser.add_argument("--model", choices=("physics", "hybrid"), default="physics")
    parser.add_argument("--seconds", type=float, default=4.0, help="s per pass of the log")
    parser.add_argument("--loops", type=int, default=3, help="passes of the log")
    parser.add_argument("--rate", type=float, default=1000.0, help="Hz")
    args = parser.parse_args()
    _, X, W, station = lr.free_motion(20.0, seed=0)
    names = arm_joint_names(station)
    model = make_estimator(args.model, robot=RobotOptions(robot="ftdrake"),
                           target_names=[f"meas_{a}" for a in WRENCH_AXES]).fit(X, W)
    per_loop = round(args.seconds * args.rate)
    log = lr.resampled(*lr.free_motion(max(10.0, args.seconds), seed=1)[:3], args.rate,
                       per_loop)
    kind = lr.Ros2Driver if args.transport == "ros2" else lr.LcmDriver
    port = 7700 + os.getpid() % 200
    with tempfile.TemporaryDirectory() as folder:
        serve, _ = lr.start_serve(model, args.rate, kind, names, port, Path(folder))
        driver = None
        try:
            driver, _ = lr.start_driver(kind, names, port)
            play(driver, log, args.rate, per_loop, args.loops)
            serve.send_signal(signal.SIGINT)
            out, _ = serve.communicate(timeout=60)
        finally:
            if serve.poll() is None:
                serve.kill()
            if driver is not None:
                driver.close()
        said = [line for line in (Path(folder) / "serve.err").read_text().splitlines()
                if "clock restarted" in line]
    summary = json.loads(out.strip().splitlines()[-1])
    flags = driver.contacts
    result = {
        "sent": per_loop * args.loops, "processed": summary["processed"],
        "published": summary["published_wrench"], "contact_states": len(flags),
        "false_contacts": sum(1 for k, on in enumerate(flags) if on and not (k and flags[k - 1])),
        "rejected": summary["rejected"], "dropped": summary["load"].get("dropped_ft"),
        "fault_episodes": summary["fault_episodes"],
        "clock_restarts": summary.get("clock_restarts"), "restarts_said": len(said)}
    print(f"{args.transport} {args.model}: sent {result['sent']}, processed "
          f"{result['processed']}, published {result['published']}, contact states back "
          f"{result['contact_states']}, false contact episodes {result['false_contacts']}; "
          f"rejected {result['rejected'] or 'none'}, dropped {result['dropped']}, fault "
          f"episodes {result['fault_episodes'] or 'none'}, clock restarts "
          f"{result['clock_restarts']}")
    for line in said[:2]:
        print(f"  {line}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
