"""``ftdrake simulate`` and ``ftdrake collect``: the simulated rig, once (with a log, a figure
and a summary) or many times (a dataset).

    ftdrake simulate [--trajectory contact] [--duration S] [--seed N] [--html] [--out DIR]
    ftdrake simulate --trajectory fourier --lcm URL --realtime    # a simulated robot on LCM
    ftdrake collect [--trajectories 8] [--trajectory fourier] [--cluster ADDRESS] [--out FILE]
"""

from __future__ import annotations

import json
import sys

from .. import conventions as col
from ..config.task import FREE_KINDS
from ..errors import FtdrakeError
from ..io import atomic_path, staged_outputs
from . import args as a
from . import ros2
from .hardware import add_transport_flags, describe_channels, hardware_from_args, open_transport

# The old --scenario values, as trajectory kinds.
_SCENARIOS = {"free": "fourier", "contact": "contact"}


def register(sub) -> None:
    """Adds ``simulate`` and ``collect`` to an ``argparse`` subparsers object."""
    p = a.add_command(sub, "simulate", "run the diagram once: log, figure, summary")
    a.add_config(p)
    trajectory = a.add_trajectory(
        p, default="contact", help="what the arm does: contact presses the tool on the task's "
        "surfaces; the others are free motion (fourier: smooth)")
    a.add_deprecated(p, "--scenario", trajectory, values=_SCENARIOS)
    p.add_argument("--duration", type=a.positive_float, metavar="S",
                   help="seconds to simulate (default: the scenario's trajectory.duration_s)")
    a.add_seed(p, None, "seed of trajectory and sensor noise (default: the scenario's)")
    p.add_argument("--out", type=a.output_folder, default="out/simulate", metavar="DIR",
                   help="folder for log.parquet, wrench.png, summary.json (and replay.html)")
    html = a.add_html(p, default=False)
    a.add_deprecated(p, "--meshcat-html", html)
    a.add_quiet(p, "no progress bar")
    add_transport_flags(p, lcm_help="also publish the arm's joint state and the sensor on "
                        "LCM, on the channels of --hardware (see `ftdrake serve`)")
    p.add_argument("--realtime", action="store_true", help="pace the simulation to the wall "
                   "clock")
    ros2.add_options(p)
    p.set_defaults(run=run_simulate)

    p = a.add_command(sub, "collect", "free-motion runs → one Parquet dataset")
    a.add_config(p)
    p.add_argument("--trajectories", type=a.positive_int, default=8, metavar="N",
                   help="runs to simulate")
    p.add_argument("--duration", type=a.positive_float, default=20.0, metavar="S",
                   help="seconds per run")
    trajectory = a.add_trajectory(
        p, default="fourier", kinds=FREE_KINDS,
        help="free motion of each run; rehearsal: the contact motion stopping 3 cm above the "
             "surface; task_covering: motion planned to cover the task's approaches to every "
             "surface and to excite the payload")
    a.add_deprecated(p, "--kind", trajectory)
    a.add_seed(p, 0, "seed of the first run (run i: seed + i)")
    a.add_jobs(p)
    cluster = a.add_cluster(p, "run on this Dask scheduler instead of local processes")
    a.add_deprecated(p, "--dask", cluster)
    p.add_argument("--out", type=a.output_file, default="out/dataset.parquet", metavar="FILE",
                   help="the dataset, Parquet")
    a.add_quiet(p)
    p.set_defaults(run=run_collect)


def run_simulate(args) -> int:
    from .. import plots
    from ..data.logs import write_log
    from ..sim import station as sim_station
    from ..sim.lcm_publisher import simulate_on_lcm
    from ..sim.simulate import simulate
    from ..systems.wrench_arrows import recording_meshcat

    config = a.scenario_from_args(args, args.trajectory)
    meshcat = recording_meshcat() if args.html else None
    station = sim_station.build_station(config, meshcat=meshcat)
    if meshcat is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    realtime_rate = 1.0 if args.realtime else 0.0
    if args.ros2:
        result = ros2.simulate(args, station)
    elif args.lcm is not None or args.hardware is not None:
        hardware = hardware_from_args(args)
        if not args.quiet:
            print(f"ftdrake simulate: publishing {describe_channels(hardware).splitlines()[1]}"
                  f" on {hardware.lcm_url}".replace("  in:  ", ""), file=sys.stderr, flush=True)
        result = simulate_on_lcm(station, hardware, open_transport(args, hardware),
                                 realtime_rate=realtime_rate, progress=not args.quiet)
    else:
        result = simulate(station, progress=not args.quiet, realtime_rate=realtime_rate)
    log, summary = result.log, dict(result.timing)
    scenario = "contact" if args.trajectory == "contact" else "free"
    contact_times = log.loc[log[col.CONTACT_TRUE] == 1, col.TIME]
    summary.update(
        scenario=scenario,
        trajectory=config.trajectory.kind,
        sensor_preset=config.sensor.preset,
        sensor_rate_hz=config.sensor.spec().rate_hz,
        first_contact_time_s=float(contact_times.iloc[0]) if len(contact_times) else None,
        max_contact_force_n=float(
            (log[col.wrench_columns(col.EXTERNAL_TRUE)[:3]] ** 2).sum(axis=1).max() ** 0.5
        ),
        saturated_samples=int(log[col.SATURATED].sum()),
    )
    with staged_outputs(args.out) as stage:
        write_log(log, stage / "log.parquet")
        plots.plot_wrench_log(log, stage / "wrench.png", title=f"{scenario} scenario")
        if meshcat is not None:
            meshcat.StopRecording()
            meshcat.PublishRecording()
            (stage / "replay.html").write_text(meshcat.StaticHtml())
        with atomic_path(stage / "summary.json") as tmp:
            tmp.write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return 0


def run_collect(args) -> int:
    from ..data.dataset import save_dataset
    from ..sim.collection import collect

    config = a.load_scenario(args)
    try:
        frame = collect(config, args.trajectories, seed=args.seed, kind=args.trajectory,
                        duration=args.duration, n_jobs=args.jobs, dask_address=args.cluster,
                        progress=not args.quiet)
    except OSError as e:  # dask.distributed: the scheduler cannot be reached
        if args.cluster is None:
            raise
        raise FtdrakeError(f"--cluster {args.cluster}: {e}") from e
    save_dataset(frame, args.out)
    print(json.dumps({"out": str(args.out), "rows": len(frame),
                      "trajectories": int(frame[col.TRAJECTORY].nunique()),
                      "contact_rows": int(frame[col.CONTACT_TRUE].sum())}))
    return 0
