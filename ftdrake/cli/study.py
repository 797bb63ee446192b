"""``ftdrake study``: parse → run the study → print the estimate and the findings."""

from __future__ import annotations

from pathlib import Path

from ..config import load_config
from ..experiments import study
from ..experiments.study import FEATURES, FIGURES


def register(subparsers) -> None:
    """Adds ``ftdrake study [--quick|--paper] [--out DIR] ...`` to an argparse subparsers."""
    p = subparsers.add_parser("study", help="RF vs SVR (+ physics, hybrid): the study repeated")
    grid = p.add_mutually_exclusive_group()
    grid.add_argument("--quick", dest="preset", action="store_const", const="quick",
                      help="small grids, ~3 min on 2 cores (default)")
    grid.add_argument("--paper", dest="preset", action="store_const", const="paper",
                      help="the study's full grids (days; not for CI)")
    p.add_argument("--out", type=Path, default=Path("out/study"))
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--trajectories", type=int, default=study.TRAJECTORIES,
                   help="runs per dataset")
    p.add_argument("--test-trajectories", type=int, default=study.TEST_TRAJECTORIES,
                   help="of those, held out whole for testing")
    p.add_argument("--duration", type=float, default=study.DURATION_S, help="seconds per run")
    p.add_argument("--train-hz", type=float, default=study.TRAIN_HZ,
                   help="training rows per second of log (logs are 1 kHz)")
    p.add_argument("--cv", choices=["grouped", "shuffled"], default="grouped")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=-1, help="worker processes (-1: all cores)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(preset="quick", run=run_command)


def run_command(args) -> int:
    """Prints the grid and time estimate, runs the study, prints the findings."""
    sizes = study.grid_sizes(args.preset)
    estimate = study.estimate_seconds(
        args.preset, trajectories=args.trajectories, duration=args.duration,
        test_trajectories=args.test_trajectories, train_hz=args.train_hz, n_jobs=args.jobs)
    print(f"study, preset {args.preset}: grid sizes per feature set "
          + "; ".join(f"{k} {_fmt_sizes(v)}" for k, v in sizes.items())
          + f"; estimated time {_fmt_duration(estimate)} on an idle machine"
          + (" (a lower bound: large-C SVR fits are slow)" if args.preset == "paper" else ""),
          flush=True)
    results = study.run_study(
        args.out, preset=args.preset, trajectories=args.trajectories,
        test_trajectories=args.test_trajectories, duration=args.duration,
        train_hz=args.train_hz, cv=args.cv, n_jobs=args.jobs, progress=not args.quiet,
        seed=args.seed, config=load_config(args.config))
    print(f"wrote {args.out}/results.json, results.md and {2 * len(FIGURES)} figures "
          f"in {results['wall_time_s']:.0f} s")
    for f in results["findings"]:
        print(f"  ({f['id']}) {'yes' if f['reproduced'] else 'NO '} {f['claim']}: "
              f"{f['evidence']}")
    return 0


def _fmt_sizes(sizes: dict) -> str:
    return "/".join(str(sizes[f]) for f in FEATURES)


def _fmt_duration(seconds: float) -> str:
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= 2 * size:
            return f"~{seconds / size:.0f} {unit}"
    return f"~{seconds:.0f} s"
