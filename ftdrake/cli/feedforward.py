"""`ftdrake learn-feedforward`: learn the torque feedforward iteratively, ILC beside it.

    ftdrake learn-feedforward [--iterations 5] [--trajectory rehearsal] [--out DIR]
    ftdrake learn-feedforward --two-part [--measurement timed|contour|both] [--diameter MM]
                              [--save-model FILE]
    ftdrake learn-feedforward --two-part --family quick|full [--out DIR]

Runs :func:`ftdrake.experiments.feedforward.run_feedforward_experiment` (friction on; the
controller's model knows neither it nor the true tool) and writes ``summary.json``,
``iterations.csv``, ``tracking.png`` and the final model ``feedforward_model.ftd``.

With ``--two-part``: the hole-cutting benchmark with compliant joints
(:func:`ftdrake.experiments.contour.run_contour_experiment`): torque feedforward only, the
two-part compensation with the chosen tool measurement, and ILC of the motor reference;
writes ``summary.json``, ``iterations.csv`` and ``contour.png``. With ``--family``: the
transfer of each method's correction to other contours
(:func:`ftdrake.experiments.contour_family.run_contour_family`).
"""

from __future__ import annotations

import dataclasses as dc
import logging
from pathlib import Path

from . import args as a


def register(subparsers) -> None:
    """Adds ``ftdrake learn-feedforward`` to an argparse subparsers."""
    p = a.add_command(
        subparsers, "learn-feedforward",
        "learn the torque feedforward (GP), ILC beside it",
        "A GP learns from earlier runs; a time-indexed ILC is the baseline.")
    p.add_argument("--iterations", type=a.positive_int, metavar="N",
                   help="learning iterations; with --family quick 2 unless given (default: 5)")
    a.add_trajectory(p, default="rehearsal",
                     help="the task's trajectory kind (rehearsal: the contact task in the air)")
    p.add_argument("--out", type=a.output_folder, default="out/feedforward", metavar="DIR",
                   help="folder for summary.json, iterations.csv, tracking.png and the model")
    a.add_config(p)
    a.add_seed(p, 0, "every random draw: the trajectory, the GP fits; with --two-part also the "
                     "tool measurements' noise")
    p.add_argument("--duration", type=a.positive_float, metavar="S",
                   help="seconds per run (default: the scenario's trajectory.duration_s)")
    p.add_argument("--target", choices=["model_error", "feedback"], default="model_error",
                   help="what the GP learns (see FeedforwardPlan.target)")
    p.add_argument("--ilc-gain", type=a.positive_float, default=1.0, metavar="GAMMA",
                   help="the ILC baseline's learning gain γ")
    p.add_argument("--ilc-cutoff", type=a.positive_float, default=5.0, metavar="HZ",
                   help="the ILC baseline's Q-filter cut-off (zero-phase Butterworth), Hz")
    a.add_quiet(p)
    two = p.add_argument_group("two-part compensation (hole cutting, compliant joints)")
    two.add_argument("--two-part", action="store_true",
                     help="the hole-cutting benchmark: torque feedforward plus the learned "
                          "motor-reference correction from tool measurements")
    two.add_argument("--measurement", choices=["timed", "contour", "both"], default="both",
                     help="the tool measurement part two learns from: timed (laser-tracker "
                          "like) or an untimed contour scan")
    two.add_argument("--diameter", type=a.positive_float, default=20.0, metavar="MM",
                     help="the learned hole's diameter")
    two.add_argument("--new-diameter", type=a.positive_float, default=26.0, metavar="MM",
                     help="the hole run without relearning (its centre moved)")
    two.add_argument("--speed", type=a.positive_float, default=30.0, metavar="MM/S",
                     help="cutting speed")
    two.add_argument("--save-model", type=a.output_file, metavar="FILE",
                     help="write the learned two-part model (the timed method's, else the "
                          "contour one's) to FILE, for `ftdrake export-correction`")
    two.add_argument("--family", choices=["quick", "full"],
                     help="learn on the hole, then run each method's correction on a family "
                          "of other contours (speed, direction, new holes; full: tilted "
                          "planes, a 3-D path, a slot) and on the pooled data of earlier "
                          "contours; writes transfer.json, learning_curve.json, summary.json")
    two.add_argument("--members", type=lambda v: [m for m in v.split(",") if m],
                     metavar="NAME,...",
                     help="with --family: run these contours of the full family instead "
                          "(speed_60, reversed, hole_40_elsewhere, hole_10_elsewhere, "
                          "hole_60_elsewhere, tilted_x20, tilted_y20, 3d_reoriented, "
                          "slot_corners)")
    p.set_defaults(run=run_command)


def run_command(args) -> int:
    from ..experiments import feedforward as experiment

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.family is not None and not args.two_part:
        raise a.ConfigError("--family: runs the hole-cutting benchmark; add --two-part")
    if args.family is not None:
        return _run_family(args)
    if args.two_part:
        return _run_two_part(args)
    plan = experiment.FeedforwardPlan(iterations=args.iterations or 5, trajectory=args.trajectory,
                                      seed=args.seed, duration_s=args.duration,
                                      target=args.target, ilc_gain=args.ilc_gain,
                                      ilc_cutoff_hz=args.ilc_cutoff)
    summary = experiment.run_feedforward_experiment(
        a.load_scenario(args), plan, args.out, progress=not args.quiet)
    print(f"wrote {args.out}/summary.json, iterations.csv, tracking.png, feedforward_model.ftd "
          f"in {summary['wall_time_s']:.0f} s")
    print("tool-tip tracking RMS (mm) per iteration:")
    for method in ("gp", "ilc"):
        tips = summary["task"][method]["tip_rms_mm"]
        print(f"  {method:>4}: " + "  ".join(f"{x:.3g}" for x in tips)
              + f"   ({summary['task'][method]['improvement']:.1f}×)")
    g = summary["generalisation"]
    print(f"new trajectory (same path at {g['speed']:.0%} speed), tool-tip RMS (mm): "
          + ", ".join(f"{k} {g[k]['tip_rms_mm']:.3g} ({g[k]['improvement']:.1f}×)"
                      for k in ("none", "gp", "ilc")))
    for goal, met in summary["goals"].items():
        print(f"  {'yes' if met else 'NO '} {goal}")
    return 0


def provenance() -> dict:
    """The result files' provenance record (:func:`ftdrake.version.result_provenance`)."""
    from ..version import result_provenance

    return result_provenance()


def _run_two_part(args) -> int:
    from ..experiments import contour

    plan = contour.ContourPlan(iterations=args.iterations or 5).with_seed(args.seed)
    measured = ("timed", "contour") if args.measurement == "both" else (args.measurement,)
    plan = dc.replace(
        plan, methods=("torque", *measured, "ilc"),
        hole=dc.replace(plan.hole, diameter_m=args.diameter / 1e3, speed_m_s=args.speed / 1e3),
        new_hole=dc.replace(plan.new_hole, diameter_m=args.new_diameter / 1e3,
                            speed_m_s=args.speed / 1e3))
    out = args.out if args.out != Path("out/feedforward") else Path("out/two_part")
    summary = contour.run_contour_experiment(a.load_scenario(args), plan, out,
                                             progress=not args.quiet,
                                             model_out=args.save_model,
                                             provenance=provenance())
    first = summary["first_run"]
    print(f"wrote {out}/summary.json, iterations.csv, contour.png in "
          f"{summary['wall_time_s']:.0f} s")
    if args.save_model is not None:
        print(f"wrote the two-part model {args.save_model}")
    print(f"no learning: radial RMS {first['radial_rms_mm']:.4f} mm, max "
          f"{first['radial_max_mm']:.4f} mm; the encoders miss "
          f"{100 * first['invisible_share']:.0f} % of the tool error (RMS)")
    print("hole radial RMS error (mm) per iteration:")
    for method, values in summary["task"].items():
        print(f"  {method:>8}: " + "  ".join(f"{x:.4f}" for x in values["radial_rms_mm"]))
    g = summary["generalisation"]
    print("new hole without relearning, radial RMS (mm): "
          + ", ".join(f"{k} {v['radial_rms_mm']:.4f} ({v['improvement']:.1f}×)"
                      for k, v in g.items()))
    for goal, met in summary["goals"].items():
        print(f"  {'yes' if met else 'NO '} {goal}")
    return 0


def _run_family(args) -> int:
    from ..experiments import contour_family as family

    plan = family.family_plan(args.family, args.iterations, args.seed, args.members)
    out = (args.out if args.out != Path("out/feedforward")
           else Path(f"out/two_part_family_{args.family}"))
    summary = family.run_contour_family(a.load_scenario(args), plan, out,
                                        progress=not args.quiet, provenance=provenance())
    print(f"wrote {out}/transfer.json, learning_curve.json, summary.json in "
          f"{summary['wall_time_s']:.0f} s")
    base = summary["base_hole_radial_rms_mm"]
    print("learned hole, radial RMS (mm) per iteration: "
          + "; ".join(f"{k} " + " ".join(f"{x:.4f}" for x in v) for k, v in base.items()))
    columns = list(family.TRANSFER_METHODS)
    print("kept improvement K = radial RMS without learning / with the correction learned "
          "elsewhere:")
    print(f"  {'contour':<20}{'none (mm)':>10}" + "".join(f"{c:>18}" for c in columns))
    for name, kept in summary["transfer"].items():
        none = summary["radial_rms_mm"][name]["none"]
        print(f"  {name:<20}{none:>10.4f}"
              + "".join(f"{kept[c]:>17.1f}×" if c in kept else f"{'-':>18}" for c in columns))
    curve = summary["learning_curve"]
    print(f"learning curve on {curve['contour']} (radial RMS, mm, by contours pooled): "
          + ", ".join(f"{n} {r:.4f} ({k:.1f}×)" for n, r, k in
                      zip(curve["contours_learned_from"], curve["radial_rms_mm"],
                          curve["improvement"], strict=True)))
    for goal, met in summary["goals"].items():
        print(f"  {'yes' if met else 'NO '} {goal}")
    return 0
