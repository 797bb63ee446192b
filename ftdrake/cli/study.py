"""``ftdrake study``: parse → run the study → print the estimate and the findings."""

from __future__ import annotations

import dataclasses as dc
import sys

from ..errors import ConfigError
from ..experiments import study
from ..experiments.study import FEATURES, FIGURES, paper, protocols
from ..experiments.study.report import tool_markdown
from ..sim.station import plan_trajectory, robot_geometry
from ..sim.trajectories import trajectory_extent
from . import args as a

halving_factor = a.number(int, lambda v: v >= 2, "must be a whole number >= 2")
iteration_cap = a.number(int, lambda v: v >= 1 or v == -1,
                         "must be a whole number >= 1, or -1 for no cap")


def register(subparsers) -> None:
    """Adds ``ftdrake study [--quick|--paper] [--out DIR] ...`` to an argparse subparsers."""
    p = a.add_command(subparsers, "study", "RF vs SVR (+ physics, hybrid): the study repeated")
    grid = p.add_mutually_exclusive_group()
    grid.add_argument("--quick", dest="preset", action="store_const", const="quick",
                      help="small grids, one search per protocol pair (see "
                           "docs/study/quick_vs_full.md); under 5 min on 2 idle cores; what runs "
                           "without --paper")
    grid.add_argument("--paper", dest="preset", action="store_const", const="paper",
                      help="the study's full grids (days; not for CI)")
    p.add_argument("--out", type=a.output_folder, default="out/study", metavar="DIR",
                   help="folder for the results and figures")
    a.add_config(p)
    p.add_argument("--trajectories", type=a.positive_int, default=study.TRAJECTORIES,
                   metavar="N", help="runs per dataset")
    p.add_argument("--test-trajectories", type=a.positive_int,
                   default=study.TEST_TRAJECTORIES, metavar="N",
                   help="of those, held out whole for testing (fewer than --trajectories)")
    p.add_argument("--duration", type=a.positive_float, default=study.DURATION_S, metavar="S",
                   help="seconds per run")
    p.add_argument("--train-hz", type=a.positive_float, default=study.TRAIN_HZ, metavar="HZ",
                   help="training rows per second of log (logs are 1 kHz)")
    p.add_argument("--cv", choices=["grouped", "shuffled"], default="grouped",
                   help="cross-validation folds: grouped by trajectory segment, or the study's "
                        "plain shuffled K-fold")
    a.add_seed(p, 0, "seed of the runs and the searches")
    a.add_jobs(p, "worker processes (-1: all cores)")
    a.add_quiet(p)
    cluster = a.add_cluster(p, "--paper: a Dask scheduler (default: a LocalCluster of --jobs "
                            "workers)")
    a.add_deprecated(p, "--scheduler", cluster)
    p.add_argument("--search", choices=["halving", "grid"], default="halving",
                   help="--paper: successive halving or the exhaustive grid")
    p.add_argument("--features", default="q", metavar="SETS",
                   help="--paper: feature sets, ';'-separated")
    p.add_argument("--max-train-rows", type=a.positive_int, metavar="N",
                   help="--paper: training rows drawn from the split (default: all)")
    p.add_argument("--halving-factor", type=halving_factor, metavar="FACTOR",
                   help="--paper --search halving: keep 1/FACTOR per round (default: 3)")
    p.add_argument("--rf-resource", choices=["n_estimators", "n_samples"], default=None,
                   help="--paper --search halving: RF's budget, trees or rows "
                        "(default: n_estimators)")
    p.add_argument("--svr-max-iter", type=iteration_cap, metavar="N",
                   help="--paper: libsvm iteration cap per SVR fit, -1 for none "
                        "(default: 100000)")
    p.add_argument("--tool-table", action="store_true",
                   help="only simulate the study's trajectory and write study_tool.md")
    p.set_defaults(preset="quick", run=run_command)


def run_command(args) -> int:
    """Prints the grid and time estimate, runs the study, prints the findings."""
    if args.tool_table:
        return _tool_table(args)
    if args.preset == "paper":
        return _paper(args)
    if not args.test_trajectories < args.trajectories:
        raise ConfigError(f"--test-trajectories {args.test_trajectories}: must be fewer than "
                          f"--trajectories ({args.trajectories}): the others are trained on")
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
        seed=args.seed, config=a.load_scenario(args))
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
    features = tuple(f.strip() for f in args.features.split(";"))
    halving = {k: v for k, v in (("factor", args.halving_factor),
                                 ("rf_resource", args.rf_resource),
                                 ("svr_max_iter", args.svr_max_iter)) if v is not None}
    fits = paper.exhaustive_fits("paper", features)
    print("study --paper: exhaustive grid search would fit "
          + "; ".join(f"{m} {f} {n}" for m, v in fits.items() for f, n in v.items())
          + f" models; running {args.search} on "
          + (args.cluster or f"a LocalCluster of {max(args.jobs, 1) if args.jobs > 0 else 2}"
             " workers"), flush=True)
    out = paper.run_paper(
        args.out, scheduler=args.cluster, features=features, search=args.search,
        max_train_rows=args.max_train_rows, seed=args.seed, progress=not args.quiet,
        config=a.load_scenario(args), n_workers=args.jobs if args.jobs > 0 else 2,
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
    config = protocols.study_scenario(a.load_scenario(args))
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
