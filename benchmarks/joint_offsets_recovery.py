"""Joint zero offsets identified from the wrench (``identify_joint_offsets``): printed for
synthetic static poses and for the simulated rig with encoder offsets, with a gravity sag on
the shoulder pitch, and with neither (the figures of docs/guide/calibration.md, "Joint zero
offsets").

    python benchmarks/joint_offsets_recovery.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ftdrake import ScenarioConfig, build_station, simulate
from ftdrake import conventions as col
from ftdrake.compensation.calibration.joint_offsets import identify_joint_offsets
from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator
from ftdrake.config import EncoderConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import test_joint_encoders as rig_tests
import test_joint_offsets as synthetic


def rig(encoders: EncoderConfig):
    """The rig held at 13 poses (cable off), identified on the ideal wrench, every 10th row."""
    config = ScenarioConfig()
    config.cable.enabled = False
    config.encoders = encoders
    station = build_station(config.validate(), trajectory=rig_tests.held_poses(config))
    log = simulate(station, progress=False).log
    X = np.hstack([log[col.joint_columns(p, 7)].to_numpy() for p in (col.Q, col.QD, col.QDD)])
    Y = log[col.wrench_columns(col.IDEAL)].to_numpy()
    return identify_joint_offsets(X[::10], Y[::10], PhysicsPayloadCompensator(mode="dynamic"))


def main() -> None:
    model = synthetic.static_model()
    q = synthetic.poses(0)
    noise = np.random.default_rng(1).standard_normal((len(q), 6)) * synthetic.SIGMA
    result = identify_joint_offsets(q - synthetic.INJECTED, synthetic.readings(model, q, noise),
                                    model)
    print("== 300 synthetic static poses, 2° on joint_l and joint_b\n" + result.summary())
    for title, encoders in (
            ("rig: 2° on joint_l and joint_b", EncoderConfig(enabled=True,
                                                             offsets=rig_tests.OFFSETS)),
            ("rig: a sag on joint_l (k = 1000 N·m/rad), no offset",
             EncoderConfig(enabled=True, sag_stiffness=[0, 1000.0, 0, 0, 0, 0, 0])),
            ("rig: no offset, no sag", EncoderConfig())):
        print(f"== {title}\n" + rig(encoders).summary())


if __name__ == "__main__":
    main()
