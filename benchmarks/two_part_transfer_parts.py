"""Which part of the two-part correction breaks when it runs on a contour it has not learned.

Learns the two-part timed correction on the ``quick`` family's base hole (as
``ftdrake learn-feedforward --two-part --family quick`` does, same seeds), then runs two of the
family's contours with part two only (the motor-reference correction), part one only (the
torque feedforward) and both, and prints each run's radial RMS and max (mm), the radial RMS the
motor angles show, the motor-side tracking RMS (mrad), and the reference correction's mean
confidence per joint on the hole. Takes a few minutes (about 11 simulated runs).

    OMP_NUM_THREADS=1 python benchmarks/two_part_transfer_parts.py
"""

from __future__ import annotations

import numpy as np

from ftdrake.config import ScenarioConfig
from ftdrake.experiments.contour import HoleRunner, Learner, contour_scenario
from ftdrake.experiments.contour_family import family_plan
from ftdrake.experiments.reference_correction import ReferenceCorrection, desired_states


def _learn(runner, plan):
    base = runner.task(plan.hole)
    last = runner.run(base)
    learner = Learner("timed", runner, base, plan)
    learner.record_applied(None)
    for k in range(1, plan.iterations + 1):
        learner.update(last, k)
        reference = learner.reference(base)
        learner.record_applied(reference)
        last = runner.run(base, reference, learner.feedforward())
    print(f"learned hole, two-part timed: radial RMS {last['radial_rms_mm']:.4f} mm")
    return learner


def main() -> None:
    family = family_plan("quick")
    plan = family.contour
    runner = HoleRunner(contour_scenario(ScenarioConfig()))
    learner = _learn(runner, plan)
    correction = ReferenceCorrection(learner.reference_model, trust_ratio=plan.trust_ratio,
                                     reject_ratio=plan.reject_ratio)
    for name in ("hole_40_elsewhere", "speed_60"):
        task = runner.task(family.members[name])
        none = runner.run(task)
        confidence = correction.evaluate(desired_states(task.trajectory, none["t"]))[2]
        on_hole = np.round(confidence[none["on_hole"]].mean(0), 2)
        print(f"{name}: no learning {none['radial_rms_mm']:.4f} mm; part two's mean "
              f"confidence per joint on the hole {on_hole}")
        for label, reference, feedforward in (
                ("part two only", learner.reference(task), None),
                ("part one only", None, learner.feedforward()),
                ("both", learner.reference(task), learner.feedforward())):
            run = runner.run(task, reference, feedforward)
            print(f"  {label:>14}: radial RMS {run['radial_rms_mm']:.4f} mm (max "
                  f"{run['radial_max_mm']:.4f}), motor-visible {run['radial_motor_rms_mm']:.4f} "
                  f"mm, motor tracking {run['motor_rms_mrad']:.2f} mrad")


if __name__ == "__main__":
    main()
