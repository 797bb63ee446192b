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
                      help="small grids, one search per protocol pair (see "
                           "docs/study/quick_vs_full.md); under 5 min on 2 idle cores (default)")
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
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="--paper: a Dask scheduler (default: a LocalCluster of --jobs workers)")
    p.add_argument("--search", choices=["halving", "grid"], default="halving",
                   help="--paper: successive halving (default) or the exhaustive grid")
    p.add_argument("--features", default="q",
                   help="--paper: feature sets, ';'-separated (default: q)")
    p.add_argument("--max-train-rows", type=int, default=None,
                   help="--paper: training rows drawn from the split (default: all)")
    p.add_argument("--halving-factor", type=int, default=None,
                   help="--paper --search halving: keep 1/FACTOR per round (default 3)")
    p.add_argument("--rf-resource", choices=["n_estimators", "n_samples"], default=None,
                   help="--paper --search halving: RF's budget, trees (default) or rows")
    p.add_argument("--svr-max-iter", type=int, default=None,
                   help="--paper: libsvm iteration cap per SVR fit (default 100000; -1 none)")
    p.add_argument("--tool-table", action="store_true",
                   help="only simulate the study's trajectory and write study_tool.md")
    p.set_defaults(preset="quick", run=run_command)


def run_command(args) -> int:
    """Prints the grid and time estimate, runs the study, prints the findings."""
    if args.tool_table:
        return _tool_table(args)
    if args.preset == "paper":
        return _paper(args)
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
    for p, found in results.get("study_protocols", {}).get("findings", {}).items():
        print(f"  study trajectory, {p}: "
              + ", ".join(f"({k}) {v['reproduced']}" for k, v in found.items()))
    return 0


def _fmt_sizes(sizes: dict) -> str:
    return "/".join(str(sizes[f]) for f in FEATURES)


def _fmt_duration(seconds: float) -> str:
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= 2 * size:
            return f"~{seconds / size:.0f} {unit}"
    return f"~{seconds:.0f} s"


def _paper(args) -> int:
    """The paper grid on the study's protocol, on a Dask cluster."""
    import sys

    from ..experiments.study import paper as protocols

    features = tuple(f.strip() for f in args.features.split(";"))
    halving = {k: v for k, v in (("factor", args.halving_factor),
                                 ("rf_resource", args.rf_resource),
                                 ("svr_max_iter", args.svr_max_iter)) if v is not None}
    fits = protocols.exhaustive_fits("paper", features)
    print("study --paper: exhaustive grid search would fit "
          + "; ".join(f"{m} {f} {n}" for m, v in fits.items() for f, n in v.items())
          + f" models; running {args.search} on "
          + (args.scheduler or f"a LocalCluster of {max(args.jobs, 1) if args.jobs > 0 else 2}"
             " workers"), flush=True)
    out = protocols.run_paper(
        args.out, scheduler=args.scheduler, features=features, search=args.search,
        max_train_rows=args.max_train_rows, seed=args.seed, progress=not args.quiet,
        config=load_config(args.config), n_workers=args.jobs if args.jobs > 0 else 2,
        halving=halving, command="ftdrake " + " ".join(sys.argv[1:]))
    print(f"wrote {args.out}/paper.json and paper.md in {out['wall_time_s']:.0f} s")
    for k, v in out.get("exhaustive_s_estimate", {}).items():
        print(f"  exhaustive {k}: {out['exhaustive_fits'][k.split()[0]][k.split()[1]]} fits, "
              f"~{v / 3600:.1f} h on {out['workers']} workers (estimate)")
    for p, found in out["findings"].items():
        print(f"  {p}: " + ", ".join(f"({k}) {v['reproduced']}" for k, v in found.items()))
    return 0


def _tool_table(args) -> int:
    """Simulates the study's trajectory with its tool; writes the Tables 1–3 comparison."""
    import dataclasses as dc

    from ..experiments.study import protocols
    from ..experiments.study.report import tool_markdown
    from ..sim.station import plan_trajectory, robot_geometry
    from ..sim.trajectories import trajectory_extent

    config = protocols.study_scenario(load_config(args.config))
    frame = protocols.collect_study(config, heldout=0, seed=args.seed, n_jobs=1)
    sensor = protocols.sensor_table(frame)
    config = dc.replace(config, trajectory=dc.replace(config.trajectory, seed=args.seed))
    tip = trajectory_extent(plan_trajectory(config), robot_geometry(config), dt=0.5)
    text = tool_markdown(protocols.joint_table(frame), sensor,
                         protocols.table2_comparison(sensor), tip)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study_tool.md").write_text(text)
    print(text)
    return 0
