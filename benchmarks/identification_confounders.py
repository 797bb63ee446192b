"""What pulls the identified payload and mounting off the truth: the cable, the cross-talk.

Fits the physics model (consistent, mounting identified) to 2 × 20 s of Fourier free motion of
the default scenario, then again with the cable off, then with the cable and the sensor's
cross-talk off, and prints mass, centre of mass and mounting rotation for each. Then the same
with the weight carried without inertia identified (``weight_without_inertia``), on the
default scenario, without cross-talk, and with only the cable's hanging weight (its spring
off) and no cross-talk. The tool is 1.5 kg at (20, 6.7, 86.7) mm; the sensor is mounted at
(1.5, -2, 1) deg; the cable's hanging weight is 1.2 N (0.122 kg) at (-40, 0, 40) mm.

    nice -n 5 python benchmarks/identification_confounders.py    # ~4 min on 2 cores
"""

from __future__ import annotations

import dataclasses as dc
import json
import warnings

import numpy as np

from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.config import ScenarioConfig
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.sim.collection import collect


def variants(base: ScenarioConfig) -> dict:
    """name → (scenario, identify the weight carried without inertia)."""
    no_cable = dc.replace(base, cable=dc.replace(base.cable, enabled=False))
    no_crosstalk = dc.replace(base, sensor=dc.replace(base.sensor, crosstalk=0.0))
    return {
        "default": (base, False),
        "no cable": (no_cable, False),
        "no cable, no cross-talk": (dc.replace(no_cable, sensor=no_crosstalk.sensor), False),
        "default + weight term": (base, True),
        "no cross-talk + weight term": (no_crosstalk, True),
        "cable weight only, no cross-talk + weight term": (
            dc.replace(no_crosstalk, cable=dc.replace(base.cable, stiffness=0.0)), True),
    }


def main() -> None:
    rows = []
    for name, (config, weight) in variants(ScenarioConfig()).items():
        data = collect(config, 2, kind="fourier", duration=20.0, progress=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ExcitationWarning)
            model = PhysicsPayloadCompensator(identification="consistent",
                                              identify_mounting=True,
                                              weight_without_inertia=weight).fit(
                joint_state_layout(data)[::4], wrench_targets(data)[::4])
        p = model.parameters_
        row = {"variant": name, "mass_kg": round(float(p[0]), 4),
               "com_mm": np.round(1000 * p[1:4] / p[0], 2).tolist(),
               "mounting_rpy_deg": np.round(
                   model.identified()["mounting_rpy_deg"]["value"], 3).tolist()}
        if weight:
            row["weight_mass_kg"] = round(float(p[16]), 4)
            row["weight_at_mm"] = np.round(1000 * p[17:20] / p[16], 1).tolist()
        rows.append(row)
        extra = (f"  weight {row['weight_mass_kg']:.4f} kg at {row['weight_at_mm']} mm"
                 if weight else "")
        print(f"{name:<48} mass {row['mass_kg']:.4f} kg  CoM {row['com_mm']} mm  "
              f"mounting {row['mounting_rpy_deg']} deg{extra}", flush=True)
    print(json.dumps({"benchmark": "identification_confounders", "rows": rows}))


if __name__ == "__main__":
    main()
