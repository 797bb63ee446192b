"""Joint-only vs IMU compensation in motion on the compliant rig, per axis, × the resting noise.

The rig (``scenario.transmission``): compliant joints on, the F/T loop and the log reading the
motor-side encoders (``chain_reads_motors``) and a gearbox transmission error that makes the
wrist vibrate in motion (``transmission_error``, rad per joint); an IMU at the sensor
(``scenario.imu``, its default noise unless told otherwise). The sensor keeps its noise, bias,
quantization, filter and mounting error but has no cross-talk, drift or warm-up (so that what
the models miss is the motion). Cable off.

Each run is a Fourier excitation of ``--duration`` s; the first 0.2 s are dropped, the models
fit the first 70 % of the rest and are scored on the last 30 % (held out): the std of
``measured − predicted`` per axis divided by the resting noise, the std of ``measured −
internal_true`` of the same run (the sensor's own noise: what it reads at rest).

Rows printed:

* ``rigid``: rigid joints (the loop reads the links): the physics model on the joints.
* ``compliant``: compliant joints, no transmission error: the physics model on the motors'
  joints (the check that the compliance alone does not explain the effect).
* ``vibrating``: with the transmission error: joints (q̈ the motors' steps), joints with the
  loop's own q̈ estimate (``qdd_est``), and the IMU model at each ``--cutoffs`` of the
  gyroscope's causal derivative (the ``imu_alpha`` columns recomputed from ``imu_gyro``);
  then the same IMU model with an ideal IMU and with a consumer-grade IMU (``--consumer``
  noise).

    python benchmarks/imu_compensation.py [--duration 4] [--error 3e-5] [--json out.json]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import warnings

import numpy as np

from ftdrake import conventions as col
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.compensation.features import stack_layout
from ftdrake.config import ScenarioConfig
from ftdrake.signals import causal_acceleration
from ftdrake.sim.simulate import simulate
from ftdrake.sim.station import build_station

AXES = col.WRENCH_AXES
#: A consumer MEMS IMU's noise per sample at 1 kHz (m/s², rad/s; see ftdrake/config/imu.py).
CONSUMER = (0.038, 5.5e-3)


def rig(duration: float, error: float, compliant: bool = True, imu=None) -> ScenarioConfig:
    config = ScenarioConfig()
    config.cable.enabled = False
    config.trajectory.kind = "fourier"
    config.trajectory.duration_s = duration
    config.sensor = dc.replace(config.sensor, crosstalk=0.0, temperature_rise_c=0.0,
                               drift_std=[0.0] * 6)
    config.imu = dc.replace(imu or config.imu, enabled=True)
    if compliant:
        config.transmission = dc.replace(
            config.transmission, enabled=True, chain_reads_motors=True,
            transmission_error=[error] * 7 if error > 0 else [])
    return config.validate()


def run(config):
    log = simulate(build_station(config), progress=False).log
    log = log[log[col.TIME] > 0.2].reset_index(drop=True)
    Y = log[col.wrench_columns(col.MEASURED)].to_numpy()
    noise = (Y - log[col.wrench_columns(col.INTERNAL_TRUE)].to_numpy()).std(axis=0)
    return log, Y, noise


def joints(log, qdd=col.QDD):
    return stack_layout(*(log[col.joint_columns(p)].to_numpy() for p in (col.Q, col.QD, qdd)))


def with_imu(log, period, cutoff):
    gyro = log[col.imu_columns(col.IMU_GYRO)].to_numpy()
    return np.hstack([joints(log), log[col.imu_columns(col.IMU_ACC)].to_numpy(), gyro,
                      causal_acceleration(gyro, period, cutoff)])


def held_out_ratio(model, X, Y, noise) -> np.ndarray:
    """std of the held-out residual per axis / the resting noise."""
    split = len(Y) * 7 // 10
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a short run leaves some inertia poorly excited
        model.fit(X[:split], Y[:split])
    return (Y[split:] - model.predict(X[split:])).std(axis=0) / noise


def physics():
    return PhysicsPayloadCompensator(identify_mounting=True)


def imu_model():
    return ImuPayloadCompensator(identify_mounting=True)


def measure(args) -> dict:
    rows = {}
    period = 1.0 / ScenarioConfig().sensor.spec().rate_hz
    log, Y, noise = run(rig(args.duration, 0.0, compliant=False))
    rows["rigid: joints"] = held_out_ratio(physics(), joints(log), Y, noise)
    rows["rigid: IMU"] = held_out_ratio(imu_model(), with_imu(log, period, args.cutoff), Y,
                                        noise)
    log, Y, noise = run(rig(args.duration, 0.0))
    rows["compliant: joints"] = held_out_ratio(physics(), joints(log), Y, noise)
    log, Y, noise = run(rig(args.duration, args.error))
    resting = noise
    rows["vibrating: joints"] = held_out_ratio(physics(), joints(log), Y, noise)
    rows["vibrating: joints, qdd_est"] = held_out_ratio(physics(), joints(log, col.QDD_EST), Y,
                                                        noise)
    for cutoff in args.cutoffs:
        rows[f"vibrating: IMU, α at {cutoff:g} Hz"] = held_out_ratio(
            imu_model(), with_imu(log, period, cutoff), Y, noise)
    ideal = ScenarioConfig().imu.without_noise()
    log, Y, noise = run(rig(args.duration, args.error, imu=ideal))
    rows[f"vibrating: ideal IMU, α at {args.cutoff:g} Hz"] = held_out_ratio(
        imu_model(), with_imu(log, period, args.cutoff), Y, noise)
    rows["vibrating: ideal IMU, α at 100 Hz"] = held_out_ratio(
        imu_model(), with_imu(log, period, 100.0), Y, noise)
    consumer = dc.replace(ScenarioConfig().imu, accelerometer_noise_std=[CONSUMER[0]] * 3,
                          gyroscope_noise_std=[CONSUMER[1]] * 3)
    log, Y, noise = run(rig(args.duration, args.error, imu=consumer))
    for cutoff in (2.0, 5.0, args.cutoff):
        rows[f"vibrating: consumer IMU, α at {cutoff:g} Hz"] = held_out_ratio(
            imu_model(), with_imu(log, period, cutoff), Y, noise)
    return {"resting_noise": resting, "rows": rows}


def verdict(rows, cutoff) -> str:
    joint = rows["vibrating: joints"]
    imu = rows[f"vibrating: IMU, α at {cutoff:g} Hz"]
    axes = [a for a, j in zip(AXES, joint, strict=True) if j >= 3.0]
    met = all(i <= 1.5 for i, j in zip(imu, joint, strict=True) if j >= 3.0)
    return (f"goal (IMU ≤ 1.5× where joints ≥ 3×; axes {', '.join(axes) or 'none'}; α at "
            f"{cutoff:g} Hz): {'met' if met else 'NOT met'}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=4.0, help="s of simulation per run")
    parser.add_argument("--error", type=float, default=3e-5,
                        help="transmission error, rad at the output, every joint")
    parser.add_argument("--cutoff", type=float, default=ScenarioConfig().imu.alpha_cutoff_hz,
                        help="Hz, the α cut-off of the goal's row (default: the config's)")
    parser.add_argument("--cutoffs", type=lambda s: [float(v) for v in s.split(",")],
                        default=[3.0, 5.0, 10.0, 20.0, 40.0], help="Hz, α cut-offs to compare")
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args()
    if args.cutoff not in args.cutoffs:
        args.cutoffs.append(args.cutoff)
    result = measure(args)
    noise = result["resting_noise"]
    print("resting noise (std of measured − internal_true): "
          + ", ".join(f"{a} {v:.4g}" for a, v in zip(AXES, noise, strict=True)))
    print(f"held-out error × resting noise ({args.duration:g} s runs, transmission error "
          f"{args.error:g} rad)")
    print(f"{'':44s}" + "".join(f"{a:>7s}" for a in AXES))
    for name, values in result["rows"].items():
        print(f"{name:44s}" + "".join(f"{v:7.2f}" for v in values))
    print(verdict(result["rows"], args.cutoff))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"args": vars(args), "resting_noise": noise.tolist(),
                       "rows": {k: v.tolist() for k, v in result["rows"].items()}}, f,
                      indent=1)


if __name__ == "__main__":
    main()
