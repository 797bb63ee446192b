"""`ftdrake learn-feedforward`: learn the torque feedforward iteratively, ILC beside it.

    ftdrake learn-feedforward [--iterations 5] [--trajectory rehearsal] [--out DIR]

Runs :func:`ftdrake.experiments.feedforward.run_feedforward_experiment` (friction on; the
controller's model knows neither it nor the true tool) and writes ``summary.json``,
``iterations.csv``, ``tracking.png`` and the final model ``feedforward_model.ftd``.
"""

from __future__ import annotations

import logging
from pathlib import Path

from ..config import TRAJECTORY_KINDS, load_config
from ..experiments import feedforward as experiment


def register(subparsers) -> None:
    """Adds ``ftdrake learn-feedforward`` to an argparse subparsers."""
    p = subparsers.add_parser(
        "learn-feedforward",
        help="learn the torque feedforward from earlier runs (GP), time-indexed ILC beside it")
    p.add_argument("--iterations", type=int, default=5, help="learning iterations (default 5)")
    p.add_argument("--trajectory", choices=TRAJECTORY_KINDS, default="rehearsal",
                   help="the task's trajectory kind (default: rehearsal, the contact task "
                        "in the air)")
    p.add_argument("--out", type=Path, default=Path("out/feedforward"))
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--seed", type=int, default=0, help="the trajectory's seed")
    p.add_argument("--duration", type=float, default=None, help="seconds per run")
    p.add_argument("--target", choices=["model_error", "feedback"], default="model_error",
                   help="what the GP learns (see FeedforwardPlan.target)")
    p.add_argument("--ilc-gain", type=float, default=1.0,
                   help="the ILC baseline's learning gain γ (default 1)")
    p.add_argument("--ilc-cutoff", type=float, default=5.0, metavar="HZ",
                   help="the ILC baseline's Q-filter cut-off (zero-phase Butterworth), "
                        "default 5 Hz")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(run=run_command)


def run_command(args) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    plan = experiment.FeedforwardPlan(iterations=args.iterations, trajectory=args.trajectory,
                                      seed=args.seed, duration_s=args.duration,
                                      target=args.target, ilc_gain=args.ilc_gain,
                                      ilc_cutoff_hz=args.ilc_cutoff)
    summary = experiment.run_feedforward_experiment(
        load_config(args.config), plan, args.out, progress=not args.quiet)
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
