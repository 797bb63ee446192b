"""Streams with gaps at a live station: joint states slower than the F/T stream, joint states
or wrenches lost, against the same streams complete.

The physics and the hybrid model are trained as ``ftdrake train`` trains them on `--train-s`
s of simulated free motion on ftdrake's arm (as ``live_rate.py`` does); a second free-motion
simulation, resampled at 1 kHz, is fed message by message to an LCM station on ``memq://``
(the default chain: compensator, bias tracker, detector), with each case's messages left
out. The station's clock is the stamps, so nothing here depends on this machine's speed.
Per case and model:

* processed: F/T messages run through the chain (a wrench with no joint state within
  ``pair_tolerance_s``, 5 ms, faults as ``stamp_gap`` and is not);
* error: RMS and max of ‖F‖ of the published ``wrench_compensated`` after the first second,
  N: in free motion, the compensation's error plus the sensor's noise;
* contact: published contact states that say contact with no fault (free motion: all false).

The last line is one JSON object ``{"<case>": {"<model>": {"processed", "error_rms_n",
"error_max_n", "contact_states"}}}``.

    python benchmarks/stream_gaps.py [--seconds 10] [--train-s 20] [--models physics,hybrid]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from live_rate import free_motion, resampled

from ftdrake import ChainConfig, RobotOptions, make_estimator
from ftdrake.conventions import WRENCH_AXES
from ftdrake.hardware import HardwareConfig
from ftdrake.hardware.messages import encode_joint_state, encode_wrench
from ftdrake.testing import listening_station

RATE = 1000.0


def every(m: int):
    """Message k is sent when k is a multiple of `m` (a stream at 1/m of the rate)."""
    return lambda k: k % m == 0


# case → (joint state k sent?, wrench k sent?)
CASES = {
    "complete": (every(1), every(1)),
    "joint states at 500 Hz": (every(2), every(1)),
    "joint states at 250 Hz": (every(4), every(1)),
    "5 joint states lost each second": (lambda k: k % 1000 >= 5, every(1)),
    "3 of every 16 wrenches lost": (every(1), lambda k: k % 16 < 13),
}


def run_case(model, q, v, w, joint_sent, wrench_sent) -> dict:
    """The station fed the replay with the case's messages left out; its outputs measured."""
    config = HardwareConfig(lcm_url="memq://", sensor_timeout_s=1.0, joint_state_timeout_s=1.0)
    now = [0.0]
    dut, contacts, wrenches = listening_station(model, ChainConfig(), config, lambda: now[0])
    lc = dut.lcm.lc
    for k in range(len(q)):
        t = (k + 1) / RATE
        now[0] = t
        if joint_sent(k):
            lc.publish(config.joint_state_channel,
                       encode_joint_state("iiwa_status", t, q[k], v[k]))
        if wrench_sent(k):
            lc.publish(config.ft_channel, encode_wrench(t, w[k]))
        while lc.handle_timeout(0) > 0:  # the messages, then the station's own outputs
            pass
    force = np.linalg.norm([x.wrench[:3] for x in wrenches if x.t > 1.0], axis=1)
    return {"processed": dut.processed,
            "error_rms_n": float(np.sqrt(np.mean(force**2))),
            "error_max_n": float(force.max()),
            "contact_states": sum(c.contact and not c.fault for c in contacts)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="s of replay per case")
    parser.add_argument("--train-s", type=float, default=20.0, help="simulated training s")
    parser.add_argument("--models", default="physics,hybrid")
    args = parser.parse_args()
    _, X, W, _ = free_motion(args.train_s, seed=0)
    t, X_replay, W_replay = free_motion(max(10.0, args.seconds), seed=1)[:3]
    q, v, w = resampled(t, X_replay, W_replay, RATE, round(args.seconds * RATE))
    results = {}
    for name in args.models.split(","):
        model = make_estimator(name, robot=RobotOptions(robot="ftdrake"),
                               target_names=[f"meas_{a}" for a in WRENCH_AXES]).fit(X, W)
        for case, (joint_sent, wrench_sent) in CASES.items():
            row = run_case(model, q, v, w, joint_sent, wrench_sent)
            results.setdefault(case, {})[name] = row
            print(f"{case:<34} {name:<8} processed {row['processed']:>6}  ‖F‖ error RMS "
                  f"{row['error_rms_n']:.3f} N, max {row['error_max_n']:.3f} N  contact "
                  f"states {row['contact_states']}", flush=True)
    print(json.dumps(results))


if __name__ == "__main__":
    main()
