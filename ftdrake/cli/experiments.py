"""``ftdrake demo`` and ``ftdrake evaluate-detection``: the main job end to end, and contact
detection measured on unseen seeds.

    ftdrake demo [--trajectories 4] [--duration 20] [--no-html] [--out DIR]
    ftdrake evaluate-detection --model a.ftd [--model b.ftd ...] [--minutes 10] [--out DIR]
"""

from __future__ import annotations

from . import args as a


def register(sub) -> None:
    """Adds ``demo`` and ``evaluate-detection`` to an ``argparse`` subparsers object."""
    p = a.add_command(sub, "demo", "collect → train → contact scenario in the loop")
    a.add_config(p)
    p.add_argument("--out", type=a.output_folder, default="out/demo", metavar="DIR",
                   help="folder for the summary, figures, models and logs")
    p.add_argument("--trajectories", type=a.positive_int, default=4, metavar="N",
                   help="Fourier runs to train on")
    p.add_argument("--duration", type=a.positive_float, default=20.0, metavar="S",
                   help="seconds per training run")
    a.add_html(p, default=True)
    p.add_argument("--rehearse-all-surfaces", action="store_true",
                   help="also train on (and hold out) one rehearsal at each other surface of "
                        "the task (the wall)")
    a.add_quiet(p)
    p.set_defaults(run=run_demo_command)

    p = a.add_command(
        sub, "evaluate-detection", "contact detection of models on unseen seeds",
        "False positives in long free motion, misses and delays of presses on table and wall, "
        "a detection-rate plot.")
    a.add_model_file(p, action="append", required=True,
                     help="a model file (repeat to compare models; named by file stem)")
    a.add_config(p)
    p.add_argument("--minutes", type=a.positive_float, default=None, metavar="MIN",
                   help="simulated minutes of free motion, split over the trajectory kinds "
                        "(default: 10; 2 with --quick)")
    p.add_argument("--budget", type=a.positive_float, default=None, metavar="PER_HOUR",
                   help="false positives per hour the thresholds are set for (default: the "
                        "scenario's detector.false_positives_per_hour)")
    p.add_argument("--quick", action="store_true",
                   help="a short plan: --minutes of free motion, five presses per surface, "
                        "no tracker events")
    p.add_argument("--compare-tests", action="store_true",
                   help="evaluate each model with the norm and the χ² test (each with its "
                        "thresholds for the budget), on the same runs")
    a.add_jobs(p)
    p.add_argument("--in-loop", action="store_true",
                   help="simulate every run with each model in the loop, instead of "
                        "simulating each run once and replaying every model over it (the same "
                        "numbers)")
    p.add_argument("--out", type=a.output_folder, default="out/detection", metavar="DIR",
                   help="folder for detection.json, detection.md, detection_rate.png")
    a.add_quiet(p)
    p.set_defaults(run=run_evaluate_detection)


def run_demo_command(args) -> int:
    from ..experiments.demo import print_table, run_demo

    config = a.load_scenario(args)
    summary = run_demo(args.out, config, fourier=args.trajectories, duration=args.duration,
                       other_surfaces=args.rehearse_all_surfaces, meshcat_html=args.html,
                       progress=not args.quiet)
    print_table(summary)
    print(f"wrote {args.out}/summary.json, contact.png, model_forest.ftd, model_hybrid.ftd, "
          "contact_log_*.parquet" + (", replay.html (a self-contained Meshcat replay of the "
                                     "hybrid's run: open it in a browser)" if args.html else ""))
    return 0


def run_evaluate_detection(args) -> int:
    from ..compensation.files.persistence import load_model
    from ..experiments.detection import (
        DetectionPlan,
        markdown,
        run_detection_evaluation,
        run_plan,
    )
    from ..experiments.detection_replay import run_plan_by_replay

    config = a.load_scenario(args)
    models = {}
    for path in args.model:
        with a.naming("--model", path):
            models[path.stem] = load_model(path, expect_n_joints=len(config.home_q))
    changes = {"false_positives_per_hour": args.budget,
               "tests": ("norm", "chi2") if args.compare_tests else None}
    plan = (DetectionPlan.quick(args.minutes or 2.0, **changes) if args.quick
            else DetectionPlan(free_minutes=args.minutes or 10.0, **changes))
    results = run_detection_evaluation(args.out, models, config, plan, n_jobs=args.jobs,
                                       progress=not args.quiet,
                                       run=run_plan if args.in_loop else run_plan_by_replay)
    print(markdown(results, plan))
    plot = (", detectable_force_vs_domain.png"
            if (args.out / "detectable_force_vs_domain.png").is_file() else "")
    print(f"wrote {args.out}/detection.json, detection.md, detection_rate.png{plot}")
    return 0
