"""`ftdrake export-correction`: a learned two-part model's reference correction as a CSV.

    ftdrake export-correction --model two_part.ftd --path joints.csv [--rate 1000] --out c.csv
    ftdrake export-correction --model two_part.ftd --hole 26 [--hole-offset 4,-3,0] --out c.csv

For a controller that takes a corrected joint path but no torque feedforward: the corrected
reference ``q_ref_j``, its offset from the path ``offset_j`` and the offset's std
``offset_std_j`` (rad) with the confidence, every ``1 / rate`` s along the path
(:func:`ftdrake.experiments.two_part_model.export_reference_csv`). The path is a joint path
CSV (``time, q_0 … q_{n-1}``) or a hole of the cutting benchmark (its diameter in mm; the
joint path solved by IK on the scenario's arm).
"""

from __future__ import annotations

import argparse

from . import args as a


def register(subparsers) -> None:
    """Adds ``ftdrake export-correction`` to an argparse subparsers."""
    p = a.add_command(
        subparsers, "export-correction",
        "export a two-part model's joint reference correction along a path (CSV)",
        "For controllers that take a corrected path but no torque feedforward.")
    a.add_model_file(p, help="a two-part model (learn-feedforward --two-part --save-model)",
                     required=True)
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--path", type=a.existing_file, metavar="FILE",
                       help="the joint path: CSV with columns time, q_0 … q_{n-1} (s, rad)")
    where.add_argument("--hole", type=a.positive_float, metavar="MM",
                       help="the cutting benchmark's hole of this diameter instead")
    p.add_argument("--hole-offset", type=_xyz, default=[0.0, 0.0, 0.0], metavar="X,Y,Z",
                   help="the hole's centre from the home tip (mm)")
    p.add_argument("--speed", type=a.positive_float, default=30.0, metavar="MM/S",
                   help="the hole's cutting speed")
    p.add_argument("--rate", type=a.positive_float, default=1000.0, metavar="HZ",
                   help="the controller's rate: one CSV row every 1/HZ s")
    p.add_argument("--out", type=a.output_file, required=True, metavar="FILE",
                   help="the CSV to write")
    a.add_config(p)
    p.set_defaults(run=run_command)


def _xyz(text: str) -> list[float]:
    """An argument type: three finite numbers separated by commas."""
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"must be three numbers X,Y,Z; got {text!r}")
    return [a.finite_float(part) for part in parts]


def run_command(args) -> int:
    from ..experiments.two_part_model import (
        TwoPartModel,
        export_reference_csv,
        read_joint_path,
    )

    model = TwoPartModel.load(args.model)
    if args.path is not None:
        trajectory = read_joint_path(args.path, model.n)
    else:
        trajectory = _hole_trajectory(args, model.n)
    table = export_reference_csv(model, trajectory, args.rate, args.out)
    print(f"wrote {args.out}: {len(table)} rows at {args.rate:g} Hz over "
          f"{trajectory.end_time() - trajectory.start_time():.2f} s, {model.n} joints")
    return 0


def _hole_trajectory(args, n_joints: int):
    from ..config.contour import HoleConfig
    from ..errors import ConfigError
    from ..experiments.contour import HoleRunner, contour_scenario

    runner = HoleRunner(contour_scenario(a.load_scenario(args)))
    if runner.n != n_joints:
        raise ConfigError(f"--model: learned for {n_joints} joints; the scenario's arm has "
                          f"{runner.n}")
    hole = HoleConfig(diameter_m=args.hole / 1e3, speed_m_s=args.speed / 1e3,
                      offset_m=[v / 1e3 for v in args.hole_offset])
    return runner.task(hole.validate("--hole")).trajectory
