"""A 30-minute warm-up: the compensated wrench with and without the temperature feature.

The noisy sensor alone (its Drake system at 1 kHz) is fed the ideal wrench of a rigid payload
moving along a slow Fourier-like trajectory of all 7 joints, from a cold start: the wrist
warms from 22 °C by 10 °C with a 10-minute time constant (``SensorConfig`` defaults) and the
zero drifts with it. A physics model is identified on the first 10 minutes of one run, with
and without the temperature column, and its compensated wrench (reading − prediction) on a
second 30-minute run (another seed and trajectory) is averaged over 10-s windows: the worst
|mean| per axis, in units of the sensor's noise σ. Run twice: without the random-walk drift
(the part nobody can model) and with it (``drift_std`` default), to say how much it adds.

    nice -n 5 python benchmarks/temperature_drift.py [--minutes 30]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
import warnings

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import SensorConfig
from ftdrake.compensation.estimators.physics import (
    ExcitationWarning,
    PhysicsPayloadCompensator,
)
from ftdrake.systems.noisy_sensor import NoisyForceTorqueSensor
from ftdrake.testing import THETA, sinusoids

LOG_HZ = 50


def run(config, duration, seed):
    """(X at the logged samples, readings, temperature, times)."""
    n = round(duration * 1000) + 1
    X = sinusoids(np.random.default_rng(seed), range(7), n=n, duration=duration, amplitude=0.5)
    model = PhysicsPayloadCompensator()
    phi = np.r_[THETA[:10], np.zeros(6)]
    ideal = np.vstack([model.regressor(X[i:i + 50_000]) @ phi for i in range(0, n, 50_000)])
    t = np.linspace(0, duration, n)
    builder = DiagramBuilder()
    source = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, ideal.T)))
    dut = builder.AddSystem(NoisyForceTorqueSensor(config))
    builder.Connect(source.get_output_port(), dut.get_input_port_wrench_ideal())
    period = dut.period * round(1000 / LOG_HZ)
    wrench = LogVectorOutput(dut.get_output_port_wrench_measured(), builder, period)
    temperature = LogVectorOutput(dut.get_output_port_temperature(), builder, period)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    ts = wrench.FindLog(context).sample_times()[1:]
    rows = np.round((ts - dut.period) / dut.period).astype(int)
    return (X[rows], wrench.FindLog(context).data().T[1:],
            temperature.FindLog(context).data()[0, 1:], ts)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    args = parser.parse_args(argv)
    duration = 60.0 * args.minutes
    results = {}
    start = time.perf_counter()
    for label, drift in (("no random walk", [0.0] * 6), ("with random walk", None)):
        extra = {} if drift is None else {"drift_std": drift}
        train_config = SensorConfig(seed=1, crosstalk=0.0, mounting_rpy_deg=[0.0] * 3, **extra)
        test_config = SensorConfig(seed=2, crosstalk=0.0, mounting_rpy_deg=[0.0] * 3, **extra)
        sigma = np.asarray(train_config.spec().noise_std)
        X, Y, T, _ = run(train_config, min(600.0, duration), seed=1)
        Xt, Yt, Tt, tt = run(test_config, duration, seed=2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            plain = PhysicsPayloadCompensator(identification="consistent").fit(X, Y)
            warm = PhysicsPayloadCompensator(identification="consistent").fit(np.c_[X, T], Y)
        row = {}
        for name, model, Xm in (("without temperature", plain, Xt),
                                ("with temperature", warm, np.c_[Xt, Tt])):
            c = Yt - model.predict(Xm)
            means = np.array([c[(tt >= a) & (tt < a + 10)].mean(axis=0)
                              for a in np.arange(0, duration - 10 + 1e-9, 10)])
            row[name] = (np.abs(means).max(axis=0) / sigma).round(2).tolist()
        row["identified k (N/K, N*m/K)"] = np.round(warm.temperature_coefficients_, 5).tolist()
        row["true k"] = train_config.temperature_coefficients
        results[label] = row
    elapsed = time.perf_counter() - start
    print(f"{args.minutes:g}-minute warm-up (22 -> 32 °C, tau 10 min); worst 10-s mean of the "
          "compensated wrench, in noise σ, per axis Fx Fy Fz Tx Ty Tz")
    for label, row in results.items():
        for name in ("without temperature", "with temperature"):
            print(f"  {label:17s} {name:20s} " + " ".join(f"{v:6.2f}" for v in row[name]))
    print(json.dumps({"benchmark": "temperature_drift", "minutes": args.minutes,
                      "results": results, "seconds": round(elapsed, 1),
                      "machine": platform.machine(), "python": platform.python_version()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
