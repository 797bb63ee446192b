"""`ftdrake learn-feedforward`: learn the torque feedforward iteratively, ILC beside it.

    ftdrake learn-feedforward [--iterations 5] [--trajectory rehearsal] [--out DIR]

Runs :func:`ftdrake.experiments.feedforward.run_feedforward_experiment` (friction on; the
controller's model knows neither it nor the true tool) and writes ``summary.json``,
``iterations.csv``, ``tracking.png`` and the final model ``feedforward_model.ftd``.
"""

from __future__ import annotations

import logging

from ..experiments import feedforward as experiment
from . import args as a


def register(subparsers) -> None:
    """Adds ``ftdrake learn-feedforward`` to an argparse subparsers."""
    p = a.add_command(
        subparsers, "learn-feedforward",
        "learn the torque feedforward (GP), ILC beside it",
        "A GP learns from earlier runs; a time-indexed ILC is the baseline.")
    p.add_argument("--iterations", type=a.positive_int, default=5, metavar="N",
                   help="learning iterations")
    a.add_trajectory(p, default="rehearsal",
                     help="the task's trajectory kind (rehearsal: the contact task in the air)")
    p.add_argument("--out", type=a.output_folder, default="out/feedforward", metavar="DIR",
                   help="folder for summary.json, iterations.csv, tracking.png and the model")
    a.add_config(p)
    a.add_seed(p, 0, "the trajectory's seed")
    p.add_argument("--duration", type=a.positive_float, metavar="S",
                   help="seconds per run (default: the scenario's trajectory.duration_s)")
    p.add_argument("--target", choices=["model_error", "feedback"], default="model_error",
                   help="what the GP learns (see FeedforwardPlan.target)")
    p.add_argument("--ilc-gain", type=a.positive_float, default=1.0, metavar="GAMMA",
                   help="the ILC baseline's learning gain γ")
    p.add_argument("--ilc-cutoff", type=a.positive_float, default=5.0, metavar="HZ",
                   help="the ILC baseline's Q-filter cut-off (zero-phase Butterworth), Hz")
    a.add_quiet(p)
    p.set_defaults(run=run_command)


def run_command(args) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    plan = experiment.FeedforwardPlan(iterations=args.iterations, trajectory=args.trajectory,
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
