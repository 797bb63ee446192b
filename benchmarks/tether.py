"""What a tethered-cable model removes, on the default cable and on a second geometry.

Two simulated cables (sim/cable.py: a spring from a point on a link to a point on the tool,
0.5 N·s/m of damping, and a hanging weight):

* ``A``: the default scenario's (anchored on link_r, 25 N/m, 0.20 m, 1.2 N);
* ``B``: one the model was not designed on (on the upper arm link_u, 60 N/m, 0.35 m, 2.0 N).

For each: 6 × 20 s Fourier runs to fit on (every 4th row), 2 held-out Fourier runs and 2
held-out rehearsals (the contact task's motion, stopping above the surface). Six models:
the payload model of the demo (mounting, weight without inertia) without a tether, with
``tether="auto"``, and with the tether and ``identify_crosstalk``; and the hybrid on each.
Printed per axis (Fx … Tz): the held-out RMS of prediction − ``internal_true_*`` (what the sensor
reads without contact, noise and drift; each run's mean removed, as the bias tracker removes
it) over the sensor's noise σ. Then the same fit on the plant's own reaction at the weld
(``ideal_*``: no sensor imperfections), with the identified geometry against the injected one.

    python benchmarks/tether.py [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import time
import warnings

import numpy as np

from ftdrake import ScenarioConfig
from ftdrake.compensation.estimators.hybrid import HybridCompensator
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.io import atomic_write_text
from ftdrake.sim.collection import collect

CABLES = {
    "A": {},
    "B": {"anchor_body": "link_u", "p_anchor": [0.05, 0.0, 0.15], "stiffness": 60.0,
          "rest_length": 0.35, "weight_n": 2.0},
}


def _data(cable):
    config = ScenarioConfig()
    config.cable = dc.replace(config.cable, **cable)
    return (config,
            collect(config, 6, kind="fourier", duration=20.0, progress=False),
            {"fourier": collect(config, 2, kind="fourier", seed=300, duration=20.0,
                                progress=False),
             "rehearsal": collect(config, 2, kind="rehearsal", seed=100, progress=False)})


def _models(X, Y):
    out, times = {}, {}
    for tether, crosstalk in ((None, False), ("auto", False), ("auto", True)):
        name = ("tether" if tether else "no tether") + (" + cross-talk" if crosstalk else "")
        for kind in ("physics", "hybrid"):
            physics = PhysicsPayloadCompensator(identify_mounting=True,
                                                weight_without_inertia=True, tether=tether,
                                                identify_crosstalk=crosstalk)
            model = physics if kind == "physics" else HybridCompensator(physics=physics)
            started = time.perf_counter()
            out[f"{kind}, {name}"] = model.fit(X, Y)
            times[f"{kind}, {name}"] = round(time.perf_counter() - started, 1)
    return out, times


def _error_over_noise(model, frame, noise):
    X = joint_state_layout(frame)
    error = model.predict(X) - wrench_targets(frame, "internal_true")
    keep = frame["t"].to_numpy() > 0.5
    error, runs = error[keep], frame["trajectory"].to_numpy()[keep]
    for run in np.unique(runs):
        error[runs == run] -= error[runs == run].mean(axis=0)
    return (np.sqrt(np.mean(error ** 2, axis=0)) / noise).round(2).tolist()


def _geometry(model, config):
    return {"frame": model.tether_frame_, "anchor_m": model.tether_anchor_.round(4).tolist(),
            "attach_m": model.tether_attach_.round(4).tolist(),
            "stiffness_n_per_m": round(float(model.parameters_[20]), 2),
            "rest_length_m": round(float(model.parameters_[21] / model.parameters_[20]), 4),
            "hanging_weight_n": round(float(model.parameters_[16] * 9.81), 3),
            "tool_mass_kg": round(float(model.parameters_[0]), 4),
            "injected": {"body": config.cable.anchor_body, "anchor_m": config.cable.p_anchor,
                         "attach_m": config.cable.p_SAttach,
                         "stiffness_n_per_m": config.cable.stiffness,
                         "rest_length_m": config.cable.rest_length,
                         "hanging_weight_n": config.cable.weight_n, "tool_mass_kg": 1.5}}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore", ExcitationWarning)
    results = {}
    for name, cable in CABLES.items():
        config, train, held_out = _data(cable)
        noise = np.asarray(config.sensor.spec().noise_std)
        X, Y = joint_state_layout(train)[::4], wrench_targets(train)[::4]
        models, times = _models(X, Y)
        # The plant's reaction is exact for the plant's own q̈ (the logs' qdd_est lags it).
        ideal = PhysicsPayloadCompensator(weight_without_inertia=True, tether="auto").fit(
            joint_state_layout(train, "plant")[::4], wrench_targets(train, "ideal")[::4])
        results[name] = {
            "held_out_error_over_noise": {
                kind: {label: _error_over_noise(m, frame, noise) for label, m in models.items()}
                for kind, frame in held_out.items()},
            "fit_time_s": times,
            "identified_from_measured": _geometry(models["physics, tether"], config),
            "identified_from_measured_with_crosstalk": _geometry(
                models["physics, tether + cross-talk"], config),
            "identified_from_plant_reaction": _geometry(ideal, config),
        }
        print(f"cable {name}: held-out RMS / noise σ (Fx Fy Fz Tx Ty Tz)")
        for kind, rows in results[name]["held_out_error_over_noise"].items():
            for label, row in rows.items():
                print(f"  {kind:9s} {label:20s} " + " ".join(f"{v:6.2f}" for v in row))
        for source in ("identified_from_measured", "identified_from_measured_with_crosstalk",
                       "identified_from_plant_reaction"):
            print(f"  {source}: {json.dumps(results[name][source])}")
        print(f"  fit times (s): {times}", flush=True)
    if args.json:
        atomic_write_text(args.json, json.dumps(results, indent=1))
    print(json.dumps(results))


if __name__ == "__main__":
    main()
